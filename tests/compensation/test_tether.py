"""The tethered cable (compensation/identification/tether.py): its frames and columns against Drake,
its identification against a cable injected into the simulated plant, its compiled row, its file.

The simulated cable is a Drake ``LinearSpringDamper`` from a point on a link to a point on
the tool plus a hanging weight (sim/cable.py); the sensor's ``ideal_*`` columns are the
plant's reaction at the sensor weld, computed by Drake and not by the payload model. The
identification tests use a geometry the defaults were not designed on (cable B: anchored on
the upper arm link_u, 60 N/m, 0.35 m, 2.0 N; the default cable hangs from link_r).
"""

import dataclasses as dc
import warnings

import numpy as np
import pytest

from ftdrake import CompensationChain, ScenarioConfig
from ftdrake.compensation.estimators.physics import ExcitationWarning, PhysicsPayloadCompensator
from ftdrake.compensation.files.persistence import load_model, save_model
from ftdrake.compensation.identification.payload_identification import (
    CROSSTALK_LENGTH_M,
    CROSSTALK_PRIOR,
    fit_crosstalk,
)
from ftdrake.compensation.identification.tether import WORLD, tether_columns
from ftdrake.conventions import WRENCH_AXES
from ftdrake.data.dataset import joint_state_layout, wrench_targets
from ftdrake.errors import ConfigError
from ftdrake.physics.chain import SerialChain, joint_frames_in_sensor_batch
from ftdrake.physics.robot import ftdrake_arm
from ftdrake.sim.collection import collect
from ftdrake.systems.noisy_sensor import crosstalk_matrix, mounting_rotation

TRUE_MASS = 1.5  # kg, the default tool (models/ft_sensor_tool.sdf)
CABLE_B = {"anchor_body": "link_u", "p_anchor": [0.05, 0.0, 0.15],
           "p_SAttach": [-0.04, 0.0, 0.04], "stiffness": 60.0, "rest_length": 0.35,
           "weight_n": 2.0}


@pytest.fixture(scope="module")
def cable_b_runs():
    """Two 12 s Fourier runs to fit on and one to hold out, with cable B."""
    config = ScenarioConfig()
    config.cable = dc.replace(config.cable, **CABLE_B)
    train = collect(config, 2, kind="fourier", duration=12.0, seed=21, n_jobs=2,
                    progress=False)
    held_out = collect(config, 1, kind="fourier", duration=12.0, seed=40, n_jobs=1,
                       progress=False)
    return train, held_out


def _fit(frame, prefix, **options):
    # The plant's reaction ("ideal") is exact for the plant's own q̈; the logs' qdd_est is
    # the loop's causal estimate, which lags it.
    source = "plant" if prefix == "ideal" else "est"
    X, Y = joint_state_layout(frame, source)[::4], wrench_targets(frame, prefix)[::4]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        return PhysicsPayloadCompensator(weight_without_inertia=True, **options).fit(X, Y)


@pytest.fixture(scope="module")
def ideal_fit(cable_b_runs):
    return _fit(cable_b_runs[0], "ideal", tether="auto")


def _arm():
    plant, frame_S = ftdrake_arm().build_plant()
    return plant, frame_S, SerialChain.from_plant(plant, frame_S)


def test_joint_frames_in_sensor_equal_drakes_poses(rng):
    plant, frame_S, chain = _arm()
    q = rng.uniform(-2.0, 2.0, (4, chain.num_positions))
    out = np.empty((4, chain.num_moving_joints + 1, 3, 4))
    joint_frames_in_sensor_batch(q, chain.X_pre, chain.kinds, chain.axes, chain.q_index, out)
    context = plant.CreateDefaultContext()
    moving = [j.name for j in chain.joints if j.type != "weld"]
    for n in range(4):
        plant.SetPositions(context, q[n])
        X_SW = frame_S.CalcPoseInWorld(context).inverse()
        for k, name in enumerate(moving):
            X_WM = plant.GetJointByName(name).frame_on_child().CalcPoseInWorld(context)
            np.testing.assert_allclose(out[n, k], (X_SW @ X_WM).GetAsMatrix34(), atol=1e-12)
        np.testing.assert_allclose(out[n, -1], X_SW.GetAsMatrix34(), atol=1e-12)


