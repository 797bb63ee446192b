"""Dataset files: one Parquet file of logs plus the scenario that made them.

A dataset holds the log columns of :mod:`ftdrake.sim.simulate` for several runs stacked, plus
``trajectory`` (int id). The scenario config that made it is stored as YAML in the file's
metadata (key ``ftdrake.scenario``), with the column units (``ftdrake.units``), the ftdrake
version and the layout's version (``ftdrake.log_format``,
:data:`ftdrake.conventions.LOG_FORMAT`; a dataset of an older layout is read with today's
column names, see :func:`~ftdrake.data.logs.read_frame`). ``joint_state_layout`` and
``wrench_targets`` turn a dataset into ``X = [q, q̇, q̈]`` and wrench targets.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from .. import conventions as col
from ..config import ScenarioConfig, parse_config
from ..errors import LogError
from ..io import atomic_path
from ..version import ftdrake_version
from .logs import META_LOG_FORMAT, META_SCENARIO, read_frame

META_UNITS = b"ftdrake.units"
META_VERSION = b"ftdrake.version"


def save_dataset(frame: pd.DataFrame, path: str | Path, scenario_yaml: str | None = None) -> None:
    """Writes `frame` as Parquet with scenario and units metadata, atomically."""
    table = pa.Table.from_pandas(frame, preserve_index=False)
    metadata = dict(table.schema.metadata or {})
    metadata[META_SCENARIO] = (scenario_yaml or frame.attrs.get("scenario") or "").encode()
    metadata[META_UNITS] = json.dumps(column_units(frame.columns)).encode()
    metadata[META_VERSION] = ftdrake_version().encode()
    metadata[META_LOG_FORMAT] = str(col.LOG_FORMAT).encode()
    table = table.replace_schema_metadata(metadata)
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp)


def load_dataset(path: str | Path) -> tuple[pd.DataFrame, ScenarioConfig | None]:
    """Reads a dataset written by :func:`save_dataset`; returns (frame, scenario or None)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no dataset at {path}")
    try:
        frame = read_frame(path, kind="parquet")
    except LogError as e:
        raise LogError(f"{path} is not a readable Parquet dataset: {e}") from None
    text = frame.attrs.get("scenario")
    scenario = parse_config(text, source=f"{path} metadata") if text else None
    return frame, scenario


#: Units of the IMU's columns (:mod:`ftdrake.systems.imu`), by prefix.
IMU_UNITS = {col.IMU_ACC: "m/s^2", col.IMU_GYRO: "rad/s", col.IMU_ALPHA: "rad/s^2"}


def column_units(columns) -> dict[str, str]:
    """Unit of each known column (used for the dataset's metadata and the README)."""
    units = {}
    for name in columns:
        prefix, _, suffix = name.rpartition("_")
        if name == col.TIME:
            units[name] = "s"
        elif prefix in (col.Q,):
            units[name] = "rad"
        elif prefix in (col.QD, col.QD_EST):
            units[name] = "rad/s"
        elif prefix in (col.QDD, col.QDD_EST):
            units[name] = "rad/s^2"
        elif prefix in IMU_UNITS and suffix in col.IMU_AXES:
            units[name] = IMU_UNITS[prefix]
        elif suffix in col.WRENCH_AXES:
            units[name] = "N" if suffix.startswith("F") else "N*m"
        else:
            units[name] = "1"
    return units


def joint_state_layout(frame: pd.DataFrame, source: str = "est", n: int | None = None):
    """``X = [q, q̇, q̈]`` from a dataset: `source` "est" (q̇ and the causal q̈ estimate, as
    the loop's compensator gets them) or "plant" (the simulator's exact values)."""
    if source not in ("est", "plant"):
        raise ValueError(f"source must be 'est' or 'plant', got {source!r}")
    n = n or sum(1 for c in frame.columns if c.startswith("q_") and c[2:].isdigit())
    qd, qdd = (col.QD_EST, col.QDD_EST) if source == "est" else (col.QD, col.QDD)
    blocks = [col.joint_columns(p, n) for p in (col.Q, qd, qdd)]
    missing = [c for block in blocks for c in block if c not in frame.columns]
    if missing:
        raise LogError(f"dataset lacks columns {missing[:6]}{'...' if len(missing) > 6 else ''}"
                       f"{_layout_hint(frame, source, n)}")
    return np.hstack([frame[block].to_numpy(dtype=float) for block in blocks])


def imu_layout(frame: pd.DataFrame, source: str = "est", n: int | None = None):
    """``X = [q, q̇, q̈, imu_acc, imu_gyro, imu_alpha]`` (N × (3n + 9)) from a dataset, for
    :class:`~ftdrake.compensation.estimators.imu_physics.ImuPayloadCompensator`; `source` as
    in :func:`joint_state_layout`."""
    missing = [c for c in col.IMU_INPUTS if c not in frame.columns]
    if missing:
        more = "..." if len(missing) > 3 else ""
        raise LogError(f"dataset lacks the IMU columns {missing[:3]}{more}: simulate "
                       "with scenario.imu.enabled: true (or log an IMU at the sensor "
                       "under these names, ftdrake.conventions.IMU_INPUTS)")
    return np.hstack([joint_state_layout(frame, source, n),
                      frame[list(col.IMU_INPUTS)].to_numpy(dtype=float)])


def _layout_hint(frame: pd.DataFrame, source: str, n: int) -> str:
    """What fixes a missing [q, q̇, q̈] block: the other `source`, or a recorder."""
    other = "plant" if source == "est" else "est"
    qd, qdd = (col.QD, col.QDD) if other == "plant" else (col.QD_EST, col.QDD_EST)
    blocks = [col.joint_columns(p, n) for p in (col.Q, qd, qdd)]
    if all(c in frame.columns for block in blocks for c in block):
        return (f"; this log has the {'plant' if other == 'plant' else 'estimated'} joint "
                f"state instead: pass source={other!r}")
    return ("; a log in this layout comes from ftdrake.add_recorder (q, qd, and the loop's "
            "own q̈ estimate qd_est/qdd_est), collect or simulate; a robot log with other "
            "columns is read with ftdrake.data.load_training_data")


def wrench_targets(frame: pd.DataFrame, prefix: str = col.MEASURED) -> np.ndarray:
    """The (N, 6) wrench columns with `prefix` (default: the measured reading)."""
    names = col.wrench_columns(prefix)
    missing = [c for c in names if c not in frame.columns]
    if missing:
        raise ValueError(f"dataset lacks columns {missing}")
    return frame[names].to_numpy(dtype=float)
