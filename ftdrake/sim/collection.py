"""Collecting simulated datasets: several free-motion runs, one table.

The table holds the log columns of :mod:`ftdrake.sim.simulate` for several runs stacked, plus
``trajectory`` (int id); :mod:`ftdrake.data.dataset` writes and reads it as Parquet.

Runs are independent, so they run in parallel: local processes by default (joblib), or on a
Dask cluster with ``dask_address``. Each worker builds its own diagram from the config's YAML;
no Drake object is ever pickled.
"""

from __future__ import annotations

import dataclasses as dc

import numpy as np
import pandas as pd
from joblib import Parallel, delayed
from tqdm.auto import tqdm

from .. import conventions as col
from ..config import ConfigError, ScenarioConfig, dump_config, parse_config
from ..config.task import FREE_KINDS
from ..parallel import dask_backend
from .simulate import simulate
from .station import build_station


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
    config = parse_config(config_yaml)
    log = simulate(build_station(config), progress=False).log
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
    if base.trajectory.kind not in FREE_KINDS:
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

