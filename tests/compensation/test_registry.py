"""The compensator registry: adding a compensator is one module and one registry entry.

Two compensators defined here are registered with one entry each and then work everywhere
the registry feeds. A toy without a robot: tuning presets, model files, the loop
(CompensatorSystem, through its row predictor) and the ONNX refusal. A robot-based one with
its own ``train`` option and a compiled fused loop path (:class:`PointMassCompensator`):
``ftdrake train --model pointmass`` and :func:`ftdrake.make_estimator`, ``ftdrake
evaluate``, the loop (CompensatorSystem and CompensationChain running its fused update),
save/load, and ONNX (it offers none: ``export_onnx`` and ``ftdrake export`` refuse it,
naming the class).
"""

import functools
import json

import numba
import numpy as np
import pandas as pd
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from ftdrake import (
    CompensationChain,
    CompensatorSystem,
    ConfigError,
    RobotOptions,
    ScenarioConfig,
    load_model,
    load_training_data,
    make_estimator,
    save_model,
)
from ftdrake.cli.main import main as ftdrake_cli
from ftdrake.compensation.compiled.loop import fused_update
from ftdrake.compensation.estimators import registry
from ftdrake.compensation.estimators.base import Compensator
from ftdrake.compensation.estimators.build import TrainOption
from ftdrake.compensation.estimators.registry import CompensatorEntry
from ftdrake.compensation.estimators.tuning import param_grid
from ftdrake.compensation.files.onnx_export import export_onnx
from ftdrake.physics.chain import SerialChain, sensor_kinematics_row
from ftdrake.physics.robot import RobotDescription, ftdrake_arm

N = 2  # joints


class MeanCompensator(Compensator):
    """Predicts the training mean plus `gain` × the first joint angle on every output."""

    def __init__(self, features="q", gain=0.0):
        super().__init__(features=features)
        self.gain = gain

    def _fit(self, Z, Y):
        del Z  # Compensator._fit's signature; the mean ignores the inputs
        self.mean_ = Y.mean(axis=0)

    def _predict(self, Z):
        return self.mean_ + self.gain * Z[:, :1]


@pytest.fixture
def registered(monkeypatch):
    entry = CompensatorEntry("mean", MeanCompensator, "training mean", {"gain": 0.5},
                             {"quick": [{"gain": [0.0, 1.0]}]})
    monkeypatch.setitem(registry.REGISTRY, "mean", entry)
    return entry


def data():
    rng = np.random.default_rng(0)
    X = rng.uniform(-1, 1, (60, 3 * N))
    return X, rng.normal(size=(60, 6)) + 3.0


def test_every_shipped_compensator_is_registered_once_with_a_distinct_class():
    classes = [e.cls for e in registry.REGISTRY.values()]
    assert registry.names() == ["rf", "svr", "gpr", "physics", "hybrid", "arm", "imu-physics"]
    assert len(set(classes)) == len(classes)
    for e in registry.REGISTRY.values():
        assert registry.entry_for(e.cls) is e and registry.entry(e.name) is e


def test_unknown_names_list_the_registered_ones():
    with pytest.raises(ValueError, match=r"unknown compensator 'forest'; expected one of \['rf'"):
        registry.entry("forest")


def test_one_entry_makes_a_new_compensator_buildable_tunable_and_loadable(registered, tmp_path):
    model = registered.build()
    assert model.gain == 0.5
    assert param_grid("quick", model) == [{"gain": [0.0, 1.0]}]
    X, Y = data()
    model.fit(X, Y)
    with pytest.raises(ValueError, match="not a registered compensator"):
        registry.entry_for(object())
    loaded = load_model(save_model(model, tmp_path / "m.ftdm", target_names=list("abcdef"),
                                   target_units=["N"] * 6))
    np.testing.assert_array_equal(loaded.predict(X), model.predict(X))


def test_unregistered_compensators_cannot_be_saved(tmp_path):
    X, Y = data()
    with pytest.raises(ValueError, match="not a registered compensator"):
        save_model(MeanCompensator().fit(X, Y), tmp_path / "m.ftdm",
                   target_names=list("abcdef"), target_units=["N"] * 6)


def test_a_new_compensator_runs_in_the_loop_through_its_row_predictor(registered):
    X, Y = data()
    model = registered.build().fit(X, Y)
    assert model.compiled_predictor() is None  # no compiled form: the generic row path
    with pytest.raises(TypeError, match="MeanCompensator has no ONNX export"):
        model.onnx_parts()
    builder = DiagramBuilder()
    q = np.array([0.3, -0.2])
    wrench = np.arange(6.0)
    dut = builder.AddSystem(CompensatorSystem(model, 0.01, n_joints=N))
    builder.Connect(builder.AddSystem(ConstantVectorSource(wrench)).get_output_port(),
                    dut.get_input_port_wrench_measured())
    builder.Connect(builder.AddSystem(ConstantVectorSource(np.r_[q, 0, 0])).get_output_port(),
                    dut.get_input_port_joint_state())
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(0.05)
    context = dut.GetMyContextFromRoot(simulator.get_context())
    expected = model.mean_ + 0.5 * q[0]  # independent of predict: the toy's own formula
    np.testing.assert_allclose(dut.get_output_port_wrench_internal().Eval(context), expected,
                               rtol=1e-12)
    np.testing.assert_allclose(dut.get_output_port_wrench_compensated().Eval(context),
                               wrench - expected, rtol=1e-12)


