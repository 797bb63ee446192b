"""The adaptive computed-torque term: the torque that carries a grasped payload.

Checked against Drake's own inverse dynamics of the simulated plant with the grasp applied
(a point mass added to the tool body: exact, no model of the wrench transfer), and in the loop
against the arm's tracking before the grasp."""

import dataclasses as dc

import numpy as np
import pytest
from pydrake.multibody.tree import MultibodyForces

from ftdrake import RandomForestCompensator, ScenarioConfig
from ftdrake.config import ConfigError
from ftdrake.sim.events import apply_grasp
from ftdrake.sim.scene import CONTROL_SENSOR_FRAME, make_control_plant
from ftdrake.sim.station import build_station
from ftdrake.systems.payload_feedforward import PayloadFeedforward


@pytest.mark.parametrize("moving", [False, True])
def test_the_torque_is_what_the_grasped_mass_adds_to_the_plant_s_inverse_dynamics(moving):
    config = ScenarioConfig()
    station = build_station(config)
    plant, scene = station.plant, station.scene
    events = config.events  # 0.5 kg at (0, 20, 120) mm from So, in S
    rng = np.random.default_rng(3)
    q = np.asarray(config.home_q) + rng.uniform(-0.6, 0.6, 7)
    v = rng.uniform(-1.0, 1.0, 7) if moving else np.zeros(7)
    vdot = rng.uniform(-3.0, 3.0, 7) if moving else np.zeros(7)
    torques = []
    for grasped in (False, True):
        context = plant.CreateDefaultContext()
        if grasped:
            apply_grasp(events, scene, context)
        plant.SetPositions(context, scene.arm, q)
        plant.SetVelocities(context, scene.arm, v)
        full_vdot = np.zeros(plant.num_velocities())
        plant.SetVelocitiesInArray(scene.arm, vdot, full_vdot)
        forces = MultibodyForces(plant)
        plant.CalcForceElementsContribution(context, forces)  # gravity (the grasp's weight)
        tau = plant.CalcInverseDynamics(context, full_vdot, forces)
        torques.append(plant.GetVelocitiesFromArray(scene.arm, tau))
    expected = torques[1] - torques[0]
    control_plant = make_control_plant(config, scene)
    dut = PayloadFeedforward(control_plant, control_plant.GetFrameByName(CONTROL_SENSOR_FRAME))
    mass, p = events.grasp_mass_kg, np.asarray(events.grasp_p_SP)
    tau = dut.torque(q, v, vdot, np.r_[mass, mass * p])
    print(f"moving={moving}: |τ| {np.linalg.norm(expected):.3f} N·m, "
          f"error {np.max(np.abs(tau - expected)):.2e}")
    assert np.linalg.norm(expected) > 0.5  # a real load on the joints
    np.testing.assert_allclose(tau, expected, atol=1e-9)
    # Through the port: the same, and zero without a payload.
    context = dut.CreateDefaultContext()
    dut.get_input_port_estimated_state().FixValue(context, np.r_[q, v])
    dut.get_input_port_desired_acceleration().FixValue(context, vdot)
    np.testing.assert_array_equal(dut.get_output_port_control().Eval(context), np.zeros(7))
    dut.get_input_port_payload().FixValue(context, np.r_[mass, mass * p])
    np.testing.assert_allclose(dut.get_output_port_control().Eval(context), tau, atol=1e-12)


def test_adapting_needs_the_tracker_s_payload():
    config = ScenarioConfig()
    config = dc.replace(config, controller=dc.replace(config.controller, adapt_to_payload=True))
    with pytest.raises(ConfigError, match=r"bias_tracker\.track_payload: true"):
        build_station(config)
    # The tracker's payload asked for but the tracker itself off: said, not silently unadapted.
    rng = np.random.default_rng(0)
    model = RandomForestCompensator(features="q", n_estimators=2).fit(
        rng.uniform(-1, 1, (50, 21)), rng.normal(size=(50, 6)))
    config = config.with_chain(bias_tracker=dc.replace(config.chain.bias_tracker, enabled=False,
                                                        track_payload=True))
    with pytest.raises(ConfigError, match=r"bias_tracker\.enabled: true"):
        build_station(config, model)
