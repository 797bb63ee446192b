"""CompensatorSystem and ContactDetector, alone and in the loop of the simulated arm."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from ftdrake import ScenarioConfig, build_station, evaluate_detection, simulate
from ftdrake import conventions as col
from ftdrake.compensation.estimators.base import Compensator
from ftdrake.compensation.estimators.forest import RandomForestCompensator
from ftdrake.compensation.files.persistence import load_model, save_model
from ftdrake.config import DetectorConfig
from ftdrake.data.dataset import joint_state_layout, wrench_targets
from ftdrake.offline.thresholds import thresholds_from_quantile
from ftdrake.runtime.compensator import CompensatorSystem
from ftdrake.runtime.detector import ContactDetector
from ftdrake.sim.collection import collect

PERIOD = 1e-3
N = 7


@pytest.fixture(scope="module")
def forest():
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, size=(400, 3 * N))
    Y = np.column_stack([np.sin(X[:, j]) + X[:, N + j] for j in range(6)])
    return RandomForestCompensator(features="q,qd,qdd", n_estimators=10, random_state=0).fit(X, Y)


def source(builder, value):
    if isinstance(value, PiecewisePolynomial):
        return builder.AddSystem(TrajectorySource(value))
    return builder.AddSystem(ConstantVectorSource(np.asarray(value, dtype=float)))


def run_compensator(model, wrench, state, accel=None, duration=0.01, **kwargs):
    builder = DiagramBuilder()
    dut = builder.AddSystem(CompensatorSystem(model, PERIOD, **kwargs))
    builder.Connect(source(builder, wrench).get_output_port(), dut.GetInputPort("wrench_measured"))
    builder.Connect(source(builder, state).get_output_port(), dut.GetInputPort("joint_state"))
    if accel is not None:
        builder.Connect(source(builder, accel).get_output_port(),
                        dut.GetInputPort("joint_acceleration"))
    logs = {name: LogVectorOutput(dut.GetOutputPort(name), builder, PERIOD)
            for name in ("wrench_internal", "wrench_compensated", "wrench_std", "out_of_domain",
                         "fault")}
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(duration)
    context = simulator.get_context()
    return {name: log.FindLog(context).data().T for name, log in logs.items()}


def test_outputs_equal_predict_and_external_is_exact_difference(forest):
    rng = np.random.default_rng(1)
    q, v, a = rng.uniform(-0.8, 0.8, (3, N))
    wrench = rng.normal(size=6) * 5
    out = run_compensator(forest, wrench, np.concatenate([q, v]), accel=a)
    expected = forest.predict(np.concatenate([q, v, a])[None, :])[0]
    np.testing.assert_allclose(out["wrench_internal"][-1], expected, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(out["wrench_compensated"][-1],
                                  wrench - out["wrench_internal"][-1])
    # The forest's spread across trees, from the fused compiled update.
    std = forest.predict_std(np.concatenate([q, v, a])[None, :])[0]
    np.testing.assert_allclose(out["wrench_std"][-1], std, rtol=1e-6, atol=1e-9)
    assert out["out_of_domain"][-1, 0] == 0.0 and out["fault"][-1, 0] == 0.0


class AccelerationEcho(Compensator):
    """Predicts the first six joints' q̈ from its input: shows the estimated q̈ directly."""

    def _fit(self, Z, Y):
        pass

    def _predict(self, Z):
        return Z[:, 2 * self.n_joints_: 2 * self.n_joints_ + 6]


def test_acceleration_is_estimated_when_port_unconnected():
    echo = AccelerationEcho().fit(np.zeros((10, 3 * N)), np.zeros((10, 6)))
    accel = np.linspace(0.1, 0.7, N)  # rad/s², constant
    t = np.array([0.0, 1.0])
    v = np.column_stack([np.zeros(N), accel])  # v = accel · t
    state = PiecewisePolynomial.FirstOrderHold(t, np.vstack([np.zeros((N, 2)), v]))
    out = run_compensator(echo, np.zeros(6), state, duration=0.4)
    # The filtered difference of v has converged to the true, constant acceleration.
    np.testing.assert_allclose(out["wrench_internal"][-1], accel[:6], rtol=1e-6)
    # ... and it starts from zero: the filter is causal, not told the answer.
    assert np.abs(out["wrench_internal"][1]).max() < 0.5 * accel[:6].min()


