"""SplitMix64, the random stream of the compiled kernels (numba; imported by them, lazily).

A one-element ``uint64`` state array: deterministic for a seed, independent of NumPy's and
numba's own generators, and free of global state (threads and Dask workers draw side by side).
"""

from __future__ import annotations

import numba as nb
import numpy as np

_GAMMA = np.uint64(0x9E3779B97F4A7C15)
_MIX1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX2 = np.uint64(0x94D049BB133111EB)
_S30, _S27, _S31 = np.uint64(30), np.uint64(27), np.uint64(31)


@nb.njit(cache=True, nogil=True)
def next_u64(state):
    """The next 64-bit number of the stream in ``state`` (advanced in place)."""
    s = state[0] + _GAMMA
    state[0] = s
    z = (s ^ (s >> _S30)) * _MIX1
    z = (z ^ (z >> _S27)) * _MIX2
    return z ^ (z >> _S31)
