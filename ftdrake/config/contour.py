"""Typed configuration of the tool-side measurements and the hole-cutting task.

Plain dataclasses (readable with Drake's YAML loader like the scenario tree), used by
:mod:`ftdrake.sim.tool_measurement` and :mod:`ftdrake.experiments.contour`. Units SI.
"""

# No `from __future__ import annotations`: Drake's YAML loader needs real type objects.

import dataclasses as dc
import math

from ..errors import ConfigError


def _check(ok: bool, where: str, message: str) -> None:
    if not ok:
        raise ConfigError(f"{where}: {message}")


def _check_registration(config, where: str, d: int) -> None:
    for name in ("frame_rotation_rad", "frame_offset_m"):
        value = getattr(config, name)
        _check(len(value) == d and all(math.isfinite(v) for v in value), f"{where}.{name}",
               f"must be {d} finite numbers, got {value}")


@dc.dataclass
class TrackerConfig:
    """A timed tool-tip position measurement, like a laser tracker's.

    Samples the tip every ``1 / rate_hz`` s; each sample carries white noise of
    ``noise_std_m`` per axis and reaches the user ``latency_s`` later, stamped with its
    arrival time (``stamp_corrected``: stamped with the time it was taken, as a tracker
    synchronised with the controller is).

    Mis-registration (all zero by default: the tracker measures in the robot's base frame B
    on the controller's clock): the tracker's frame T sits at ``frame_offset_m`` (p_BT, m)
    rotated by ``frame_rotation_rad`` (R_BT as a rotation vector, rad), and its clock reads
    ``(1 + clock_skew) · t + clock_offset_s``. When any is set, the experiment registers the
    measurement before using it (:mod:`ftdrake.experiments.tool_registration`):
    ``registration`` ``"fiducials"`` estimates the frame from ``fiducials_m`` (points known
    in B, measured with the tracker's noise) and the clock from the path; ``"path"`` both
    from the path (which hides the rigid part of the tool's error, see that module).
    """

    rate_hz: float = 1000.0  # laser trackers stream at up to 1 kHz (e.g. Leica AT960)
    noise_std_m: float = 10e-6  # of the order of a tracker's ±15 µm + 6 µm/m (MPE) at 1–2 m
    latency_s: float = 0.0
    stamp_corrected: bool = True
    seed: int = 0
    frame_rotation_rad: list[float] = dc.field(default_factory=lambda: [0.0, 0.0, 0.0])
    frame_offset_m: list[float] = dc.field(default_factory=lambda: [0.0, 0.0, 0.0])
    clock_offset_s: float = 0.0
    clock_skew: float = 0.0
    registration: str = "fiducials"
    # Four nests around the robot's base (m, in B), as a tracker's set-up measures.
    fiducials_m: list[list[float]] = dc.field(default_factory=lambda: [
        [0.8, 0.6, 0.0], [0.8, -0.6, 0.0], [-0.3, 0.6, 0.2], [-0.3, -0.6, 0.5]])

    @property
    def misregistered(self) -> bool:
        """True when the simulated tracker is off the base frame or the controller's clock."""
        return bool(any(self.frame_rotation_rad) or any(self.frame_offset_m)
                    or self.clock_offset_s or self.clock_skew)

    def validate(self, where: str = "tracker") -> "TrackerConfig":
        _check(math.isfinite(self.rate_hz) and self.rate_hz > 0, f"{where}.rate_hz",
               f"must be > 0 Hz, got {self.rate_hz}")
        _check(math.isfinite(self.noise_std_m) and self.noise_std_m >= 0,
               f"{where}.noise_std_m", f"must be >= 0 m, got {self.noise_std_m}")
        _check(math.isfinite(self.latency_s) and self.latency_s >= 0, f"{where}.latency_s",
               f"must be >= 0 s, got {self.latency_s}")
        _check_registration(self, where, 3)
        _check(math.isfinite(self.clock_offset_s), f"{where}.clock_offset_s",
               f"must be finite (s), got {self.clock_offset_s}")
        _check(math.isfinite(self.clock_skew) and abs(self.clock_skew) < 0.01,
               f"{where}.clock_skew", f"must be within ±0.01 (a clock's rate error), got "
               f"{self.clock_skew}")
        _check(self.registration in ("fiducials", "path"), f"{where}.registration",
               f"'fiducials' or 'path', got {self.registration!r}")
        _check(len(self.fiducials_m) >= 3 and all(len(f) == 3 for f in self.fiducials_m),
               f"{where}.fiducials_m", "must list >= 3 points [x, y, z] (m) not on one line")
        return self


