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


@dc.dataclass
class TrackerConfig:
    """A timed tool-tip position measurement, like a laser tracker's.

    Samples the tip every ``1 / rate_hz`` s; each sample carries white noise of
    ``noise_std_m`` per axis and reaches the user ``latency_s`` later, stamped with its
    arrival time (``stamp_corrected``: stamped with the time it was taken, as a tracker
    synchronised with the controller is).
    """

    rate_hz: float = 1000.0  # laser trackers stream at up to 1 kHz (e.g. Leica AT960)
    noise_std_m: float = 10e-6  # of the order of a tracker's ±15 µm + 6 µm/m (MPE) at 1–2 m
    latency_s: float = 0.0
    stamp_corrected: bool = True
    seed: int = 0

    def validate(self, where: str = "tracker") -> "TrackerConfig":
        _check(math.isfinite(self.rate_hz) and self.rate_hz > 0, f"{where}.rate_hz",
               f"must be > 0 Hz, got {self.rate_hz}")
        _check(math.isfinite(self.noise_std_m) and self.noise_std_m >= 0,
               f"{where}.noise_std_m", f"must be >= 0 m, got {self.noise_std_m}")
        _check(math.isfinite(self.latency_s) and self.latency_s >= 0, f"{where}.latency_s",
               f"must be >= 0 s, got {self.latency_s}")
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

    def validate(self, where: str = "contour_scan") -> "ContourScanConfig":
        _check(math.isfinite(self.spacing_m) and self.spacing_m > 0, f"{where}.spacing_m",
               f"must be > 0 m, got {self.spacing_m}")
        _check(math.isfinite(self.noise_std_m) and self.noise_std_m >= 0,
               f"{where}.noise_std_m", f"must be >= 0 m, got {self.noise_std_m}")
        return self


@dc.dataclass
class HoleConfig:
    """A hole to cut: a circle in a plane, entered along an arc lead-in from its centre.

    The plane is horizontal (normal +z in W) at the tool tip's height at the scenario's
    home pose plus ``offset_m[2]``; the centre is the home tip position plus ``offset_m``.
    The tool points down, normal to the plane. The path: rest at the centre, a half-circle
    lead-in of radius d/4 that meets the hole tangentially, one full turn at ``speed_m_s``,
    a lead-out along the hole while slowing down, rest.
    """

    diameter_m: float = 0.040
    speed_m_s: float = 0.030  # laser cutting of sheet metal: tens of mm/s
    offset_m: list[float] = dc.field(default_factory=lambda: [0.0, 0.0, 0.0])
    rest_s: float = 0.3

    def validate(self, where: str = "hole") -> "HoleConfig":
        _check(math.isfinite(self.diameter_m) and 0.002 <= self.diameter_m <= 0.3,
               f"{where}.diameter_m", f"must be in [2, 300] mm, got {self.diameter_m}")
        _check(math.isfinite(self.speed_m_s) and 0 < self.speed_m_s <= 0.5,
               f"{where}.speed_m_s", f"must be in (0, 0.5] m/s, got {self.speed_m_s}")
        _check(len(self.offset_m) == 3 and all(math.isfinite(v) for v in self.offset_m),
               f"{where}.offset_m", f"must be 3 finite numbers (m), got {self.offset_m}")
        _check(math.isfinite(self.rest_s) and self.rest_s >= 0, f"{where}.rest_s",
               f"must be >= 0 s, got {self.rest_s}")
        return self
