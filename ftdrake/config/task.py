"""What a run does: the trajectory, the contact task's frames and the events during it."""

# No `from __future__ import annotations`: Drake's YAML loader needs real type objects.

import dataclasses as dc
from typing import Optional

from ..errors import ConfigError
from .checks import non_negative, positive, six, vector

TRAJECTORY_KINDS = ("random", "fourier", "reference", "z_rich", "contact", "rehearsal", "study",
                    "task_covering")
#: The contact-free kinds (what ``collect`` runs); ``rehearsal`` is the contact motion stopping
#: ``trajectory.rehearsal_height_m`` above the surface.
FREE_KINDS = tuple(kind for kind in TRAJECTORY_KINDS if kind != "contact")


@dc.dataclass
class TrajectoryConfig:
    """What the arm does. See :mod:`ftdrake.sim.trajectories` for each kind.

    ``contact`` presses the tool tip into the surface `contact_target` (one of
    ``task.surfaces``); ``rehearsal`` is the same motion stopping `rehearsal_height_m` above
    that surface (contact-free training data that looks like the task)."""

    kind: str = "contact"
    duration_s: float = 14.0
    seed: int = 0
    # Fraction of each joint's speed / acceleration limit the excitation may use.
    speed_fraction: float = 0.3
    acceleration_limit: float = 4.0  # rad/s², every joint
    # Fourier excitation: harmonics of the base frequency.
    base_frequency_hz: float = 0.1
    harmonics: int = 4
    # Contact scenario and its rehearsal. The target is a surface named in task.surfaces.
    contact_target: str = "table"
    # Commanded penetration of the target surface (m); negative: stop that far above it.
    press_depth_m: float = 0.012
    press_duration_s: float = 3.0
    # A rehearsal stops this far above the target surface (m), wherever press_depth_m says.
    rehearsal_height_m: float = 0.03

    def validate(self, where: str = "trajectory") -> None:
        if self.kind not in TRAJECTORY_KINDS:
            raise ConfigError(
                f"{where}.kind: unknown kind {self.kind!r}; expected one of {TRAJECTORY_KINDS}"
            )
        positive(self.duration_s, f"{where}.duration_s")
        if not 0 < self.speed_fraction <= 1:
            raise ConfigError(f"{where}.speed_fraction: {self.speed_fraction} not in (0, 1]")
        positive(self.acceleration_limit, f"{where}.acceleration_limit")
        positive(self.base_frequency_hz, f"{where}.base_frequency_hz")
        if self.harmonics < 1:
            raise ConfigError(f"{where}.harmonics: must be >= 1, got {self.harmonics}")
        # Which names are surfaces is the task's business (ScenarioConfig.validate checks it).
        if not (isinstance(self.contact_target, str) and self.contact_target):
            raise ConfigError(
                f"{where}.contact_target: must name a surface of task.surfaces, "
                f"got {self.contact_target!r}"
            )
        if not -0.2 <= self.press_depth_m <= 0.05:
            raise ConfigError(f"{where}.press_depth_m: {self.press_depth_m} not in [-0.2, 0.05] m")
        positive(self.press_duration_s, f"{where}.press_duration_s")
        positive(self.rehearsal_height_m, f"{where}.rehearsal_height_m")
        if self.rehearsal_height_m > 0.2:
            raise ConfigError(
                f"{where}.rehearsal_height_m: {self.rehearsal_height_m} not in (0, 0.2] m"
            )