@dc.dataclass
class ContourScanConfig:
    """An untimed inspection of the cut contour: points in the cutting plane, no times.

    The tool path's points are resampled every ``spacing_m`` of arc length along the
    path (as a scanner or a camera sees the cut edge) with white noise of ``noise_std_m``
    per in-plane axis.
    """

    spacing_m: float = 0.2e-3
    noise_std_m: float = 10e-6  # a measuring microscope / vision scan of a cut edge
    seed: int = 0
    # Mis-registration (zero by default): the instrument's frame in the plane, rotated by
    # ``frame_rotation_rad`` about the plane's normal and offset by ``frame_offset_m``
    # (in-plane, m); the experiment then registers the scan to the commanded path, or to
    # ``datums_m`` (in-plane points of the part known in the plane's frame, measured with
    # the scan's noise) when ``registration`` is "datums".
    frame_rotation_rad: float = 0.0
    frame_offset_m: list[float] = dc.field(default_factory=lambda: [0.0, 0.0])
    registration: str = "datums"
    datums_m: list[list[float]] = dc.field(default_factory=lambda: [
        [0.05, 0.05], [-0.05, 0.05], [0.0, -0.06]])

    @property
    def misregistered(self) -> bool:
        """True when the simulated scan is off the plane's frame."""
        return bool(self.frame_rotation_rad or any(self.frame_offset_m))

    def validate(self, where: str = "contour_scan") -> "ContourScanConfig":
        _check(math.isfinite(self.spacing_m) and self.spacing_m > 0, f"{where}.spacing_m",
               f"must be > 0 m, got {self.spacing_m}")
        _check(math.isfinite(self.noise_std_m) and self.noise_std_m >= 0,
               f"{where}.noise_std_m", f"must be >= 0 m, got {self.noise_std_m}")
        _check(math.isfinite(self.frame_rotation_rad), f"{where}.frame_rotation_rad",
               f"must be finite (rad), got {self.frame_rotation_rad}")
        _check(len(self.frame_offset_m) == 2 and all(map(math.isfinite, self.frame_offset_m)),
               f"{where}.frame_offset_m", f"must be 2 finite numbers (m), got "
               f"{self.frame_offset_m}")
        _check(self.registration in ("datums", "path"), f"{where}.registration",
               f"'datums' or 'path', got {self.registration!r}")
        _check(len(self.datums_m) >= 3 and all(len(f) == 2 for f in self.datums_m),
               f"{where}.datums_m", "must list >= 3 in-plane points [x, y] (m) not in a line")
        return self


@dc.dataclass
class HoleConfig:
    """A contour to cut: a circle (or a slot) in a plane, entered along an arc lead-in from
    its centre.

    The plane passes through the tool tip's position at the scenario's home pose plus
    ``offset_m`` (its centre); its normal is ``normal`` in W (default +z, horizontal); the tool
    points against the normal. The path: rest at the centre, a half-circle lead-in that meets
    the contour tangentially, one full turn at ``speed_m_s`` (``direction`` "ccw":
    counter-clockwise about the normal, "cw": clockwise), a lead-out along the contour while
    slowing down, rest.

    The contour: a circle of ``diameter_m``; or, when ``slot_m`` = [length, width] is given, a
    rectangle of those sides (along the plane's x and y) whose corners are rounded to
    ``corner_radius_m``. ``height_m`` > 0 makes the path 3-D: it rises out of the plane by
    ``height_m · sin²(2π u / L)`` (u: arc length along the contour, L its length), two bumps per
    turn. ``tool_tilt_deg`` > 0 reorients the tool along the contour: it leans towards the
    contour's outward normal by ``tool_tilt_deg · sin²(2π u / L)``.
    """

    diameter_m: float = 0.040
    speed_m_s: float = 0.030  # laser cutting of sheet metal: tens of mm/s
    offset_m: list[float] = dc.field(default_factory=lambda: [0.0, 0.0, 0.0])
    rest_s: float = 0.3
    direction: str = "ccw"
    normal: list[float] = dc.field(default_factory=lambda: [0.0, 0.0, 1.0])
    slot_m: list[float] = dc.field(default_factory=list)
    corner_radius_m: float = 0.002
    height_m: float = 0.0
    tool_tilt_deg: float = 0.0

    def validate(self, where: str = "hole") -> "HoleConfig":
        _check(math.isfinite(self.diameter_m) and 0.002 <= self.diameter_m <= 0.3,
               f"{where}.diameter_m", f"must be in [2, 300] mm, got {self.diameter_m}")
        _check(math.isfinite(self.speed_m_s) and 0 < self.speed_m_s <= 0.5,
               f"{where}.speed_m_s", f"must be in (0, 0.5] m/s, got {self.speed_m_s}")
        _check(len(self.offset_m) == 3 and all(math.isfinite(v) for v in self.offset_m),
               f"{where}.offset_m", f"must be 3 finite numbers (m), got {self.offset_m}")
        _check(math.isfinite(self.rest_s) and self.rest_s >= 0, f"{where}.rest_s",
               f"must be >= 0 s, got {self.rest_s}")
        _check(self.direction in ("ccw", "cw"), f"{where}.direction",
               f"'ccw' or 'cw' (about the plane's normal), got {self.direction!r}")
        _check(len(self.normal) == 3 and all(math.isfinite(v) for v in self.normal)
               and math.hypot(*self.normal) > 1e-9, f"{where}.normal",
               f"must be 3 finite numbers, not all zero (a direction in W), got {self.normal}")
        _check(len(self.slot_m) in (0, 2) and all(math.isfinite(v) and 0.002 <= v <= 0.3
                                                  for v in self.slot_m), f"{where}.slot_m",
               f"[] (a circle) or [length, width], each in [2, 300] mm, got {self.slot_m}")
        if self.slot_m:
            _check(math.isfinite(self.corner_radius_m)
                   and 0 < self.corner_radius_m <= 0.5 * min(self.slot_m),
                   f"{where}.corner_radius_m", f"must be in (0, half the slot's width], got "
                   f"{self.corner_radius_m} for a slot of {self.slot_m}")
        _check(math.isfinite(self.height_m) and 0 <= self.height_m <= 0.05, f"{where}.height_m",
               f"must be in [0, 50] mm, got {self.height_m}")
        _check(math.isfinite(self.tool_tilt_deg) and 0 <= self.tool_tilt_deg <= 45,
               f"{where}.tool_tilt_deg", f"must be in [0, 45] degrees, got {self.tool_tilt_deg}")
        return self
