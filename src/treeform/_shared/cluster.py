"""The Dask client of the batch jobs (``dataset generate``, ``eval``): a LocalCluster or a scheduler."""

from __future__ import annotations

import logging

from treeform._shared.errors import InputError

__all__ = ["WORKER_ENV", "MAX_WORKERS", "check_cluster", "dask_client"]

MAX_WORKERS = 1024
"""The most local worker processes a command starts."""

WORKER_ENV = {"LP_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
"""Environment of LocalCluster workers: one rasterizer / BLAS thread each (the workers are the parallelism)."""


def check_cluster(workers, scheduler, *, allow_zero: bool = True) -> None:
    """Fail early, with one line, on a worker count out of [0 or 1, :data:`MAX_WORKERS`], a
    scheduler that is not an address, or both given (the workers of a running scheduler are its own).

    Examples
    --------
    >>> check_cluster(2, None); check_cluster(None, "tcp://10.0.0.5:8786")
    >>> check_cluster(None, "nope")
    Traceback (most recent call last):
    ...
    treeform._shared.errors.InputError: scheduler: expected an address like tcp://HOST:PORT, got 'nope'
    """
    import re

    from treeform._shared.checks import check_int

    if workers is not None:
        check_int(workers, "workers", 0 if allow_zero else 1, MAX_WORKERS)
    if scheduler is not None and not re.fullmatch(r"(tcp|tls|ws|wss|ucx)://[^\s/]+/?", str(scheduler)):
        raise InputError(f"scheduler: expected an address like tcp://HOST:PORT, got {scheduler!r}")
    if workers is not None and scheduler is not None:
        raise InputError("give either --workers (a local cluster) or --scheduler (an existing one), not both")


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
