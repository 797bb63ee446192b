"""Compliant joint transmissions: the motor side of a two-mass model per joint.

Each joint is a motor of reflected inertia ``J = J_m N²`` driving the link through a gearbox
spring ``k`` and damper ``d`` (all at the output side, per joint)::

    J φ̈ = τ_m − τ_s,     M(q) q̈ + C(q, q̇) = τ_g(q) + τ_s,
    τ_s = k (φ − q) + d (φ̇ − q̇)

``φ`` is the motor angle divided by the gear ratio: what the encoder on the motor shaft
reports, and what the controller feeds back. The tool moves with ``q``.

With a gearbox kinematic error (``transmission_error`` e, ``transmission_error_cycles`` c),
the spring's link end stands at ``φ + e·sin(c·N·φ)`` instead of ``φ`` (rate
``φ̇·(1 + e·c·N·cos(c·N·φ))``): a ripple the motor-side encoder does not see, whose
frequency ``c·N·φ̇`` grows with speed. The motor feels the spring's torque unscaled (the
error's virtual-work factor ``1 + e·c·N·cos(·)`` on the motor's side is left out: it
differs from 1 by at most ``e·c·N``, a few per cent for catalogue errors).

How it is integrated at the scenario's 1 ms step, and why: the link side of the spring is
Drake's PD-controlled joint actuator (``JointActuator.set_controller_gains``: Kp = k, Kd = d,
desired state ``[φ, φ̇]`` on the plant's ``desired_state`` input), which the SAP solver treats
*implicitly*. A gearbox spring against the wrist's small link inertia has modes of several
kHz, which an explicit force element cannot integrate at 1 ms; implicitly they are stable.
The motor side, in :class:`MotorSide`, is integrated explicitly (semi-implicit Euler): its
mode against a held link, ``√(k/J)``, is 30–50 Hz for catalogue values, ``ω·dt ≈ 0.3``,
well inside the explicit step's stability bound ``ω·dt < 2``; :func:`check_motor_step`
checks that bound. (The alternative, a 10–20× finer plant step, costs as many times the run
time.)

:func:`configure_plant_transmission` sets the gains on a plant before ``Finalize``.
"""

from __future__ import annotations

import numpy as np
from pydrake.multibody.tree import JointActuatorIndex, PdControllerGains
from pydrake.systems.framework import BasicVector, LeafSystem

from ..config.transmission import TransmissionConfig
from ..errors import ConfigError

# ω·dt must stay below 2 for the explicit motor step to be stable; keep a margin.
STABILITY_MARGIN = 4.0


def configure_plant_transmission(plant, arm, config: TransmissionConfig) -> None:
    """Makes each of `arm`'s joint actuators the link end of its gearbox spring (before
    ``plant.Finalize()``): PD gains (k, d) towards the plant's desired state, no effort limit
    (a spring transmits what it is deflected by; the motor's torque is not limited here).
    """
    actuators = arm_actuators(plant, arm)
    if len(actuators) != len(config.stiffness):
        raise ConfigError(f"scenario.transmission: has {len(config.stiffness)} joints; the arm "
                          f"has {len(actuators)} actuators")
    for index, k, d in zip(actuators, config.stiffness, config.damping(), strict=True):
        actuator = plant.get_mutable_joint_actuator(index)
        actuator.set_controller_gains(PdControllerGains(p=float(k), d=float(d)))
        actuator.set_effort_limit(np.inf)


def arm_actuators(plant, arm) -> list:
    """`arm`'s joint actuator indices in the order they were added (the model file's, proximal
    first); works before ``Finalize`` (``GetJointActuatorIndices`` does not)."""
    return [JointActuatorIndex(i) for i in range(plant.num_actuators())
            if plant.get_joint_actuator(JointActuatorIndex(i)).model_instance() == arm]


def check_motor_step(config: TransmissionConfig, period: float) -> None:
    """Raises ConfigError when a motor's explicit step would be unstable (or nearly so)."""
    for i, (k, J) in enumerate(zip(config.stiffness, config.reflected_inertia(), strict=True)):
        omega = np.sqrt(k / J)
        if omega * period > 2.0 / STABILITY_MARGIN:
            raise ConfigError(
                f"scenario.transmission: joint {i}'s motor mode √(k/J) = {omega:.0f} rad/s is "
                f"too fast for the {period * 1e3:g} ms step (ω·dt = {omega * period:.2f}, "
                f"keep below {2.0 / STABILITY_MARGIN:.2f}): lower stiffness[{i}], raise "
                f"rotor_inertia[{i}] or the gear ratio, or shorten scenario.time_step")