def test_register_adds_an_entry_once(monkeypatch):
    monkeypatch.setattr(registry, "REGISTRY", dict(registry.REGISTRY))
    new = registry.register(CompensatorEntry("mean", MeanCompensator, "training mean"))
    assert registry.entry("mean") is new and registry.names()[-1] == "mean"
    with pytest.raises(ValueError, match="'mean' is registered already"):
        registry.register(new)


def test_options_a_model_does_not_take_are_refused_naming_those_that_do():
    with pytest.raises(ConfigError, match=r"^identify_mounting is for kind physics, hybrid or "
                                          r"imu-physics on a wrench"):
        make_estimator("rf", options={"identify_mounting": True})
    with pytest.raises(ConfigError, match=r"^drive_gains is for kind physics, hybrid or "
                                          "arm on joint torques"):
        make_estimator("svr", options={"drive_gains": "identify"})
    with pytest.raises(ValueError, match=r"unknown train options \['colour'\]"):
        make_estimator("rf", options={"colour": "red"})
    # An option at its default is not "given": every model accepts it.
    assert make_estimator("rf", options={"identify_mounting": False}).features == "q,qd,qdd"


# -- a robot-based compensator: its own option and a compiled fused loop path ----------------
GRAVITY_W = np.array([0.0, 0.0, -9.81])
WRENCH = [f"meas_{a}" for a in ("Fx", "Fy", "Fz", "Tx", "Ty", "Tz")]
MASS, BIAS = 1.2, np.array([0.5, -0.3, 1.0, 0.02, -0.01, 0.03])  # kg; N, N·m


@functools.lru_cache(maxsize=4)
def serial_chain(description: RobotDescription) -> SerialChain:
    plant, frame_S = description.build_plant()
    return SerialChain.from_plant(plant, frame_S)


@numba.njit
def point_mass_row(row, n, gravity_W, X_pre, kinds, axes, q_index, v_index, theta, mean, std):
    """One row [q, q̇, q̈] → mean = [m·g_S + b_F; b_T], std = 0 (the fused update's kernel)."""
    kin = np.empty((7, 3))  # ω, α, a, g in S; then R_WS
    sensor_kinematics_row(row[:n], row[n:2 * n], row[2 * n:3 * n], gravity_W, X_pre, kinds,
                          axes, q_index, v_index, kin[4:], kin[:4])
    for i in range(3):
        mean[i] = theta[0] * kin[3, i] + theta[1 + i]
        mean[3 + i] = theta[4 + i]
        std[i] = std[3 + i] = 0.0


POINT_MASS_UPDATE = fused_update(point_mass_row)  # compiled at its first call


class PointMassCompensator(Compensator):
    """A point mass m at the sensor origin plus biases on a robot: forces m·g_S + b_F,
    torques b_T (N, N·m, in S), g_S gravity in S from the joint angles through the robot's
    chain. `fixed_mass` (kg): m is not fitted."""

    def __init__(self, features="q", robot=None, sensor_frame=None, base_frame=None,
                 package_xmls=(), fixed_mass=None):
        super().__init__(features=features)
        self.robot = robot
        self.sensor_frame = sensor_frame
        self.base_frame = base_frame
        self.package_xmls = package_xmls
        self.fixed_mass = fixed_mass

    def _chain(self) -> SerialChain:
        return serial_chain(RobotDescription(self.robot, self.sensor_frame, self.base_frame,
                                             tuple(self.package_xmls)))

    def _gravity_S(self, Z):
        q = Z[:, :self.n_joints_]
        return self._chain().evaluate(q, 0 * q, 0 * q, GRAVITY_W).g_S

    def _fit(self, Z, Y):
        g = self._gravity_S(Z)
        if self.fixed_mass is None:
            A = np.hstack([g.reshape(-1, 1), np.tile(np.eye(3), (len(g), 1))])
            mass, *force_bias = np.linalg.lstsq(A, Y[:, :3].reshape(-1), rcond=None)[0]
        else:
            mass = float(self.fixed_mass)
            force_bias = (Y[:, :3] - mass * g).mean(axis=0)
        self.theta_ = np.r_[mass, force_bias, Y[:, 3:].mean(axis=0)]

    def _predict(self, Z):
        g = self._gravity_S(Z)
        torque = np.broadcast_to(self.theta_[4:], (len(Z), 3))
        return np.hstack([self.theta_[0] * g + self.theta_[1:4], torque])

    def fused_loop_update(self):
        args = (int(self.n_joints_), GRAVITY_W, *self._chain().kernel_args(), self.theta_)
        return POINT_MASS_UPDATE, args


