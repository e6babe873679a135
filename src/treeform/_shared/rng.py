"""Random number generator helper: every stochastic function takes ``seed`` or ``rng``."""

from __future__ import annotations

import numpy as np

MAX_SEED = 2**32 - 1
"""The largest seed a command takes: what every library the seeds reach accepts (numpy, torch, OpenCV, COLMAP)."""


def check_seed(seed) -> int:
    """Return ``seed`` as an int after checking it is an integer in [0, :data:`MAX_SEED`].

    >>> check_seed(7)
    7
    """
    from treeform._shared.checks import check_int

    return check_int(seed, "seed", 0, MAX_SEED)


def as_rng(seed=None) -> np.random.Generator:
    """Return a ``numpy.random.Generator`` from an int seed, a Generator, or None (seed 0).

    ``None`` maps to seed 0, never to OS entropy: same input -> same output. A negative or
    non-integer seed raises :class:`~treeform._shared.errors.InputError` (one line for the CLI).

    Examples
    --------
    >>> float(as_rng(3).random()) == float(as_rng(3).random())
    True
    >>> as_rng(-5)
    Traceback (most recent call last):
    ...
    treeform._shared.errors.InputError: seed: expected a non-negative integer, got -5
    """
    if isinstance(seed, np.random.Generator):
        return seed
    if seed is None:
        return np.random.default_rng(0)
    try:
        ok = not isinstance(seed, bool) and float(seed) == int(seed) and int(seed) >= 0
    except (TypeError, ValueError, OverflowError):
        ok = False
    if not ok:
        from treeform._shared.errors import InputError

        raise InputError(f"seed: expected a non-negative integer, got {seed!r}")
    return np.random.default_rng(int(seed))
