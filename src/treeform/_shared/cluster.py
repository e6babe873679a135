"""The Dask client of the batch jobs (``dataset generate``, ``eval``): a LocalCluster or a scheduler."""

from __future__ import annotations

import logging

from treeform._shared.errors import InputError

__all__ = ["WORKER_ENV", "dask_client"]

WORKER_ENV = {"LP_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
"""Environment of LocalCluster workers: one rasterizer / BLAS thread each (the workers are the parallelism)."""


def dask_client(workers: int | None, scheduler: str | None):
    """A distributed Client (and the LocalCluster it owns, or None).

    Parameters
    ----------
    workers : int
        LocalCluster worker processes (one thread each); ignored with ``scheduler``.
    scheduler : str, optional
        Address of a running scheduler, e.g. ``tcp://HOST:8786``.
    """
    from distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            return Client(scheduler, timeout="10s"), None
        except (OSError, TimeoutError, ValueError) as exc:
            raise InputError(f"--scheduler {scheduler}: cannot connect ({type(exc).__name__}: {exc})") from None
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0",
                           silence_logs=logging.CRITICAL, env=dict(WORKER_ENV))  # failures: our own log line
    return Client(cluster), cluster