FIXED_MASS = TrainOption("fixed_mass", kind=float, metavar="KG",
                         description="pointmass: the mass in kg (default: identified)",
                         scope="(the point mass at the sensor origin)")


def make_point_mass(request):
    """PointMassCompensator on the request's robot: ftdrake's arm, or a file and its frame."""
    robot = request.robot
    if robot.robot is None:
        raise ConfigError(f"--model {request.kind} needs --robot")
    description = (robot.simulated_arm() if robot.is_simulated_arm else
                   RobotDescription(robot.robot_file(), robot.sensor_frame, robot.base_frame))
    return PointMassCompensator(robot=description.model, sensor_frame=description.sensor_frame,
                                base_frame=description.base_frame,
                                package_xmls=description.package_xmls,
                                fixed_mass=request.options["fixed_mass"])


@pytest.fixture
def pointmass(monkeypatch):
    entry = CompensatorEntry("pointmass", PointMassCompensator,
                             "a point mass at the sensor origin + biases", needs_robot=True,
                             wrench_only=True, make=make_point_mass, train_options=(FIXED_MASS,))
    monkeypatch.setitem(registry.REGISTRY, "pointmass", entry)
    return entry


def gravity_in_S(q):
    """g_S per row from Drake's own kinematics (the oracle; the model uses the compiled chain)."""
    plant, frame_S = ftdrake_arm().build_plant()
    context = plant.CreateDefaultContext()
    out = []
    for row in q:
        plant.SetPositions(context, row)
        R_SW = plant.CalcRelativeRotationMatrix(context, frame_S, plant.world_frame())
        out.append(R_SW.multiply(GRAVITY_W))
    return np.array(out)


def oracle(q, theta):
    g = gravity_in_S(q)
    return np.hstack([theta[0] * g + theta[1:4], np.broadcast_to(theta[4:], (len(q), 3))])


def write_log(path, seed, rows=300):
    """A 7-joint log at 100 Hz: smooth joint angles and the point mass's readings + noise."""
    rng = np.random.default_rng(seed)
    t = np.arange(rows) / 100.0
    phase = rng.uniform(0, 2 * np.pi, 7)
    q = 0.8 * np.sin(0.9 * t[:, None] * np.arange(1, 8) / 3 + phase)
    Y = oracle(q, np.r_[MASS, BIAS]) + rng.normal(0, 0.01, (rows, 6))
    frame = pd.DataFrame({"t": t, **{f"q_{j}": q[:, j] for j in range(7)},
                          **{n: Y[:, i] for i, n in enumerate(WRENCH)}})
    frame.to_csv(path, index=False)
    return q, Y


