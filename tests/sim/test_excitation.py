"""The task_covering trajectory kind: within limits and clear, better excitation of the payload
and better coverage of the task's approaches than the kinds that move around home."""

import numpy as np
import pytest

from ftdrake.config import ScenarioConfig
from ftdrake.errors import TrajectoryError
from ftdrake.sim import excitation
from ftdrake.sim.station import robot_geometry
from ftdrake.sim.trajectories import JointLimits, check_limits
from ftdrake.sim.trajectory_plan import make_trajectory

DURATION_S = 14.0  # the scenario's default duration
SEEDS = (0, 1)


@pytest.fixture(scope="module")
def scene():
    config = ScenarioConfig()
    g = robot_geometry(config)
    limits = JointLimits.from_plant(g.plant, g.arm, config.trajectory.acceleration_limit)
    targets = excitation.task_approach_configurations(config.trajectory, config.home_q, g)
    return config, g, limits, targets


def _plan(scene, kind, seed, duration=DURATION_S):
    config, g, limits, _ = scene
    tc = config.trajectory
    tc.kind, tc.duration_s, tc.seed = kind, duration, seed
    return make_trajectory(tc, config.home_q, limits, g)


def _samples(traj, dt=0.05):
    t = np.arange(traj.start_time(), traj.end_time() + 1e-12, dt)
    return np.array([traj.value(ti).ravel() for ti in t])


def test_task_configurations_are_the_contact_kinds_approach(scene):
    """The targets lie on the contact trajectory's own path to each surface: every target of
    a surface is within 5 mrad of a sample of the planned contact run at that surface."""
    config, g, _, targets = scene
    per_surface = len(targets) // len(g.surfaces())
    assert per_surface == 2 * excitation.APPROACH_SAMPLES
    try:
        for k, surface in enumerate(g.surfaces()):
            config.trajectory.contact_target = surface
            contact = _samples(_plan(scene, "contact", 0), dt=0.002)
            mine = targets[k * per_surface:(k + 1) * per_surface]
            distance = np.sqrt(((mine[:, None] - contact[None]) ** 2).sum(axis=2)).min(axis=1)
            assert distance.max() < 5e-3, surface
    finally:
        config.trajectory.contact_target = "table"


@pytest.mark.parametrize("seed", SEEDS)
def test_task_covering_stays_within_limits_and_clear(scene, seed):
    config, g, limits, _ = scene
    traj = _plan(scene, "task_covering", seed)
    check_limits(traj, limits, dt=0.002)  # raises on any violation
    fast = _samples(traj.derivative(1), dt=0.01)
    assert np.all(np.abs(fast) <= limits.velocity * config.trajectory.speed_fraction + 1e-6)
    assert g.clear_of_environment(traj, dt=0.02, margin=excitation.CLEARANCE_M)
    np.testing.assert_allclose(traj.value(0.0).ravel(), config.home_q, atol=1e-9)
    np.testing.assert_allclose(traj.value(DURATION_S).ravel(), config.home_q, atol=1e-9)


def test_task_covering_excites_the_payload_better_than_fourier_and_random(scene):
    """Over the same duration and seeds, the payload regressor's condition number (what the
    physics fit's identifiability depends on) is lower than the best of fourier and random."""
    _, g, _, _ = scene
    cond = {kind: [excitation.regressor_condition_number(_plan(scene, kind, s), g)
                   for s in SEEDS]
            for kind in ("task_covering", "fourier", "random")}
    assert max(cond["task_covering"]) < min(cond["fourier"] + cond["random"]), cond


def test_task_covering_goes_where_the_task_goes(scene):
    """The largest distance from an approach configuration to the nearest sample of the
    motion is smaller than the other free-motion kinds', and the home → hover lines (the
    fast part of each approach) are covered to within 0.1 rad."""
    _, g, _, targets = scene
    gaps = {kind: [excitation.coverage_gap(targets, _samples(_plan(scene, kind, s)))
                   for s in SEEDS]
            for kind in ("task_covering", "fourier", "random", "z_rich", "reference")}
    others = [gap for kind, v in gaps.items() if kind != "task_covering" for gap in v]
    assert max(gaps["task_covering"]) < min(others), gaps
    per_path = excitation.APPROACH_SAMPLES  # home → hover, then hover → near, per surface
    approach = np.vstack([targets[2 * k * per_path:(2 * k + 1) * per_path]
                          for k in range(len(g.surfaces()))])
    for s in SEEDS:
        assert excitation.coverage_gap(approach, _samples(_plan(scene, "task_covering", s))) \
            < 0.1


def test_condition_number_agrees_with_the_identifications_regressor(scene):
    """The planner's condition number equals one computed from the physics compensator's own
    regressor (Drake-checked elsewhere), rows scaled and columns normalised by hand."""
    from ftdrake.compensation.estimators.physics import PhysicsPayloadCompensator

    _, g, _, _ = scene
    traj = _plan(scene, "fourier", 0)
    t = np.arange(0.0, traj.end_time() + 1e-12, 0.1)
    X = np.hstack([np.array([f.value(ti).ravel() for ti in t])
                   for f in (traj, traj.derivative(1), traj.derivative(2))])
    model = PhysicsPayloadCompensator()
    model.n_joints_ = 7
    A = model.regressor(X).copy()
    A[:, 3:, :] *= excitation.TORQUE_ROW_SCALE
    A = A.reshape(-1, 16)
    expected = np.linalg.cond(A / np.linalg.norm(A, axis=0))
    assert excitation.regressor_condition_number(traj, g) == pytest.approx(expected, rel=1e-6)


def test_too_short_a_task_covering_run_is_refused(scene):
    with pytest.raises(TrajectoryError, match="too short for a task_covering"):
        _plan(scene, "task_covering", 0, duration=3.0)


def test_collect_and_the_scenario_yaml_select_it(tmp_path):
    """`collect --trajectory task_covering` (and the old `--kind`) and `trajectory.kind` in a
    scenario file choose the kind; a collected run of it is free motion (no contact)."""
    from ftdrake import conventions as col
    from ftdrake.cli.main import build_parser
    from ftdrake.config import load_config
    from ftdrake.sim.collection import collect

    for flag in ("--trajectory", "--kind"):
        args = build_parser().parse_args(["collect", flag, "task_covering"])
        assert args.trajectory == "task_covering"
    path = tmp_path / "scenario.yaml"
    path.write_text("trajectory:\n  kind: task_covering\n  duration_s: 6.0\n")
    config = load_config(path)
    assert config.trajectory.kind == "task_covering"
    data = collect(config, 1, n_jobs=1, progress=False)
    assert len(data) > 5000 and not data[col.CONTACT_TRUE].any()
