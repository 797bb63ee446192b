"""Collecting simulated datasets and reading them back.

A dataset is one Parquet file: the log columns of :mod:`ftdrake.simulation` for several
free-motion trajectories stacked, plus ``trajectory`` (int id). The scenario config that made
it is stored as YAML in the file's metadata (key ``ftdrake.scenario``), with the column
units (``ftdrake.units``) and the ftdrake version.

Runs are independent, so they run in parallel: local processes by default (joblib), or on a
Dask cluster with ``dask_address``. Each worker builds its own diagram from the config's YAML;
no Drake object is ever pickled.
"""

from __future__ import annotations

import contextlib
import dataclasses as dc
import json
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
from joblib import Parallel, delayed, parallel_config
from tqdm.auto import tqdm

from . import columns as col
from .config import ConfigError, ScenarioConfig, dump_config, parse_config
from .io import atomic_path

FREE_KINDS = ("random", "fourier", "reference", "z_rich", "rehearsal")
REHEARSAL_HEIGHT_M = 0.03  # a rehearsal stops the contact scenario this far above the surface
META_SCENARIO = b"ftdrake.scenario"
META_UNITS = b"ftdrake.units"
META_VERSION = b"ftdrake.version"


def trajectory_config(base: ScenarioConfig, index: int, seed: int) -> ScenarioConfig:
    """The config of run `index`: its own trajectory and noise seeds, the same sensor."""
    config = dc.replace(
        base,
        trajectory=dc.replace(base.trajectory, seed=seed + index),
        sensor=dc.replace(base.sensor, seed=seed + index),
    )
    return config


def simulate_one(config_yaml: str, index: int) -> pd.DataFrame:
    """Builds the diagram from YAML (in this process), runs it, returns its log."""
    from .diagram import build_diagram
    from .simulation import run

    config = parse_config(config_yaml)
    log, _ = run(build_diagram(config), progress=False)
    log.insert(0, col.TRAJECTORY, np.int32(index))
    return log


def collect(base: ScenarioConfig, trajectories: int, *, seed: int = 0, kind: str | None = None,
            duration: float | None = None, n_jobs: int = -1, dask_address: str | None = None,
            progress: bool = True) -> pd.DataFrame:
    """Runs `trajectories` free-motion simulations and stacks their logs."""
    if trajectories < 1:
        raise ValueError(f"trajectories must be >= 1, got {trajectories}")
    base = dc.replace(base, trajectory=dc.replace(base.trajectory))
    if kind is not None:
        base.trajectory.kind = kind
    if duration is not None:
        base.trajectory.duration_s = duration
    if base.trajectory.kind == "rehearsal":
        base.trajectory.kind = "contact"
        base.trajectory.press_depth_m = -REHEARSAL_HEIGHT_M
    elif base.trajectory.kind not in FREE_KINDS:
        raise ConfigError(
            f"scenario.trajectory.kind: collect needs free motion {FREE_KINDS}, "
            f"got {base.trajectory.kind!r}"
        )
    base.validate()
    jobs = [dump_config(trajectory_config(base, i, seed)) for i in range(trajectories)]
    with dask_backend(dask_address):
        results = Parallel(n_jobs=n_jobs, return_as="generator")(
            delayed(simulate_one)(yaml_text, i) for i, yaml_text in enumerate(jobs)
        )
        logs = list(tqdm(results, total=len(jobs), desc="collecting", unit="traj",
                         disable=not progress))
    frame = pd.concat(logs, ignore_index=True)
    frame.attrs["scenario"] = dump_config(base)
    return frame


@contextlib.contextmanager
def dask_backend(dask_address: str | None):
    """joblib's Dask backend on a Client of `dask_address`; nothing when it is None."""
    if dask_address is None:
        yield
        return
    from dask.distributed import Client

    with Client(dask_address) as client, parallel_config(backend="dask"):
        del client
        yield


def save_dataset(frame: pd.DataFrame, path: str | Path, scenario_yaml: str | None = None) -> None:
    """Writes `frame` as Parquet with scenario and units metadata, atomically."""
    from . import __version__

    table = pa.Table.from_pandas(frame, preserve_index=False)
    metadata = dict(table.schema.metadata or {})
    metadata[META_SCENARIO] = (scenario_yaml or frame.attrs.get("scenario", "")).encode()
    metadata[META_UNITS] = json.dumps(column_units(frame.columns)).encode()
    metadata[META_VERSION] = __version__.encode()
    table = table.replace_schema_metadata(metadata)
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp)


def load_dataset(path: str | Path) -> tuple[pd.DataFrame, ScenarioConfig | None]:
    """Reads a dataset written by :func:`save_dataset`; returns (frame, scenario or None)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no dataset at {path}")
    try:
        table = pq.read_table(path)
    except (pa.ArrowInvalid, OSError) as e:
        raise ValueError(f"{path} is not a readable Parquet dataset: {e}") from None
    frame = table.to_pandas()
    meta = table.schema.metadata or {}
    scenario = None
    if meta.get(META_SCENARIO):
        scenario = parse_config(meta[META_SCENARIO].decode(), source=f"{path} metadata")
        frame.attrs["scenario"] = meta[META_SCENARIO].decode()
    return frame, scenario


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
        elif suffix in col.WRENCH_AXES:
            units[name] = "N" if suffix.startswith("F") else "N*m"
        else:
            units[name] = "1"
    return units


def joint_state_layout(frame: pd.DataFrame, source: str = "est", n: int | None = None):
    """``X = [q, q̇, q̈]`` from a dataset: `source` "est" (numerically differentiated, as a
    real robot has) or "plant" (the simulator's exact values)."""
    if source not in ("est", "plant"):
        raise ValueError(f"source must be 'est' or 'plant', got {source!r}")
    n = n or sum(1 for c in frame.columns if c.startswith("q_") and c[2:].isdigit())
    qd, qdd = (col.QD_EST, col.QDD_EST) if source == "est" else (col.QD, col.QDD)
    blocks = [col.joint_columns(p, n) for p in (col.Q, qd, qdd)]
    missing = [c for block in blocks for c in block if c not in frame.columns]
    if missing:
        raise ValueError(f"dataset lacks columns {missing[:6]}{'...' if len(missing) > 6 else ''}")
    return np.hstack([frame[block].to_numpy(dtype=float) for block in blocks])


def wrench_targets(frame: pd.DataFrame, prefix: str = col.MEASURED) -> np.ndarray:
    """The (N, 6) wrench columns with `prefix` (default: the measured reading)."""
    names = col.wrench_columns(prefix)
    missing = [c for c in names if c not in frame.columns]
    if missing:
        raise ValueError(f"dataset lacks columns {missing}")
    return frame[names].to_numpy(dtype=float)