def run_cli(capsys, *argv):
    code = ftdrake_cli([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture
def logs(tmp_path):
    return {name: (tmp_path / f"{name}.csv", *write_log(tmp_path / f"{name}.csv", seed))
            for name, seed in (("train", 0), ("test", 1))}


def test_a_robot_based_compensator_trains_with_its_option_from_cli_and_python(
        pointmass, logs, tmp_path, capsys):
    csv, q, _ = logs["train"]
    with pytest.raises(SystemExit):
        ftdrake_cli(["train", "--help"])
    out = capsys.readouterr().out
    assert "--fixed-mass KG" in out and "pointmass: a point mass" in out
    fitted = tmp_path / "fitted.ftd"
    code, _, err = run_cli(capsys, "train", "--data", csv, "--model", "pointmass", "--robot",
                           "ftdrake", "--out", fitted)
    assert code == 0, err
    model = load_model(fitted)
    assert isinstance(model, PointMassCompensator) and model.fixed_mass is None
    np.testing.assert_allclose(model.theta_, np.r_[MASS, BIAS], atol=5e-3)  # noise 0.01 N

    fixed = tmp_path / "fixed.ftd"
    code, _, err = run_cli(capsys, "train", "--data", csv, "--model", "pointmass", "--robot",
                           "ftdrake", "--fixed-mass", "1.5", "--out", fixed)
    assert code == 0, err
    cli_model = load_model(fixed)
    assert cli_model.fixed_mass == 1.5 and cli_model.theta_[0] == 1.5
    # The force biases absorb the mass error: b_F = mean(F − 1.5·g_S) = b + (1.2 − 1.5)·mean(g_S)
    expected = BIAS[:3] + (MASS - 1.5) * gravity_in_S(q).mean(axis=0)
    np.testing.assert_allclose(cli_model.theta_[1:4], expected, atol=5e-3)

    # Python builds the same model as the command line.
    data = load_training_data(csv)
    python = make_estimator("pointmass", target_names=data.target_names,
                            robot=RobotOptions("ftdrake"), options={"fixed_mass": 1.5})
    np.testing.assert_array_equal(python.fit(data.X, data.Y).theta_, cli_model.theta_)

    # The option is refused by models that do not take it, naming the one that does.
    code, _, err = run_cli(capsys, "train", "--data", csv, "--model", "rf", "--fixed-mass",
                           "2", "--out", tmp_path / "rf.ftd")
    assert code == 2 and "--fixed-mass is for --kind pointmass (the point mass" in err
    code, _, err = run_cli(capsys, "train", "--data", csv, "--model", "pointmass",
                           "--out", tmp_path / "none.ftd")
    assert code == 2 and "--model pointmass needs --robot" in err


def test_a_robot_based_compensator_evaluates_saves_and_refuses_onnx(pointmass, logs,
                                                                    tmp_path, capsys):
    csv, _, _ = logs["train"]
    path = tmp_path / "m.ftd"
    assert run_cli(capsys, "train", "--data", csv, "--model", "pointmass", "--robot", "ftdrake",
                   "--out", path)[0] == 0
    test_csv, q_test, Y_test = logs["test"]
    report = tmp_path / "evaluation.json"
    code, _, err = run_cli(capsys, "evaluate", "--model", path, "--data", test_csv, "--json",
                           report)
    assert code == 0, err
    result = json.loads(report.read_text())
    model = load_model(path)
    mse = np.mean((Y_test - oracle(q_test, model.theta_)) ** 2, axis=0)
    np.testing.assert_allclose([result["metrics"]["all"][n]["mse"] for n in WRENCH], mse,
                               rtol=1e-9)
    assert result["model_class"] == "PointMassCompensator" and result["std"] is None

    # Save/load in Python keeps every prediction.
    copy = load_model(save_model(model, tmp_path / "copy.ftd", target_names=WRENCH,
                                 target_units=["N"] * 3 + ["N*m"] * 3))
    X = load_training_data(test_csv).X
    np.testing.assert_array_equal(copy.predict(X), model.predict(X))

    # No ONNX form: the exporter and `ftdrake export` refuse it, naming the class.
    with pytest.raises(TypeError, match="PointMassCompensator has no ONNX export"):
        export_onnx(model, tmp_path / "m.onnx")
    code, _, err = run_cli(capsys, "export", "--model", path, "--out", tmp_path / "m.onnx")
    assert code == 2 and "a PointMassCompensator has no ONNX export" in err
    assert not (tmp_path / "m.onnx").exists()


def test_a_robot_based_compensator_runs_its_fused_update_in_the_loop(pointmass, logs):
    csv, _, _ = logs["train"]
    data = load_training_data(csv)
    model = make_estimator("pointmass", target_names=WRENCH,
                           robot=RobotOptions("ftdrake")).fit(data.X, data.Y)
    update, _ = model.fused_loop_update()
    assert update is POINT_MASS_UPDATE

    def no_python_predict(Z):
        raise AssertionError("the loop must run the fused update, not predict")

    model._predict = no_python_predict  # only the compiled update may run in the loop
    q = np.array([0.3, -0.5, 0.2, 1.1, -0.4, 0.6, 0.1])
    internal = oracle(q[None, :], model.theta_)[0]
    push = np.array([0.0, 0.0, 12.0, 0.0, 0.0, 0.0])  # N: a contact along S's z

    # CompensatorSystem alone
    dut = CompensatorSystem(model, 1e-3)
    simulator = Simulator(dut)
    context = simulator.get_mutable_context()
    dut.get_input_port_wrench_measured().FixValue(context, internal + push)
    dut.get_input_port_joint_state().FixValue(context, np.r_[q, np.zeros(7)])
    simulator.AdvanceTo(0.005)
    np.testing.assert_allclose(dut.get_output_port_wrench_internal().Eval(context), internal,
                               rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(dut.get_output_port_wrench_compensated().Eval(context), push,
                               atol=1e-12)

    # The product chain around it (no bias tracker): the detector sees the push.
    config = ScenarioConfig()
    config.chain.bias_tracker.enabled = False
    chain = CompensationChain(model, config.chain_config())
    simulator = Simulator(chain)
    context = simulator.get_mutable_context()
    chain.get_input_port_wrench_measured().FixValue(context, internal + push)
    chain.get_input_port_joint_state().FixValue(context, np.r_[q, np.zeros(7)])
    simulator.AdvanceTo(0.2)
    np.testing.assert_allclose(chain.get_output_port_wrench_contact().Eval(context), push,
                               atol=1e-12)
    assert chain.get_output_port_contact().Eval(context)[0] == 1.0