@dc.dataclass
class TaskConfig:
    """Where the contact task happens, by frame name: the geometry is read from the models.

    A surface frame lies on the surface, at the point the contact scenario presses, with its
    z axis along the outward normal; it is looked up in ``models.environment``. The tool-tip
    frame sits at the point of the tool that touches, with z along the tool axis pointing out
    of the tip; it is looked up in ``models.tool`` and must be on the sensor's tool side.
    Swapping a model for one with the same frame names moves the task with it.
    """

    # Surface name (what trajectory.contact_target selects) → frame in models.environment.
    # A YAML mapping here adds to (or renames the frames of) these defaults.
    surfaces: dict[str, str] = dc.field(
        default_factory=lambda: {"table": "table_top", "wall": "wall_face"}
    )
    tool_tip_frame: str = "tool_tip"

    def validate(self, where: str = "task") -> None:
        if not self.surfaces:
            raise ConfigError(f"{where}.surfaces: name at least one surface frame")
        for name, frame in self.surfaces.items():
            if not (isinstance(frame, str) and frame):
                raise ConfigError(f"{where}.surfaces.{name}: must be a frame name, got {frame!r}")
        if not (isinstance(self.tool_tip_frame, str) and self.tool_tip_frame):
            raise ConfigError(
                f"{where}.tool_tip_frame: must be a frame name, got {self.tool_tip_frame!r}"
            )


@dc.dataclass
class EventsConfig:
    """Things that happen during a run, to test the tracker and the detector. All are off
    (None) by default; times are simulation times (s).

    - **Re-tare**: at `retare_at_s` the sensor driver's zero offset changes, so every later
      reading is shifted by `retare_offset` (N, N·m, in S) — a tare taken in another pose.
      With `retare_signalled` the tracker's ``tared`` input pulses then (the driver knows
      when it tared).
    - **Grasp**: at `grasp_at_s` a point mass `grasp_mass_kg` is added to the tool at
      `grasp_p_SP` (m, from the sensor origin So, in S) — the plant's inertia changes; the
      controller's model and the compensator do not know. With `grasp_signalled` the
      tracker's ``payload_changed`` input pulses (the gripper's command is known).
    - **Push**: from `push_at_s` a force at the tool tip grows linearly over `push_ramp_s` to
      `push_force_W` (N, world frame), stays for `push_hold_s`, then stops. It is applied as
      an external force (not contact), and it is added to the log's ``external_true_*`` columns
      (at the sensor, in S) like a contact would be.
    """

    retare_at_s: Optional[float] = None
    # ‖F‖ 5.0 N, ‖T‖ 0.20 N·m
    retare_offset: list[float] = dc.field(
        default_factory=lambda: [2.9, -2.9, 2.9, 0.116, -0.116, 0.116])
    retare_signalled: bool = True
    grasp_at_s: Optional[float] = None
    grasp_mass_kg: float = 0.5
    grasp_p_SP: list[float] = dc.field(default_factory=lambda: [0.0, 0.02, 0.12])
    grasp_signalled: bool = True
    push_at_s: Optional[float] = None
    push_ramp_s: float = 5.0
    push_hold_s: float = 1.0
    push_force_W: list[float] = dc.field(default_factory=lambda: [0.0, 0.0, -5.0])
    # How long the tared / payload_changed signals stay high (s): a driver's tare or a
    # gripper's close takes a while, and the tracker re-initialises while the signal is high
    # (so the grasp's transient, while the controller catches the new weight, is not contact).
    signal_s: float = 0.25

    def validate(self, where: str = "events") -> "EventsConfig":
        for name in ("retare_at_s", "grasp_at_s", "push_at_s"):
            value = getattr(self, name)
            if value is not None:
                non_negative(value, f"{where}.{name}")
        six(self.retare_offset, f"{where}.retare_offset")
        positive(self.grasp_mass_kg, f"{where}.grasp_mass_kg")
        vector(self.grasp_p_SP, 3, f"{where}.grasp_p_SP")
        positive(self.push_ramp_s, f"{where}.push_ramp_s")
        non_negative(self.push_hold_s, f"{where}.push_hold_s")
        vector(self.push_force_W, 3, f"{where}.push_force_W")
        positive(self.signal_s, f"{where}.signal_s")
        return self

    @property
    def any(self) -> bool:
        return any(t is not None for t in (self.retare_at_s, self.grasp_at_s, self.push_at_s))

