"""The simulated arm: its models, the controller, the cable and the joint friction."""

# No `from __future__ import annotations`: Drake's YAML loader needs real type objects.

import dataclasses as dc

from ..errors import ConfigError
from .checks import finite, non_negative, positive, vector


@dc.dataclass
class ModelsConfig:
    """Where the models come from. package://ftdrake/ resolves to the shipped models/."""

    arm: str = "package://ftdrake/sda10d_arm.sdf"
    tool: str = "package://ftdrake/ft_sensor_tool.sdf"
    environment: str = "package://ftdrake/environment.sdf"
    arm_base_frame: str = "arm_base"
    flange_frame: str = "flange"  # on the arm; the tool's mount frame is welded to it
    tool_mount_frame: str = "ft_sensor"
    sensor_joint: str = "ft_sensor_weld"
    p_WArmBase: list[float] = dc.field(default_factory=lambda: [0.0, 0.0, 0.95])  # m
    # Extra package.xml files for a user's own models.
    package_xmls: list[str] = dc.field(default_factory=list)


@dc.dataclass
class CableConfig:
    """A cable/hose from the forearm to the tool: a configuration-dependent force on the tool.

    Tension = stiffness · softplus(distance − rest_length) along the cable, from the tool's
    attachment point towards the anchor on `anchor_body`, plus `weight_n` of hanging cable
    pulling the attachment point down (world −z). Rigid-body models of the tool miss it.
    """

    enabled: bool = True
    anchor_body: str = "link_r"
    p_anchor: list[float] = dc.field(default_factory=lambda: [0.07, 0.0, 0.12])  # m, in anchor
    p_SAttach: list[float] = dc.field(default_factory=lambda: [-0.04, 0.0, 0.04])  # m, in S
    stiffness: float = 25.0  # N/m
    rest_length: float = 0.20  # m
    weight_n: float = 1.2  # N

    def validate(self, where: str = "cable") -> None:
        vector(self.p_anchor, 3, f"{where}.p_anchor")
        vector(self.p_SAttach, 3, f"{where}.p_SAttach")
        non_negative(self.stiffness, f"{where}.stiffness")
        non_negative(self.rest_length, f"{where}.rest_length")
        non_negative(self.weight_n, f"{where}.weight_n")


@dc.dataclass
class ControllerConfig:
    """Inverse-dynamics control on a plant with a nominal (imperfect) model of the tool."""

    kp: float = 400.0  # 1/s², per joint
    kd: float = 40.0  # 1/s
    ki: float = 0.0  # 1/s³
    # The controller's estimate of the tool: true mass × (1 + tool_mass_error), CoM shifted.
    tool_mass_error: float = -0.15
    tool_com_error: list[float] = dc.field(default_factory=lambda: [0.01, -0.01, 0.0])  # m, in S
    # Adaptive computed torque: add the torque that carries the bias tracker's payload estimate
    # (systems/payload_feedforward.py), so the arm keeps its path after a grasp. Needs
    # bias_tracker.track_payload and a compensator in the station.
    adapt_to_payload: bool = False

    def validate(self, where: str = "controller") -> None:
        positive(self.kp, f"{where}.kp")
        non_negative(self.kd, f"{where}.kd")
        non_negative(self.ki, f"{where}.ki")
        if not -0.9 < self.tool_mass_error < 2.0:
            raise ConfigError(f"{where}.tool_mass_error: {self.tool_mass_error} not in (-0.9, 2)")
        vector(self.tool_com_error, 3, f"{where}.tool_com_error")


@dc.dataclass
class FrictionConfig:
    """Joint friction in the simulated arm that the controller's model does not know.

    Per joint i: ``τ_f = viscous_i · v + coulomb_i · tanh(v / velocity_scale)`` (N·m), taken
    off the actuation torque by :class:`ftdrake.systems.friction.JointFriction`. The tanh is
    a smooth sign: the friction is evaluated from the state at the start of each plant step
    (explicitly), so its slope at v = 0, ``viscous + coulomb / velocity_scale``, must stay
    below ~joint inertia / time step (``build_station`` checks it and names the joint).

    Sizes (one entry per arm joint S, L, E, U, R, B, T; this arm's effort limits are
    300, 300, 150, 150, 60, 60, 30 N·m): the Coulomb level is 1 % of each joint's effort
    limit. For scale: the Franka Emika Panda's identified friction (Gaz et al., "Dynamic
    identification of the Franka Emika Panda robot with retrieval of feasible parameters
    using penalty-based optimization", IEEE RA-L 4(4), 2019) is a sigmoid of amplitude
    0.30-1.28 N·m per joint, i.e. 0.6-7 % of its 87 / 12 N·m joint torque limits, with slopes
    5-10 s/rad, i.e. a tanh velocity scale of 0.2-0.4 rad/s. The viscous coefficients (0.5 %
    of the effort limit per rad/s, so viscous ≈ Coulomb at 2 rad/s) are an assumption of the
    same order, not a measured value. This controller's feedback is stiff in acceleration,
    not torque (kp · M̂): the wrist roll resists 0.3 N·m with ~0.3 rad of error, so larger
    values make tracking errors no industrial servo would show. These add to the SDF's joint
    damping (0.5 N·m·s/rad).

    Off by default in the main scenario; the ``learn-feedforward`` experiment turns it on.
    """

    enabled: bool = False
    coulomb: list[float] = dc.field(
        default_factory=lambda: [3.0, 3.0, 1.5, 1.5, 0.6, 0.6, 0.3])  # N·m
    viscous: list[float] = dc.field(
        default_factory=lambda: [1.5, 1.5, 0.75, 0.75, 0.3, 0.3, 0.15])  # N·m·s/rad
    velocity_scale: float = 0.3  # rad/s: tanh(v / velocity_scale) stands in for sign(v)

    def validate(self, where: str = "friction") -> "FrictionConfig":
        if len(self.coulomb) != len(self.viscous):
            raise ConfigError(f"{where}.viscous: must have one entry per joint like "
                              f"{where}.coulomb ({len(self.coulomb)}), got {len(self.viscous)}")
        for name in ("coulomb", "viscous"):
            finite(getattr(self, name), f"{where}.{name}")
            for v in getattr(self, name):
                non_negative(v, f"{where}.{name}")
        positive(self.velocity_scale, f"{where}.velocity_scale")
        return self
