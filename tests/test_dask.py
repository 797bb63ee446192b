"""Scale-out on a Dask cluster gives the same results as local processes.

A 2-worker LocalCluster on loopback runs (a) `collect` of two short simulations, each worker
building its own Drake diagram from the scenario YAML, and (b) `ftdrake train --dask`'s grid
search. Same seeds, same numbers: bit for bit.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from ftdrake import ScenarioConfig
from ftdrake.cli.main import main as train_cli
from ftdrake.compensation.files.persistence import load_model, read_manifest
from ftdrake.data.logs import read_table
from ftdrake.sim.collection import collect
from tests.helpers import UR3_DATA

UR3 = UR3_DATA

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def cluster():
    from dask.distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                      dashboard_address=None) as dut:
        yield dut


def test_cluster_listens_on_loopback_only(cluster):
    addresses = [cluster.scheduler_address]
    addresses += [w.address for w in cluster.workers.values()]
    assert len(addresses) == 3
    assert all(a.startswith("tcp://127.0.0.1:") for a in addresses), addresses


def test_collect_on_the_cluster_equals_local(cluster):
    options = {"kind": "fourier", "duration": 2.0, "seed": 3, "progress": False}
    local = collect(ScenarioConfig(), 2, n_jobs=2, **options)
    remote = collect(ScenarioConfig(), 2, dask_address=cluster.scheduler_address, **options)
    assert len(local) == 4000 and local["trajectory"].nunique() == 2
    pd.testing.assert_frame_equal(remote, local, check_exact=True)
    assert remote.attrs["scenario"] == local.attrs["scenario"]


def test_grid_search_on_the_cluster_equals_local(cluster, tmp_path):
    """`ftdrake train --dask`: same CV scores for every candidate, same fitted forest."""
    common = ["train", "--data", UR3 / "id1.csv", "--targets", "tau_*", "--velocities", "qd_*",
              "--t-end", "6.4", "--model", "rf", "--preset", "quick", "--quiet"]
    runs = {"local": [], "dask": ["--dask", cluster.scheduler_address]}
    for name, extra in runs.items():
        assert train_cli([str(a) for a in [*common, *extra, "--out", tmp_path / name]]) == 0
    local, dask = (read_manifest(tmp_path / name)["extra"] for name in runs)
    assert dask["dask"] == cluster.scheduler_address and local["dask"] is None
    assert local["tuning"]["n_candidates"] == 4
    assert dask["tuning"] == local["tuning"]  # every candidate's mean and std, exactly

    log = read_table(UR3 / "id2.csv", targets="tau_*", velocities="qd_*")
    predictions = [load_model(tmp_path / name).predict(log.X()) for name in runs]
    np.testing.assert_array_equal(predictions[0], predictions[1])