def test_tether_columns_are_the_springs_force_and_moment(rng):
    """k·col₀ − k·ℓ0·col₁ equals the spring force k(ℓ − ℓ0) along Q → P and its moment
    about So, computed from the points in the world by Drake's poses."""
    plant, frame_S, chain = _arm()
    k, rest = 40.0, 0.3
    p_MP, p_SQ = np.array([0.05, -0.02, 0.1]), np.array([-0.04, 0.01, 0.05])
    q = rng.uniform(-2.0, 2.0, (3, chain.num_positions))
    frames = np.empty((3, chain.num_moving_joints + 1, 3, 4))
    joint_frames_in_sensor_batch(q, chain.X_pre, chain.kinds, chain.axes, chain.q_index,
                                 frames)
    wrench = tether_columns(frames[:, 3], p_MP, p_SQ) @ np.array([k, k * rest])
    context = plant.CreateDefaultContext()
    for n in range(3):
        plant.SetPositions(context, q[n])
        X_WS = frame_S.CalcPoseInWorld(context)
        p_WP = plant.GetJointByName("joint_u").frame_on_child().CalcPoseInWorld(context) @ p_MP
        p_WQ = X_WS @ p_SQ
        line = p_WP - p_WQ
        f_W = k * (np.linalg.norm(line) - rest) * line / np.linalg.norm(line)
        f_S = X_WS.rotation().inverse() @ f_W
        np.testing.assert_allclose(wrench[n, :3], f_S, atol=1e-12)
        np.testing.assert_allclose(wrench[n, 3:], np.cross(p_SQ, f_S), atol=1e-12)


def test_identification_finds_the_injected_cable(ideal_fit):
    """From the plant's own reaction at the weld: the link, both points, the stiffness, the
    rest length, the hanging weight and the tool's mass of a cable it was not designed on."""
    model = ideal_fit
    assert model.tether_frame_ == "joint_u"  # link_u is joint_u's child; its M is its frame
    assert min(model.tether_search_.values()) == model.tether_search_["joint_u"]
    np.testing.assert_allclose(model.tether_anchor_, CABLE_B["p_anchor"], atol=0.005)
    np.testing.assert_allclose(model.tether_attach_, CABLE_B["p_SAttach"], atol=0.005)
    k, k_rest = model.parameters_[20:22]
    assert k == pytest.approx(CABLE_B["stiffness"], rel=0.02)
    assert k_rest / k == pytest.approx(CABLE_B["rest_length"], abs=0.005)
    assert model.parameters_[16] * 9.81 == pytest.approx(CABLE_B["weight_n"], rel=0.03)
    assert model.parameters_[0] == pytest.approx(TRUE_MASS, rel=0.005)
    table = model.identified()
    assert table["k"]["unit"] == "N/m" and table["kl0"]["unit"] == "N"
    assert "tether" in model.summary()


def test_tether_removes_the_cables_pull_from_held_out_readings(cable_b_runs, ideal_fit):
    """On the held-out run's plant readings, the model with the tether leaves under a tenth
    of what the model without it leaves on every axis."""
    _, held_out = cable_b_runs
    without = _fit(cable_b_runs[0], "ideal")
    X, truth = joint_state_layout(held_out, "plant"), wrench_targets(held_out, "ideal")
    rms = {name: np.sqrt(np.mean((m.predict(X) - truth) ** 2, axis=0))
           for name, m in (("with", ideal_fit), ("without", without))}
    assert np.all(rms["with"] < 0.1 * rms["without"])


def _through_a_sensor(frame, rng):
    """The plant's reaction as a mounted, cross-talking, biased, noisy sensor reads it: the
    simulated sensor's own matrix (1 % cross-talk, mounting 1.5, −2, 1 deg) and ati_gamma
    noise σ, without its drift and filter, so that the noise is the floor."""
    M = crosstalk_matrix(0.01, 0.05, 0) @ np.kron(np.eye(2), mounting_rotation(
        [1.5, -2.0, 1.0]).T)
    Y = wrench_targets(frame, "ideal") @ M.T + np.array([0.6, -0.4, 1.2, 0.02, -0.015, 0.01])
    return Y + rng.normal(size=Y.shape) * NOISE_STD


NOISE_STD = np.array([1 / 40, 1 / 40, 1 / 20, 1 / 800, 1 / 800, 1 / 800])