def test_nan_input_holds_last_good_value_and_raises_fault(forest):
    t = [0.0, 0.005, 1.0]
    good = np.full(6, 1.0)
    wrench = PiecewisePolynomial.ZeroOrderHold(t, np.column_stack([good, np.full(6, np.nan),
                                                                   np.full(6, np.nan)]))
    out = run_compensator(forest, wrench, np.zeros(2 * N), accel=np.zeros(N), duration=0.01)
    assert np.all(np.isfinite(out["wrench_compensated"]))
    assert out["fault"][-1, 0] == 1.0 and out["fault"][2, 0] == 0.0
    np.testing.assert_array_equal(out["wrench_compensated"][-1], out["wrench_compensated"][4])


def test_out_of_domain_flag(forest):
    state = np.concatenate([np.full(N, 3.0), np.zeros(N)])  # q far beyond training's ±1
    out = run_compensator(forest, np.zeros(6), state, accel=np.zeros(N))
    assert out["out_of_domain"][-1, 0] == 1.0


def test_refuses_models_that_do_not_fit(forest):
    with pytest.raises(ValueError, match="trained for 7 joints; this robot has 6"):
        CompensatorSystem(forest, PERIOD, n_joints=6)
    three = RandomForestCompensator(n_estimators=3).fit(np.zeros((10, 21)), np.zeros((10, 3)))
    with pytest.raises(ValueError, match="3 outputs; a wrench needs 6"):
        CompensatorSystem(three, PERIOD)
    with pytest.raises(ValueError, match="fitted ftdrake compensator"):
        CompensatorSystem(object(), PERIOD)


def test_accepts_model_loaded_from_file(forest, tmp_path):
    path = save_model(forest, tmp_path / "m.ftd", target_names=col.WRENCH_AXES,
                      target_units=col.WRENCH_UNITS)
    loaded = load_model(path, expect_n_joints=N)
    out = run_compensator(loaded, np.zeros(6), np.zeros(2 * N), accel=np.zeros(N))
    np.testing.assert_allclose(out["wrench_internal"][-1],
                               forest.predict(np.zeros((1, 3 * N)))[0], atol=1e-12)


def test_wrong_port_size_fails_when_connecting(forest):
    builder = DiagramBuilder()
    dut = builder.AddSystem(CompensatorSystem(forest, PERIOD))
    five = builder.AddSystem(ConstantVectorSource(np.zeros(5)))
    with pytest.raises(RuntimeError, match=r"[Mm]ismatched|size"):
        builder.Connect(five.get_output_port(), dut.GetInputPort("wrench_measured"))


# ----------------------------------------------------------------------------------------------
def run_detector(forces, config, std=None):
    t = np.arange(len(forces)) * PERIOD
    W = np.zeros((6, len(forces)))
    W[2] = forces
    builder = DiagramBuilder()
    dut = builder.AddSystem(ContactDetector(config, PERIOD))
    builder.Connect(builder.AddSystem(TrajectorySource(
        PiecewisePolynomial.ZeroOrderHold(t, W))).get_output_port(),
        dut.GetInputPort("wrench_contact"))
    if std is not None:
        builder.Connect(source(builder, std).get_output_port(), dut.GetInputPort("wrench_std"))
    log = LogVectorOutput(dut.GetOutputPort("contact"), builder, PERIOD)
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(t[-1])
    return log.FindLog(simulator.get_context()).data()[0]


def test_detector_debounce_and_hysteresis():
    config = DetectorConfig(force_on=2.0, torque_on=1.0, release_ratio=0.5, debounce_on=3,
                            debounce_off=5, arm_after_s=0.0)
    forces = np.concatenate([np.zeros(10), np.full(2, 3.0), np.zeros(10),  # 2-sample blip
                             np.full(20, 3.0),  # contact
                             np.full(10, 1.5),  # inside the hysteresis band: stays on
                             np.zeros(20)])  # release
    flag = run_detector(forces, config)
    assert flag[:22].max() == 0  # the blip is shorter than debounce_on
    on = np.flatnonzero(flag)[0]
    assert 22 + 3 <= on <= 22 + 4
    assert flag[42:52].min() == 1  # hysteresis
    assert flag[-1] == 0
    off = on + np.flatnonzero(flag[on:] == 0)[0]
    assert 52 + 5 <= off <= 52 + 6


