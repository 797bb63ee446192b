"""Reading a table of static poses: one pose held still and the wrench read there per row.

The sensor's orientation comes either as **joint angles** (``q_*`` columns, rad or deg; with a
robot description they give gravity in S) or **directly as a rotation**, one of (checked in
this order, :data:`ORIENTATIONS`)

- ``qw, qx, qy, qz``: the quaternion of ``R_WS`` (S in the world; gravity along −z of W),
- ``r00 … r22``: ``R_WS`` row by row,
- ``roll, pitch, yaw`` (rad): ``R_WS = RollPitchYaw(roll, pitch, yaw)`` (Drake's, extrinsic
  x-y-z),
- ``gx, gy, gz``: gravity in S (m/s²; a unit vector is scaled to 9.81 m/s²).

A table may also name a known payload per row (:data:`KNOWN_MASS`, :data:`KNOWN_COM`), for
the gain/cross-talk correction (:mod:`.correction`). Every problem raises a LogError or
ConfigError naming the column.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
from pydrake.math import RollPitchYaw

from ...conventions import GRAVITY_W
from ...data.logs import expand_columns, is_table, read_frame, time_columns
from ...errors import ConfigError, LogError, option_name, spelled
from ..identification.consistent import PayloadPrior

#: Orientation column sets, in the order they are looked for.
ORIENTATIONS = {
    "quaternion": ("qw", "qx", "qy", "qz"),
    "rotation_matrix": tuple(f"r{i}{j}" for i in range(3) for j in range(3)),
    "roll_pitch_yaw": ("roll", "pitch", "yaw"),
    "gravity": ("gx", "gy", "gz"),
}
#: Table columns of a known payload per row (kg; m, from So in S): several loads in one table.
KNOWN_MASS = "known_mass"
KNOWN_COM = ("known_com_x", "known_com_y", "known_com_z")


def orientation_kind(columns) -> str | None:
    """Which orientation columns a table has (a key of :data:`ORIENTATIONS`), or None."""
    present = set(columns)
    for kind, names in ORIENTATIONS.items():
        if set(names) <= present:
            return kind
    return None


def gravity_in_sensor(frame: pd.DataFrame, kind: str, gravity=GRAVITY_W) -> np.ndarray:
    """(N, 3) gravity expressed in S from the orientation columns of `kind`."""
    g_W = np.asarray(gravity, dtype=float)
    values = numeric_columns(frame, ORIENTATIONS[kind])
    if kind == "gravity":
        norm = np.linalg.norm(values, axis=1)
        if np.any(norm == 0):
            raise LogError("gx, gy, gz: a row has zero gravity")
        unit = np.all(np.abs(norm - 1.0) < 0.05)
        return values * (np.linalg.norm(g_W) if unit else 1.0)
    if kind == "quaternion":
        q = values / np.linalg.norm(values, axis=1, keepdims=True)
        w, x, y, z = q.T
        R = np.stack([
            np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ], axis=1)
    elif kind == "rotation_matrix":
        R = values.reshape(-1, 3, 3)
        err = np.abs(R @ np.transpose(R, (0, 2, 1)) - np.eye(3)).max()
        if err > 1e-3:
            raise LogError(f"r00..r22: not a rotation matrix (|R Rᵀ − I| = {err:.2g})")
    else:
        R = np.array([RollPitchYaw(r).ToRotationMatrix().matrix() for r in values])
    return np.einsum("nji,j->ni", R, g_W)  # g_S = R_WSᵀ g_W


def static_table_hint(path, time: str | None = None, positions=None) -> str | None:
    """For ``train``: a sentence pointing to ``ftdrake calibrate`` when `path` is a table of
    static poses, else None. Static poses: orientation columns, or no time column (neither
    `time`, default ``t``, nor a column named like one, e.g. ``time``) and joint columns
    (`positions`, default ``q_*``) that jump from pose to pose rather than move smoothly."""
    if not is_table(path):
        return None
    try:
        frame = read_frame(path)
    except (LogError, OSError):
        return None
    columns = [str(c) for c in frame.columns]
    if orientation_kind(columns) is None:
        if (time or "t") in columns or time_columns(columns):
            return None  # a time series: its own error names --time
        joints = joint_columns(frame, positions or "q_*")
        if joints and _moves_smoothly(frame[joints].to_numpy(dtype=float)):
            return None
    how = spelled("ftdrake.calibrate_table on its rows (a DataFrame)",
                  f"`ftdrake calibrate {option_name('data')} {path}`")
    return (f"{Path(path).name} looks like a table of static poses (orientation columns, or "
            f"joints that jump from pose to pose and no time column): identify payload and "
            f"biases with {how} (add {option_name('robot')}/{option_name('sensor_frame')} "
            "for joint angles)")


def _moves_smoothly(q: np.ndarray) -> bool:
    """Whether joint rows look like samples of a motion (steps small next to the range
    covered) rather than poses one after another."""
    if len(q) < 3 or not np.isfinite(q).all():
        return False
    span = float(np.ptp(q, axis=0).max())
    if span == 0.0:
        return False  # one pose held: static
    step = float(np.median(np.abs(np.diff(q, axis=0)).max(axis=1)))
    return step < 0.02 * span


def known_payload_rows(frame, known) -> tuple[np.ndarray | None, int]:
    """(N, 4) ``[m, m·c]`` per row from `known` (mass, com) or the table's known_* columns,
    and the number of distinct loads; (None, 1) when neither is given."""
    has_columns = KNOWN_MASS in frame
    if known is not None and has_columns:
        raise ConfigError(f"a known payload is given twice: as known_payload and as the "
                          f"table's {KNOWN_MASS!r} column; keep one")
    if known is None and not has_columns:
        return None, 1
    if has_columns:
        mass = numeric_columns(frame, [KNOWN_MASS])[:, 0]
        com = numeric_columns(frame, list(KNOWN_COM))
        where = f"column {KNOWN_MASS!r}"
    else:
        known = dict(known) if not isinstance(known, PayloadPrior) else {
            "mass": known.mass, "com": known.com}
        unknown = set(known) - {"mass", "com"}
        if unknown:
            raise ConfigError(f"known_payload: unknown fields {sorted(unknown)}; give mass "
                              "(kg) and com (m, from So in S)")
        mass = np.full(len(frame), float(known.get("mass", np.nan)))
        com = np.tile(np.asarray(known.get("com", (0.0, 0.0, 0.0)), float).reshape(1, 3),
                      (len(frame), 1))
        where = "known_payload.mass"
    if not np.all(np.isfinite(mass) & (mass > 0)):
        raise ConfigError(f"{where}: a known mass must be a positive number of kg, got "
                          f"{mass[~(np.isfinite(mass) & (mass > 0))][0]}")
    if not np.all(np.isfinite(com)):
        raise ConfigError("known centre of mass: must be three finite numbers (m)")
    payload = np.column_stack([mass, mass[:, None] * com])
    loads = len(np.unique(np.round(payload, 9), axis=0))
    return payload, loads


def joint_columns(frame, positions) -> list[str]:
    try:
        return expand_columns(positions, list(frame.columns), "joint position columns")
    except (LogError, ConfigError):
        return []


def joint_layout(frame, joint_cols, position_unit="rad") -> np.ndarray:
    missing = [c for c in joint_cols if c not in frame]
    if missing:
        raise LogError(f"the table has no joint columns {missing}")
    q = numeric_columns(frame, joint_cols)
    if position_unit == "deg":
        q = np.radians(q)
    return np.hstack([q, np.zeros((len(q), 2 * q.shape[1]))])


def numeric_columns(frame, names) -> np.ndarray:
    missing = [n for n in names if n not in frame]
    if missing:
        raise LogError(f"the table has no column(s) {missing}")
    values = frame[list(names)].to_numpy(dtype=float)
    bad = ~np.isfinite(values).all(axis=1)
    if bad.any():
        raise LogError(f"columns {list(names)}: NaN or empty in {bad.sum()} rows (first at row "
                       f"{int(np.flatnonzero(bad)[0])})")
    return values
