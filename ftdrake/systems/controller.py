"""The arm's inverse-dynamics controller, sampled like a real one.

A robot's joint controller runs at a fixed rate. Drake's ``InverseDynamicsController`` keeps its
PID integral as *continuous* state, which makes the simulator integrate an ODE between the
plant's discrete steps (an error-controlled Runge–Kutta step and witness checks every
millisecond). This
controller is the same law with the integral updated once per period, built only from Drake's
C++ systems, so a diagram that uses it has no continuous state at all.
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.controllers import InverseDynamics
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import LinearSystem, Multiplexer


class DiscreteInverseDynamicsController(Diagram):
    """Computed-torque control with a PID law on the desired acceleration, at `period` s.

    ``τ = ID(q, v, v̇_c)`` with
    ``v̇_c = v̇_d + kp (q_d − q) + kd (v_d − v) + ki z``, ``z[k+1] = z[k] + period (q_d − q)[k]``,
    where ID is the inverse dynamics of `control_plant` (the controller's model of the robot).
    Gains are per joint (arrays of n) or one number for all.

    Input ports:
      estimated_state (2n): ``[q (rad), v (rad/s)]`` of the controlled model instance.
      desired_state (2n): ``[q_d, v_d]``.
      desired_acceleration (n): ``v̇_d`` (rad/s²).
    Output ports:
      control (n): joint torques (N·m), in the order of `control_plant`'s velocities.
    State: the PID integral z (n, rad·s), updated every `period` s.
    """

    def __init__(self, control_plant, kp, ki, kd, period: float):
        super().__init__()
        n = control_plant.num_velocities()
        if control_plant.num_positions() != n:
            raise ValueError("DiscreteInverseDynamicsController needs q and v of equal size")
        if not period > 0:
            raise ValueError(f"period must be > 0 s, got {period}")
        kp, ki, kd = (_gain(g, n, name) for g, name in ((kp, "kp"), (ki, "ki"), (kd, "kd")))
        # InverseDynamics holds a reference to the plant, which Python must keep alive.
        self._control_plant = control_plant
        builder = DiagramBuilder()
        # u = [q_d, v_d, q, v, v̇_d]
        inputs = builder.AddNamedSystem("inputs", Multiplexer([2 * n, 2 * n, n]))
        eye, zero = np.eye(n), np.zeros((n, n))
        pid = builder.AddNamedSystem("pid", LinearSystem(
            A=eye,
            B=period * np.hstack([eye, zero, -eye, zero, zero]),
            C=np.diag(ki),
            D=np.hstack([np.diag(kp), np.diag(kd), -np.diag(kp), -np.diag(kd), eye]),
            time_period=period,
        ))
        inverse_dynamics = builder.AddNamedSystem(
            "inverse_dynamics", InverseDynamics(control_plant, InverseDynamics.kInverseDynamics)
        )
        builder.ExportInput(inputs.get_input_port(0), "desired_state")
        estimated = builder.ExportInput(
            inverse_dynamics.get_input_port_estimated_state(), "estimated_state"
        )
        builder.ConnectInput(estimated, inputs.get_input_port(1))
        builder.ExportInput(inputs.get_input_port(2), "desired_acceleration")
        builder.Connect(inputs.get_output_port(0), pid.get_input_port())
        builder.Connect(pid.get_output_port(),
                        inverse_dynamics.get_input_port_desired_acceleration())
        builder.ExportOutput(inverse_dynamics.get_output_port_generalized_force(), "control")
        builder.BuildInto(self)
        self.set_name("controller")

    def get_input_port_estimated_state(self):
        return self.GetInputPort("estimated_state")

    def get_input_port_desired_state(self):
        return self.GetInputPort("desired_state")

    def get_input_port_desired_acceleration(self):
        return self.GetInputPort("desired_acceleration")

    def get_output_port_control(self):
        return self.GetOutputPort("control")


def _gain(value, n: int, name: str) -> np.ndarray:
    g = np.asarray(value, dtype=float)
    if g.size not in (1, n) or g.ndim > 1:
        raise ValueError(f"{name} must be one number or {n} (one per joint), got {value!r}")
    g = np.broadcast_to(g, (n,)).copy()
    if not np.all(np.isfinite(g)) or np.any(g < 0):
        raise ValueError(f"{name} must be finite and >= 0 per joint, got {value!r}")
    return g
