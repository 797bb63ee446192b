"""Reading real tool-side measurements: a tracker's timed log and an inspected contour.

Two CSV files, each with a header row (column names case-insensitive, extra columns ignored):

* **Timed tool-position log** (a laser tracker's export), :func:`read_tracker_log`:
  ``time`` (s, the tracker's clock), ``x, y, z`` (the tool tip in the tracker's frame) and,
  optionally, the tool's orientation as a unit quaternion ``qw, qx, qy, qz`` (tracker frame;
  all four or none). Time must increase strictly.
* **Inspected contour** (a measuring microscope's or a CMM's point list of the cut edge),
  :func:`read_contour_points`: ``x, y`` and optionally ``z``, in the instrument's frame, in the
  order measured or any order; no times.

`unit` scales the positions to metres (``"m"`` or ``"mm"``). Every problem (a missing file or
column, too few rows, a non-finite value, time that does not increase, a quaternion that is
not one) raises :class:`~ftdrake.errors.LogError` naming the file, and the row or column.

:func:`register_tracker_log` and :func:`register_contour_file` then put the measurement in the
robot's base frame (and on the controller's clock) with
:mod:`ftdrake.experiments.tool_registration`.
"""

from __future__ import annotations

import dataclasses as dc
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.spatial.transform import Rotation

from ..errors import LogError
from ..sim.tool_measurement import measure_datums, measure_fiducials
from .tool_registration import Registration, register_contour, register_timed, rigid_fit

#: Fewest rows a measurement file must hold: fewer cannot determine a frame and a clock.
MIN_ROWS = 10
UNITS = {"m": 1.0, "mm": 1e-3}
QUATERNION = ("qw", "qx", "qy", "qz")


@dc.dataclass
class TrackerLog:
    """A timed tool-position log: stamps (N,) s, positions (N, 3) m, orientations (N, 4)
    ``[w, x, y, z]`` or None; all in the tracker's frame and clock."""

    t: np.ndarray
    p: np.ndarray
    quaternion: np.ndarray | None
    source: str = ""


def _read(path, kind: str) -> pd.DataFrame:
    path = Path(path)
    if not path.is_file():
        raise LogError(f"{path}: no such {kind} file")
    try:
        frame = pd.read_csv(path, comment="#", skipinitialspace=True)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as e:
        raise LogError(f"{path}: not a readable CSV {kind} file ({e})") from None
    frame.columns = [str(c).strip().lower() for c in frame.columns]
    return frame


def _columns(frame: pd.DataFrame, names, path, kind: str) -> np.ndarray:
    missing = [n for n in names if n not in frame.columns]
    if missing:
        raise LogError(f"{path}: the {kind} file lacks column(s) {missing}; it has "
                       f"{list(frame.columns)} (need a header row naming {list(names)})")
    try:
        values = frame[list(names)].to_numpy(dtype=float)
    except ValueError as e:
        raise LogError(f"{path}: column(s) {list(names)} hold text where numbers belong "
                       f"({e})") from None
    bad = ~np.isfinite(values)
    if bad.any():
        row, column = np.argwhere(bad)[0]
        raise LogError(f"{path}: row {row + 1} column {names[column]!r} is empty, NaN or "
                       "infinite")
    return values


def _scale(unit: str) -> float:
    if unit not in UNITS:
        raise LogError(f"unit: 'm' or 'mm', got {unit!r}")
    return UNITS[unit]


def _enough(values: np.ndarray, path, kind: str) -> None:
    if len(values) < MIN_ROWS:
        raise LogError(f"{path}: {len(values)} rows are too few for a {kind} (need >= "
                       f"{MIN_ROWS})")


def read_tracker_log(path, *, unit: str = "m") -> TrackerLog:
    """The timed tool-position log at `path` (module docstring's format)."""
    scale = _scale(unit)
    frame = _read(path, "tracker log")
    if "time" not in frame.columns and "t" in frame.columns:
        frame = frame.rename(columns={"t": "time"})
    values = _columns(frame, ("time", "x", "y", "z"), path, "tracker log")
    _enough(values, path, "tracker log")
    t = values[:, 0]
    step = np.diff(t)
    if (step <= 0).any():
        row = int(np.flatnonzero(step <= 0)[0]) + 2
        raise LogError(f"{path}: time must increase strictly; row {row} has t = {t[row - 1]} "
                       f"after {t[row - 2]} (sort the log, or drop repeated samples)")
    quaternion = None
    present = [q for q in QUATERNION if q in frame.columns]
    if present:
        if len(present) != 4:
            raise LogError(f"{path}: an orientation needs all of {list(QUATERNION)}; found "
                           f"only {present}")
        quaternion = _columns(frame, QUATERNION, path, "tracker log")
        norm = np.linalg.norm(quaternion, axis=1)
        if np.abs(norm - 1).max() > 1e-3:
            row = int(np.argmax(np.abs(norm - 1))) + 1
            raise LogError(f"{path}: row {row}'s quaternion has norm {norm[row - 1]:.4f}, "
                           "not 1 (qw, qx, qy, qz of a rotation)")
        quaternion = quaternion / norm[:, None]
    return TrackerLog(t, values[:, 1:] * scale, quaternion, str(path))