def test_tether_with_the_sensors_mounting_and_crosstalk(cable_b_runs):
    """Through a mounted, cross-talking sensor: the search refines the mounting rotation (fitted
    first without the tether, whose pull it took in part) with the geometry, and the final fit
    identifies the cross-talk; then the geometry, the stiffness and the tool's mass are found
    as from the plant's reaction, and the held-out readings are predicted to within 1.3 noise
    σ on every axis (the noise alone gives 1). Contacts are still mapped into S by the
    mounting rotation alone."""
    train, held_out = cable_b_runs
    rng = np.random.default_rng(5)
    train = train.copy()
    train[[f"ideal_{axis}" for axis in WRENCH_AXES]] = _through_a_sensor(train, rng)
    model = _fit(train, "ideal", tether="auto", identify_mounting=True, identify_crosstalk=True)
    assert model.tether_frame_ == "joint_u"
    np.testing.assert_allclose(model.tether_anchor_, CABLE_B["p_anchor"], atol=0.005)
    np.testing.assert_allclose(model.tether_attach_, CABLE_B["p_SAttach"], atol=0.005)
    assert model.parameters_[20] == pytest.approx(CABLE_B["stiffness"], rel=0.03)
    assert model.parameters_[0] == pytest.approx(TRUE_MASS, rel=0.01)
    error = model.predict(joint_state_layout(held_out, "plant")) - _through_a_sensor(held_out,
                                                                                     rng)
    assert np.all(np.sqrt(np.mean(error ** 2, axis=0)) < 1.3 * NOISE_STD)
    assert "cross-talk E" in model.summary()
    # A contact is mapped into S by the mounting rotation alone, not by the free-motion E.
    rotation = np.kron(np.eye(2), model.mounting_rotation_).T
    np.testing.assert_allclose(model.reading_to_model_frame(), np.linalg.inv(rotation))
    assert not np.allclose(model.reading_matrix(), rotation)
    # A grasped payload's wrench is read through the whole matrix, seen from S; the chain's
    # tracker gets that map (a forest's chain the identity).
    K = model.payload_reading_map()
    np.testing.assert_allclose(K, rotation.T @ model.reading_matrix(), atol=1e-12)
    config = ScenarioConfig()
    config.chain.bias_tracker.track_payload = True
    chain = CompensationChain(model, config.chain_config(), gravity="input")
    np.testing.assert_array_equal(chain.tracker.payload_map, K)


def test_crosstalk_from_generated_wrenches(rng):
    """Y = (I + E)·V + b + noise with V rich in every axis: E is recovered to well within
    its prior's scale (a transposed or a mis-scaled E fails)."""
    n = 4000
    V = rng.normal(size=(n, 6)) * np.array([10, 10, 15, 0.5, 0.5, 0.3])
    scale = np.full((6, 6), CROSSTALK_PRIOR)
    scale[:3, 3:] /= CROSSTALK_LENGTH_M
    scale[3:, :3] *= CROSSTALK_LENGTH_M
    E = rng.uniform(-0.5, 0.5, (6, 6)) * scale
    np.fill_diagonal(E, 0.0)
    Y = V @ (np.eye(6) + E).T + np.array([1, -2, 3, 0.1, 0.2, -0.1])
    Y += rng.normal(size=Y.shape) * NOISE_STD
    assert np.all(np.abs(fit_crosstalk(V, Y) - E) < 0.02 * scale)


def test_compiled_row_and_file_keep_the_tether(ideal_fit, cable_b_runs, tmp_path):
    X = joint_state_layout(cable_b_runs[1])[::500]
    mean, std = ideal_fit.predict(X), ideal_fit.predict_std(X)
    row = ideal_fit.row_predictor()
    for x, m, s in zip(X, mean, std, strict=True):
        got_mean, got_std = row(x)
        np.testing.assert_allclose(got_mean, m, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(got_std, s, rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(ideal_fit.predict_row(x), m, rtol=1e-10, atol=1e-10)
    loaded = load_model(save_model(ideal_fit, tmp_path / "tether.ftmodel"))
    assert loaded.tether_frame_ == ideal_fit.tether_frame_
    np.testing.assert_array_equal(loaded.predict(X), mean)


def test_tether_options_are_checked():
    X, Y = np.zeros((50, 21)), np.zeros((50, 6))
    with pytest.raises(ConfigError, match="identify_crosstalk needs mode='dynamic'"):
        PhysicsPayloadCompensator(features="q", mode="static", identify_crosstalk=True).fit(
            X[:, :7], Y)
    with pytest.raises(ConfigError, match="weight_without_inertia"):
        PhysicsPayloadCompensator(tether="auto").fit(X, Y)
    with pytest.raises(ConfigError, match=f"'auto', '{WORLD}' or one of the moving joints "
                                          "joint_s"):
        PhysicsPayloadCompensator(weight_without_inertia=True, tether="link_u").fit(X, Y)


def test_hybrids_compiled_row_keeps_the_tether(cable_b_runs):
    """The hybrid's fused kernel (payload row with the tether, forest, support term) equals
    its Python prediction."""
    from ftdrake.compensation.estimators.hybrid import HybridCompensator

    train, held_out = cable_b_runs
    X, Y = joint_state_layout(train)[::8], wrench_targets(train)[::8]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ExcitationWarning)
        hybrid = HybridCompensator(physics=PhysicsPayloadCompensator(
            weight_without_inertia=True, tether="auto")).fit(X, Y)
    assert hybrid.compiled_predictor() is not None
    rows = joint_state_layout(held_out)[::600]
    row = hybrid.row_predictor()
    got = np.array([row(x)[0] for x in rows])
    np.testing.assert_allclose(got, hybrid.predict(rows), rtol=1e-10, atol=1e-10)
