"""Every Drake system ftdrake defines has a named accessor per port, Drake's way
(``get_input_port_estimated_state()``): found by walking the package, so a new system without
them fails here, not in a user's diagram.

Each system is taken from one "rig" station built with every optional part on (friction, a
push, payload tracking with motion, a temperature model, Meshcat arrows, a feedforward), or
built beside it where one station cannot hold it (the other feedforward, the chain's
joint-state gravity).
"""

import importlib
import inspect
import pkgutil

import numpy as np
import pytest
from pydrake.geometry import Meshcat
from pydrake.systems.framework import Diagram, InputPort, LeafSystem, OutputPort

import ftdrake
from ftdrake import CompensationChain, RandomForestCompensator, build_station
from ftdrake.compensation.estimators.imu_physics import ImuPayloadCompensator
from ftdrake.config import ImuConfig, TransmissionConfig
from ftdrake.systems.imu import ImuNoise
from ftdrake.systems.learned_feedforward import LearnedFeedforward, fit_feedforward_gp
from ftdrake.systems.time_indexed_feedforward import TimeIndexedFeedforward
from ftdrake.systems.transmission import MotorSide
from ftdrake.testing import push_scenario
from tests.helpers import imu_rows

N = 7  # the scenario arm's joints
PACKAGES_OF_SYSTEMS = ("ftdrake.runtime", "ftdrake.systems")


def ftdrake_modules():
    """Every module of the package, imported."""
    yield ftdrake
    for info in pkgutil.walk_packages(ftdrake.__path__, "ftdrake."):
        yield importlib.import_module(info.name)


def system_classes():
    """The Drake systems (LeafSystem or Diagram subclasses) defined in ftdrake's modules."""
    found = {}
    for module in ftdrake_modules():
        for _, cls in inspect.getmembers(module, inspect.isclass):
            if cls.__module__ == module.__name__ and issubclass(cls, (LeafSystem, Diagram)):
                found[f"{cls.__module__}.{cls.__qualname__}"] = cls
    return [found[name] for name in sorted(found)]


SYSTEM_CLASSES = system_classes()


def all_systems(diagram):
    """The diagram's systems and those of every diagram inside it."""
    for system in diagram.GetSystems():
        yield system
        if isinstance(system, Diagram):
            yield from all_systems(system)


def accessors(cls):
    """Names of the named port accessors `cls` defines (its own or a base class's, not
    pydrake's)."""
    return sorted(name for name, _ in inspect.getmembers(cls, inspect.isfunction)
                  if name.startswith(("get_input_port_", "get_output_port_")))


def temperature_forest():
    """A forest trained with the sensor temperature (its last column): the chain then has a
    ``temperature`` input."""
    rng = np.random.default_rng(0)
    return RandomForestCompensator(features="q", n_estimators=2, random_state=0).fit(
        rng.uniform(-1, 2, (60, 3 * N + 1)), rng.normal(size=(60, 6)))


@pytest.fixture(scope="module")
def instances():
    """{class: [instances]} of every ftdrake system in the rig and beside it."""
    config = push_scenario(duration=0.3, push_at=0.1)  # ToolPush
    config.friction.enabled = True  # JointFriction
    config.chain.bias_tracker.track_payload = True  # gravity_S, motion_S, payload_changed, payload
    config.chain.bias_tracker.track_payload_motion = True  # ... and SensorGravity's motion_S
    config.chain.bias_tracker.payload_change.enabled = True  # the PayloadChangeMonitor inside
    config.controller.adapt_to_payload = True  # PayloadFeedforward
    config.encoders.enabled = True  # JointEncoders
    config.sensor.vibration_per_speed = [0.01] * 6  # the noisy sensor's joint inputs
    config.encoders.sag_stiffness = [0.0, 1e4, 0.0, 0.0, 0.0, 0.0, 0.0]
    model = temperature_forest()
    feedforward = TimeIndexedFeedforward(np.zeros((10, N)), 0.01)
    station = build_station(config, model, meshcat=Meshcat(), feedforward=feedforward)
    rng = np.random.default_rng(1)
    X = rng.uniform(-1, 1, (200, 3 * N))
    chain = config.chain_config()
    chain.robot.file = "ftdrake"  # a forest carries no robot: the gravity's kinematics
    delayed = config.chain_config()
    delayed.sensor.wrench_delay_s = 0.004
    beside = [
        LearnedFeedforward(fit_feedforward_gp(X, np.sin(X[:, :N]), max_points=40,
                                              optimize_points=40), n_joints=N),
        CompensationChain(model, chain, gravity="joint_state"),  # JointStateGravity inside
        CompensationChain(model, delayed),  # a DelayLine inside
        MotorSide(TransmissionConfig(enabled=True), config.time_step),  # compliant joints
        ImuNoise(ImuConfig(), config.time_step),  # the IMU at the sensor
        CompensationChain(ImuPayloadCompensator().fit(*imu_rows(60)), chain),  # an imu input
    ]
    systems = list(all_systems(station.diagram))
    for system in beside:
        systems.append(system)
        if isinstance(system, Diagram):
            systems.extend(all_systems(system))
    out = {}
    for system in systems:
        out.setdefault(type(system), []).append(system)
    return out


