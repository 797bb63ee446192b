"""DiscreteInverseDynamicsController: Drake's inverse-dynamics control law, sampled."""

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.controllers import InverseDynamicsController
from pydrake.systems.framework import DiagramBuilder

from ftdrake import ScenarioConfig, build_station
from ftdrake.sim.scene import add_scene, make_control_plant
from ftdrake.systems.controller import DiscreteInverseDynamicsController

PERIOD = 1e-3


@pytest.fixture(scope="module")
def control_plant():
    config = ScenarioConfig()
    scene = add_scene(DiagramBuilder(), config)
    return make_control_plant(config, scene)


def fixed_inputs(controller, context, x, x_d, vd_d):
    controller.get_input_port_estimated_state().FixValue(context, x)
    controller.get_input_port_desired_state().FixValue(context, x_d)
    controller.get_input_port_desired_acceleration().FixValue(context, vd_d)


def random_inputs(n, seed):
    rng = np.random.default_rng(seed)
    return rng.uniform(-1, 1, 2 * n), rng.uniform(-1, 1, 2 * n), rng.uniform(-2, 2, n)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_torque_equals_drakes_inverse_dynamics_controller(control_plant, seed):
    n = control_plant.num_positions()
    kp, kd = np.linspace(300, 500, n), np.linspace(30, 50, n)
    ours = DiscreteInverseDynamicsController(control_plant, kp, 0.0, kd, PERIOD)
    drakes = InverseDynamicsController(control_plant, kp, np.zeros(n), kd, True)
    inputs = random_inputs(n, seed)
    torques = []
    for controller in (ours, drakes):
        context = controller.CreateDefaultContext()
        fixed_inputs(controller, context, *inputs)
        torques.append(controller.get_output_port_control().Eval(context))
    np.testing.assert_allclose(torques[0], torques[1], rtol=1e-12, atol=1e-9)
    assert np.abs(torques[0]).max() > 1.0  # not trivially zero


def test_integral_accumulates_once_per_period(control_plant):
    n = control_plant.num_positions()
    ki = 7.0
    ours = DiscreteInverseDynamicsController(control_plant, 400.0, ki, 40.0, PERIOD)
    no_integral = DiscreteInverseDynamicsController(control_plant, 400.0, 0.0, 40.0, PERIOD)
    x, x_d, vd_d = random_inputs(n, 3)
    simulator = Simulator(ours)
    fixed_inputs(ours, simulator.get_mutable_context(), x, x_d, vd_d)
    simulator.AdvanceTo(9.5 * PERIOD)  # updates at t = 0, 1, ..., 9 ms: ten of them
    z = simulator.get_context().get_discrete_state_vector().value()
    np.testing.assert_allclose(z, 10 * PERIOD * (x_d[:n] - x[:n]), rtol=1e-12)
    # The integral enters as the acceleration ki·z: compare with the same law at ki = 0.
    context = no_integral.CreateDefaultContext()
    fixed_inputs(no_integral, context, x, x_d, vd_d + ki * z)
    np.testing.assert_allclose(ours.get_output_port_control().Eval(simulator.get_context()),
                               no_integral.get_output_port_control().Eval(context), rtol=1e-12)


def test_scenario_diagram_has_no_continuous_state():
    station = build_station(ScenarioConfig())
    assert station.diagram.CreateDefaultContext().num_continuous_states() == 0


@pytest.mark.parametrize("kwargs, message", [
    ({"kp": -1.0}, "kp must be finite and >= 0"),
    ({"kd": [1.0, 2.0]}, "kd must be one number or 7"),
    ({"period": 0.0}, "period must be > 0"),
])
def test_bad_gains_or_period_are_refused(control_plant, kwargs, message):
    args = {"kp": 400.0, "ki": 0.0, "kd": 40.0, "period": PERIOD} | kwargs
    with pytest.raises(ValueError, match=message):
        DiscreteInverseDynamicsController(control_plant, **args)
