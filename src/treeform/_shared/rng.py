"""Random number generator helper: every stochastic function takes ``seed`` or ``rng``."""

from __future__ import annotations

import numpy as np


def as_rng(seed=None) -> np.random.Generator:
    """Return a ``numpy.random.Generator`` from an int seed, a Generator, or None (seed 0).

    ``None`` maps to seed 0, never to OS entropy: same input -> same output.
    """
    if isinstance(seed, np.random.Generator):
        return seed
    return np.random.default_rng(0 if seed is None else int(seed))