def read_contour_points(path, *, unit: str = "m") -> np.ndarray:
    """The inspected contour at `path`: (N, 2) or (N, 3) points (with a ``z`` column), m."""
    scale = _scale(unit)
    frame = _read(path, "contour")
    names = ("x", "y", "z") if "z" in frame.columns else ("x", "y")
    values = _columns(frame, names, path, "contour")
    _enough(values, path, "contour")
    return values * scale


def register_tracker_log(log: TrackerLog, t_model, p_model, *, fiducials_measured=None,
                         fiducials_known=None, **options) -> tuple[Registration, dict]:
    """`log` registered to the modelled path (`t_model` (M,) s on the controller's clock,
    `p_model` (M, 3) m in B): the tracker's pose and clock (:func:`register_timed`), from
    the path alone or, given fiducials (the same points measured by the tracker and known in
    B, (K, 3) each), the pose from them and the clock from the path.

    Returns ``(registration, measurement)``, the measurement in B on the controller's clock:
    ``{"t": (N,), "p": (N, 3), "R": (N, 3, 3) or None}`` (R: the tool's orientation R_BTool).
    """
    fiducials = None
    if (fiducials_measured is None) != (fiducials_known is None):
        raise LogError("fiducials: give both the measured and the known positions")
    if fiducials_measured is not None:
        fiducials = rigid_fit(fiducials_measured, fiducials_known)
    registration = register_timed(log.t, log.p, t_model, p_model, fiducials=fiducials,
                                  **options)
    R = None
    if log.quaternion is not None:
        w, x, y, z = log.quaternion.T
        R = registration.R @ Rotation.from_quat(np.column_stack([x, y, z, w])).as_matrix()
    return registration, {"t": registration.to_controller_time(log.t),
                          "p": registration.apply(log.p), "R": R}


def register_contour_file(points, path_B, **options) -> tuple[Registration, np.ndarray]:
    """Contour `points` (from :func:`read_contour_points`) registered to the commanded path
    `path_B` (:func:`register_contour`); returns ``(registration, points in B)``."""
    registration = register_contour(points, path_B, **options)
    return registration, registration.apply(points)


def register_simulated_timed(stamp, measured, t_model, p_model, tracker
                             ) -> tuple[np.ndarray, np.ndarray, Registration | None]:
    """A simulated tracker's samples (:func:`~ftdrake.sim.tool_measurement.measure_timed`)
    back in W on the controller's clock, as a user would register a real one: unchanged when
    `tracker` is not mis-registered; else the frame from its fiducials (or the path) and the
    clock from the path against the modelled path `t_model`, `p_model` (the motor angles'
    forward kinematics). Returns ``(stamp, measured, registration or None)``."""
    if not tracker.misregistered:
        return stamp, measured, None
    fiducials = {}
    if tracker.registration == "fiducials":
        known, seen = measure_fiducials(tracker)
        fiducials = {"fiducials_measured": seen, "fiducials_known": known}
    log = TrackerLog(np.asarray(stamp, dtype=float), np.asarray(measured, dtype=float), None)
    registration, out = register_tracker_log(log, t_model, p_model, **fiducials)
    return out["t"], out["p"], registration


def register_simulated_scan(scan, ideal_P, config) -> tuple[np.ndarray, Registration | None]:
    """A simulated scan (:func:`~ftdrake.sim.tool_measurement.measure_contour`) back in the
    plane's frame: unchanged when `config` is not mis-registered; else registered by its
    datum points or to the ideal contour `ideal_P` (N, 2). Returns ``(points, registration
    or None)``."""
    if not config.misregistered:
        return scan, None
    if config.registration == "datums":
        known, seen = measure_datums(config)
        registration = rigid_fit(seen, known)
        return registration.apply(scan), registration
    registration, points = register_contour_file(scan, ideal_P)
    return points, registration


__all__ = ["TrackerLog", "read_contour_points", "read_tracker_log", "register_contour_file",
           "register_simulated_scan", "register_simulated_timed", "register_tracker_log"]