class MotorSide(LeafSystem):
    """The motors of the two-mass joint model, stepped every `period` s.

    ``τ_s = k (φ − q) + d (φ̇ − q̇)``, ``φ̇⁺ = φ̇ + dt (τ_m − τ_s) / J``, ``φ⁺ = φ + dt φ̇⁺``,
    with ``J = J_m N²`` (all per joint, at the output side).

    Input ports:
      motor_torque (n): the motors' torque at the output, ``N · τ_motor`` (N·m): the
        controller's command (after friction, when on).
      link_state (2n): ``[q (rad), q̇ (rad/s)]`` of the links (the plant's state port).
    Output ports:
      motor_state (2n): ``[φ, φ̇]`` = motor angle / N (rad), its rate (rad/s): what the
        encoders report and the controller reads; also the plant's ``desired_state``
        (the spring's motor end) without a transmission error.
      link_reference (2n): the spring's link end ``[φ + e·sin(c·N·φ), its rate]`` (rad,
        rad/s): the plant's ``desired_state`` with a transmission error (= motor_state
        without one).
      deflection (n): ``φ − q`` (rad), the gearbox's twist.
      spring_torque (n): ``τ_s`` (N·m) the spring applies to the link.
    State: ``[φ, φ̇]`` (2n), discrete, updated every `period` s.
    """

    def __init__(self, config: TransmissionConfig, period: float):
        super().__init__()
        config.validate()
        check_motor_step(config, period)
        n = self.n = len(config.stiffness)
        self.k = np.asarray(config.stiffness, dtype=float)
        self.d = np.asarray(config.damping(), dtype=float)
        self.J = np.asarray(config.reflected_inertia(), dtype=float)
        self.has_error = config.has_transmission_error()
        self.error = np.asarray(config.transmission_error or np.zeros(n), dtype=float)
        self.error_rate = config.transmission_error_cycles * np.asarray(config.gear_ratio,
                                                                        dtype=float)
        self.period = float(period)
        self._torque = self.DeclareVectorInputPort("motor_torque", n)
        self._link = self.DeclareVectorInputPort("link_state", 2 * n)
        self._state = self.DeclareDiscreteState(2 * n)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        state = {self.discrete_state_ticket(self._state)}
        link = {self.input_port_ticket(self._link.get_index())}
        self.DeclareStateOutputPort("motor_state", self._state)
        self.DeclareVectorOutputPort("link_reference", 2 * n, self._calc_link_reference,
                                     prerequisites_of_calc=state)
        self.DeclareVectorOutputPort("deflection", n, self._calc_deflection,
                                     prerequisites_of_calc=state | link)
        self.DeclareVectorOutputPort("spring_torque", n, self._calc_spring,
                                     prerequisites_of_calc=state | link)

    def get_input_port_motor_torque(self):
        return self.GetInputPort("motor_torque")

    def get_input_port_link_state(self):
        return self.GetInputPort("link_state")

    def get_output_port_motor_state(self):
        return self.GetOutputPort("motor_state")

    def get_output_port_link_reference(self):
        return self.GetOutputPort("link_reference")

    def get_output_port_deflection(self):
        return self.GetOutputPort("deflection")

    def get_output_port_spring_torque(self):
        return self.GetOutputPort("spring_torque")

    def link_reference(self, motor_state) -> np.ndarray:
        """The spring's link end (2n,) for ``[φ, φ̇]``: ``[φ + e·sin(c·N·φ), φ̇·(1 +
        e·c·N·cos(c·N·φ))]``; `motor_state` itself without a transmission error."""
        motor_state = np.asarray(motor_state, dtype=float)
        if not self.has_error:
            return motor_state
        n = self.n
        phase = self.error_rate * motor_state[:n]
        return np.concatenate([
            motor_state[:n] + self.error * np.sin(phase),
            motor_state[n:] * (1.0 + self.error * self.error_rate * np.cos(phase))])

    def spring_torque(self, motor_state, link_state) -> np.ndarray:
        """τ_s (n,) for ``[φ, φ̇]`` and ``[q, q̇]`` (with the transmission error, from the
        spring's link end :meth:`link_reference`)."""
        n = self.n
        end = self.link_reference(motor_state)
        return (self.k * (end[:n] - link_state[:n])
                + self.d * (end[n:] - link_state[n:]))

    def static_motor_state(self, q, load_torque) -> np.ndarray:
        """``[φ, 0]`` holding the link at `q` against a static `load_torque` (N·m, the
        generalized force the load applies to the link): ``φ = q − load / k``."""
        q = np.asarray(q, dtype=float)
        return np.concatenate([q - np.asarray(load_torque, dtype=float) / self.k,
                               np.zeros(self.n)])

    def set_motor_state(self, context, motor_state) -> None:
        """Sets ``[φ, φ̇]`` in this system's `context`."""
        context.SetDiscreteState(self._state, np.asarray(motor_state, dtype=float))

    def _update(self, context, discrete_state):
        n = self.n
        x = context.get_discrete_state(self._state).get_value()
        tau_s = self.spring_torque(x, self._link.Eval(context))
        v = x[n:] + self.period * (self._torque.Eval(context) - tau_s) / self.J
        discrete_state.set_value(self._state, np.concatenate([x[:n] + self.period * v, v]))

    def _calc_link_reference(self, context, output: BasicVector):
        x = context.get_discrete_state(self._state).get_value()
        output.SetFromVector(self.link_reference(x))

    def _calc_deflection(self, context, output: BasicVector):
        x = context.get_discrete_state(self._state).get_value()
        output.SetFromVector(x[:self.n] - self._link.Eval(context)[:self.n])

    def _calc_spring(self, context, output: BasicVector):
        x = context.get_discrete_state(self._state).get_value()
        output.SetFromVector(self.spring_torque(x, self._link.Eval(context)))