def test_detector_threshold_grows_with_uncertainty():
    forces = np.concatenate([np.zeros(5), np.full(30, 3.0)])
    base = DetectorConfig(force_on=2.0, debounce_on=2, std_gain=2.0, arm_after_s=0.0)
    assert run_detector(forces, base, std=np.zeros(6)).max() == 1
    assert run_detector(forces, base, std=np.array([0.5, 0, 0, 0, 0, 0])).max() == 0


def test_detector_is_disarmed_at_start():
    forces = np.full(100, 5.0)
    flag = run_detector(forces, DetectorConfig(force_on=2.0, debounce_on=2, arm_after_s=0.03))
    assert flag[:30].max() == 0 and flag[-1] == 1


def test_detector_config_validation():
    with pytest.raises(ValueError, match="force_on"):
        DetectorConfig(force_on=-1).validate()
    with pytest.raises(ValueError, match="release_ratio"):
        DetectorConfig(release_ratio=1.5).validate()


# ----------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def task_data():
    """Free motion and rehearsals of the task in the air (the last one held out)."""
    base = ScenarioConfig()
    free = collect(base, 4, kind="fourier", duration=15.0, n_jobs=2, progress=False)
    rehearsal = collect(base, 3, kind="rehearsal", seed=50, n_jobs=2, progress=False)
    train = rehearsal[rehearsal["trajectory"] < 2]
    validation = rehearsal[rehearsal["trajectory"] == 2]
    X = np.vstack([joint_state_layout(free), joint_state_layout(train)])
    Y = np.vstack([wrench_targets(free), wrench_targets(train)])
    return X, Y, validation


def held_out_contact_run(model, task_data, seed=777):
    """Thresholds from the held-out rehearsal; a contact run with unseen seeds; its scores."""
    _, _, validation = task_data
    residual = wrench_targets(validation) - model.predict(joint_state_layout(validation))
    scenario = ScenarioConfig()
    scenario.trajectory.seed = scenario.sensor.seed = seed  # not in training
    scenario.chain.detector = thresholds_from_quantile(residual)
    log = simulate(build_station(scenario, model), progress=False).log
    return evaluate_detection(log, scenario.sensor.spec().noise_std)


def assert_detected_cleanly(metrics):
    assert metrics["true_contacts"] == 1
    assert metrics["missed_contacts"] == 0
    assert metrics["false_positives"] == 0
    assert 0 <= metrics["detection_delay_s"] <= 0.02  # s
    # Pressing ~25 N: the estimated external force is within 1.5 N of the truth in contact.
    assert np.linalg.norm(metrics["external_wrench_error_rms"][:3]) < 1.5


@pytest.mark.slow
def test_forest_in_the_loop_detects_contact_on_held_out_run(task_data):
    X, Y, _ = task_data
    model = RandomForestCompensator(features="q", n_estimators=40, per_output=False,
                                    max_features=0.33, random_state=0, n_jobs=2)
    assert_detected_cleanly(held_out_contact_run(model.fit(X[::4], Y[::4]), task_data))


