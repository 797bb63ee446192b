"""Where parallel work runs: local processes (joblib's default) or a Dask cluster.

Collection, grid searches and the study run their independent jobs through joblib; with a
scheduler address they go to that Dask cluster instead. Dask is an optional dependency: it is
imported only when an address is given.
"""

from __future__ import annotations

import contextlib

from joblib import parallel_config


@contextlib.contextmanager
def dask_backend(dask_address: str | None):
    """joblib's Dask backend on a Client of `dask_address`; nothing when it is None."""
    if dask_address is None:
        yield
        return
    from dask.distributed import Client  # noqa: PLC0415 (optional: only with a cluster address)

    with Client(dask_address) as client, parallel_config(backend="dask"):
        del client
        yield