def test_the_walk_finds_the_runtime_and_the_rig():
    names = {cls.__name__ for cls in SYSTEM_CLASSES}
    assert {"CompensationChain", "CompensatorSystem", "OnlineBiasTracker", "ContactDetector",
            "JointStateGravity", "ForceTorqueSensor", "NoisyForceTorqueSensor",
            "SensorGravity", "ToolPush", "ContactTruth", "DiscreteInverseDynamicsController",
            "JointFriction", "LearnedFeedforward", "TimeIndexedFeedforward",
            "WrenchArrows", "DelayLine", "MotorSide", "JointEncoders", "ImuNoise"} <= names


@pytest.mark.parametrize("cls", SYSTEM_CLASSES, ids=lambda c: c.__name__)
def test_a_system_is_defined_in_runtime_or_systems_one_a_module(cls):
    assert cls.__module__.rsplit(".", 1)[0] in PACKAGES_OF_SYSTEMS, (
        f"{cls.__qualname__} is a Drake system in {cls.__module__}: move it to ftdrake/runtime "
        "(what runs beside the robot) or ftdrake/systems (the simulation rig)")
    same_module = [c.__qualname__ for c in SYSTEM_CLASSES if c.__module__ == cls.__module__]
    assert same_module == [cls.__qualname__], f"{cls.__module__} defines {same_module}"


@pytest.mark.parametrize("cls", SYSTEM_CLASSES, ids=lambda c: c.__name__)
def test_every_port_has_a_named_accessor_that_returns_it(cls, instances):
    assert instances.get(cls), (f"no {cls.__name__} to check: add one to the rig or beside it "
                                "in tests/systems/test_ports.py's `instances` fixture")
    names = accessors(cls)
    for dut in instances[cls]:
        for kind, count, get in (("input", dut.num_input_ports(), dut.get_input_port),
                                 ("output", dut.num_output_ports(), dut.get_output_port)):
            for i in range(count):
                name = get(i).get_name()
                accessor = f"get_{kind}_port_{name}"
                assert accessor in names, f"{cls.__name__} has no {accessor}()"
                port = getattr(dut, accessor)()
                assert (port.get_name(), port.get_index()) == (name, i), accessor
                assert port.get_system() is dut, accessor


@pytest.mark.parametrize("cls", SYSTEM_CLASSES, ids=lambda c: c.__name__)
def test_every_named_accessor_returns_the_port_of_its_name(cls, instances):
    """On at least one instance; where a configuration leaves the port out, the accessor
    raises rather than return another port."""
    names = accessors(cls)
    assert names, f"{cls.__name__} has no named port accessors"
    for accessor in names:
        kind, name = accessor.removeprefix("get_").split("_port_", 1)
        expected_type = InputPort if kind == "input" else OutputPort
        returned = 0
        for dut in instances[cls]:
            has = dut.HasInputPort(name) if kind == "input" else dut.HasOutputPort(name)
            if not has:
                with pytest.raises(RuntimeError, match=name):
                    getattr(dut, accessor)()
                continue
            port = getattr(dut, accessor)()
            assert isinstance(port, expected_type), accessor
            assert port.get_name() == name, f"{cls.__name__}.{accessor}() returns {port}"
            returned += 1
        assert returned, (f"no {cls.__name__} in the test has the port {name!r}: configure "
                          "one that has it in the `instances` fixture")