@pytest.mark.slow
def test_hybrid_in_the_loop_compensates_to_the_noise_floor(task_data):
    import warnings

    from ftdrake.compensation.estimators.hybrid import HybridCompensator

    X, Y, _ = task_data
    residual = RandomForestCompensator(features="q", n_estimators=30, per_output=False,
                                       min_samples_leaf=5, random_state=0, n_jobs=2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the excitation warning is tested elsewhere
        model = HybridCompensator(residual=residual).fit(X[::4], Y[::4])
    metrics = held_out_contact_run(model, task_data)
    assert_detected_cleanly(metrics)
    assert max(metrics["compensation_error_over_noise"]) < 3.0  # within 3 σ on every axis


def test_meshcat_replay_holds_the_wrench_arrows(forest):
    import base64
    import re

    from pydrake.geometry import Meshcat

    config = ScenarioConfig()
    config.trajectory.kind, config.trajectory.duration_s = "fourier", 1.0
    single = RandomForestCompensator(features="q", n_estimators=3, random_state=0).fit(
        np.random.default_rng(0).uniform(-1, 1, (50, 3 * N)), np.zeros((50, 6)))
    meshcat = Meshcat()
    meshcat.StartRecording(set_visualizations_while_recording=False)
    simulate(build_station(config, single, meshcat=meshcat), progress=False)
    meshcat.StopRecording()
    meshcat.PublishRecording()
    html = meshcat.StaticHtml()
    blobs = [base64.b64decode(b) for b in re.findall(r"base64,([A-Za-z0-9+/=]{100,})", html)]
    for name in (b"wrench/measured", b"wrench/external"):
        assert sum(blob.count(name) for blob in blobs) >= 2  # the object and its animation


def _svr_compensator():
    from ftdrake.compensation.estimators.svr import SVRCompensator

    rng = np.random.default_rng(1)
    X = rng.uniform(-1, 1, size=(150, 3 * N))
    Y = np.column_stack([np.sin(X[:, j]) for j in range(6)])
    return SVRCompensator(features="q", C=10.0).fit(X, Y)


@pytest.mark.parametrize("kind", ["forest", "svr"])  # the compiled-forest and generic paths
def test_fault_and_out_of_domain_clear_when_inputs_recover(forest, kind):
    model = forest if kind == "forest" else _svr_compensator()
    t = [0.0, 0.003, 0.006, 0.009, 1.0]  # each column holds from its time to the next
    nan, good = np.full(6, np.nan), np.full(6, 1.0)
    wrench = PiecewisePolynomial.ZeroOrderHold(t, np.column_stack([good, nan, good, good, good]))
    far, near = np.full(2 * N, 3.0), np.zeros(2 * N)  # q outside / inside the training range
    state = PiecewisePolynomial.ZeroOrderHold(t, np.column_stack([near, near, far, near, near]))
    out = run_compensator(model, wrench, state, accel=np.zeros(N), duration=0.012)
    fault, ood = out["fault"][:, 0], out["out_of_domain"][:, 0]
    # Samples land one period after they are taken: rows 4–6 hold the NaN samples (3–5 ms).
    np.testing.assert_array_equal(fault[1:12], [0, 0, 0, 1, 1, 1, 0, 0, 0, 0, 0])
    np.testing.assert_array_equal(ood[1:12], [0, 0, 0, 0, 0, 0, 1, 1, 1, 0, 0])
    expected = model.predict(np.zeros((1, 3 * N)))[0]
    np.testing.assert_allclose(out["wrench_internal"][-1], expected, rtol=1e-9, atol=1e-12)
    np.testing.assert_array_equal(out["wrench_compensated"][-1], good - out["wrench_internal"][-1])


@pytest.mark.parametrize("hybrid", [False, True])
def test_gp_in_the_diagram_outputs_its_predict_and_predict_std(hybrid):
    import warnings

    from ftdrake.compensation.estimators.gpr import GPRCompensator
    from ftdrake.compensation.estimators.hybrid import HybridCompensator
    from ftdrake.compensation.estimators.physics import PhysicsPayloadCompensator

    rng = np.random.default_rng(3)
    X = rng.uniform(-0.5, 0.5, size=(120, 3 * N))
    Y = np.column_stack([np.sin(X[:, j]) * 5 + 0.1 * rng.normal(size=120) for j in range(6)])
    gp = GPRCompensator(features="q", max_points=60, optimize_points=40, random_state=0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = (HybridCompensator(PhysicsPayloadCompensator(mode="static", features="q"), gp)
                 if hybrid else gp).fit(X, Y)
    q, v, a = rng.uniform(-0.4, 0.4, (3, N))
    wrench = rng.normal(size=6) * 5
    out = run_compensator(model, wrench, np.concatenate([q, v]), accel=a)
    row = np.concatenate([q, v, a])[None, :]
    np.testing.assert_allclose(out["wrench_internal"][-1], model.predict(row)[0],
                               rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(out["wrench_std"][-1], model.predict_std(row)[0],
                               rtol=1e-9, atol=1e-12)
    assert (out["wrench_std"][-1] > 0).all()
    np.testing.assert_array_equal(out["wrench_compensated"][-1],
                                  wrench - out["wrench_internal"][-1])
