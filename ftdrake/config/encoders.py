"""Typed configuration of the joint encoders' errors: zero offsets and a gravity sag.

Read as ``scenario.encoders`` (see :class:`~ftdrake.config.ScenarioConfig`). Off by default:
the encoders then read the links' angles exactly and the scenario is unchanged.
"""

# No `from __future__ import annotations`: Drake's YAML loader needs real type objects.

import dataclasses as dc
import math

from ..errors import ConfigError
from .checks import finite


@dc.dataclass
class EncoderConfig:
    """What the arm's joint encoders get wrong (:class:`~ftdrake.systems.encoders.
    JointEncoders`), off by default.

    With ``enabled``, every reader of the joint state (controller, friction, the runtime
    chain, the logged ``q_*`` columns) gets, per joint i,

        q_measured,i = q_link,i + τ_i(q_link) / k_i − offsets_i

    with ``offsets`` (rad: ``q_true = q_measured + offset``) the encoder's zero error and
    ``sag_stiffness`` k_i (N·m/rad; 0: a rigid joint, no sag) the stiffness between the
    encoder (on the motor side) and the link: the link sags from the motor by τ_i/k_i, τ_i
    the torque that holds the arm (tool included) against gravity at that joint. The
    velocities pass unchanged (the sag's rate is left out: a quasi-static sag). Empty lists
    mean zeros; otherwise one entry per arm joint (checked when the station is built). The
    sag needs rigid joints: compliant transmissions (``scenario.transmission``) model it
    with their springs.
    """

    enabled: bool = False
    offsets: list[float] = dc.field(default_factory=list)  # rad per joint
    sag_stiffness: list[float] = dc.field(default_factory=list)  # N·m/rad per joint, 0: none

    def validate(self, where: str = "scenario.encoders") -> "EncoderConfig":
        finite(self.offsets, f"{where}.offsets")
        finite(self.sag_stiffness, f"{where}.sag_stiffness")
        for i, k in enumerate(self.sag_stiffness):
            if k < 0:
                raise ConfigError(f"{where}.sag_stiffness[{i}]: must be >= 0 (0: no sag), "
                                  f"got {k}")
        if self.offsets and self.sag_stiffness and \
                len(self.offsets) != len(self.sag_stiffness):
            raise ConfigError(f"{where}.sag_stiffness: must have one entry per joint like "
                              f"{where}.offsets ({len(self.offsets)}), got "
                              f"{len(self.sag_stiffness)}")
        return self

    def compliance(self, n: int) -> list[float]:
        """1/k per joint (rad/(N·m)), 0 where the joint does not sag; n entries."""
        return [1.0 / k if k > 0 else 0.0 for k in (self.sag_stiffness or [0.0] * n)]

    def offset_list(self, n: int) -> list[float]:
        """The offsets (rad), n entries (zeros when none are given)."""
        return list(self.offsets) if self.offsets else [0.0] * n

    def check_joints(self, n: int, where: str = "scenario.encoders") -> None:
        """Raises ConfigError when a list does not have one entry per arm joint."""
        for name in ("offsets", "sag_stiffness"):
            values = getattr(self, name)
            if values and len(values) != n:
                raise ConfigError(f"{where}.{name}: must have one entry per arm joint ({n}), "
                                  f"got {len(values)}")

    def sags(self) -> bool:
        return any(k > 0 and math.isfinite(k) for k in self.sag_stiffness)
