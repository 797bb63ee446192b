"""The IMU's nine columns for a model that takes them (``train --kind imu-physics``).

:class:`~ftdrake.data.training.TrainingData` holds ``[q, q̇, q̈]`` rows; an IMU model's rows
continue with ``imu_acc`` (m/s², proper acceleration of So in S), ``imu_gyro`` (rad/s, ω of S
in S) and ``imu_alpha`` (rad/s², α of S in S), the columns of
:data:`ftdrake.conventions.IMU_INPUTS`. They are taken from the same table, each training row
matched to the table's row of the same trajectory and time (the reader may drop or reorder
rows), never interpolated.
"""

from __future__ import annotations

import dataclasses as dc
from pathlib import Path

import numpy as np
import pandas as pd

from ..conventions import IMU_INPUTS, TIME, TRAJECTORY
from ..data.logs import read_frame
from ..data.training import TrainingData
from ..errors import LogError


def with_imu_columns(source, data: TrainingData, time_column: str | None = None,
                     group_column: str | None = None) -> TrainingData:
    """`data` with X = ``[q, q̇, q̈, imu_acc, imu_gyro, imu_alpha]`` (N × (3n + 9)), the IMU
    columns read from `source` (the table file or ``pandas.DataFrame`` `data` was read from).

    Raises LogError when `source` is not a table, lacks an IMU column, or a row's time has
    no row in it.
    """
    if isinstance(source, TrainingData):
        raise LogError("an IMU model is trained from the log's table (a file or DataFrame "
                       "with the imu_* columns), not from TrainingData already read")
    if data.has_temperature:
        raise LogError("an IMU model takes no temperature column; leave --temperature out")
    name = "DataFrame" if isinstance(source, pd.DataFrame) else Path(source).name
    frame = source if isinstance(source, pd.DataFrame) else _table(Path(source))
    missing = [c for c in IMU_INPUTS if c not in frame.columns]
    if missing:
        raise LogError(f"{name}: no IMU columns {missing[:3]}{'...' if len(missing) > 3 else ''}"
                       f": --kind imu-physics needs the nine columns {', '.join(IMU_INPUTS)} "
                       "(an IMU at the sensor: simulate with scenario.imu.enabled: true, or "
                       "log the IMU under these names); without an IMU use --kind physics")
    time = time_column or TIME
    group = group_column or (TRAJECTORY if TRAJECTORY in frame.columns else None)
    imu = np.full((len(data.X), len(IMU_INPUTS)), np.nan)
    ids = frame[group].to_numpy() if group else np.zeros(len(frame))
    one_group = len(np.unique(data.groups)) == 1 and (group is None or frame[group].nunique() == 1)
    for g in np.unique(data.groups):
        rows = data.groups == g
        table = frame if one_group else frame[ids == g]
        t = table[time].to_numpy(dtype=float)
        order = np.argsort(t, kind="stable")
        at = np.clip(np.searchsorted(t[order], data.t[rows]), 0, len(t) - 1)
        found = order[at]
        if not np.array_equal(t[found], data.t[rows]):
            raise LogError(f"{name}: the IMU columns could not be matched to every row by "
                           f"its time ({time}); the table's rows must each carry their IMU")
        imu[rows] = table[list(IMU_INPUTS)].to_numpy(dtype=float)[found]
    if not np.isfinite(imu).all():
        bad = int((~np.isfinite(imu).all(axis=1)).sum())
        raise LogError(f"{name}: {bad} rows have a missing or non-finite IMU value")
    return dc.replace(data, X=np.hstack([data.X, imu]))


def _table(path: Path) -> pd.DataFrame:
    if path.is_dir() or path.suffix.lower() == ".bag":
        raise LogError(f"{path}: an IMU model is trained from a CSV or Parquet table with "
                       "the imu_* columns (a bag's IMU topic is not read yet)")
    return read_frame(path)
