"""Compiled ASCII formatting of number rows for the text mesh formats (numba, imported lazily).

Python's ``%`` formatting of a 50k-triangle tree's OBJ takes about 0.1 s and holds the GIL;
these loops write the same lines straight into a byte buffer and release it, so an OBJ is
written beside other work (the preview renders) instead of in turns with it.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

_MAX_DIGITS = 20  # int64 has at most 19 digits


@nb.njit(cache=True, nogil=True)
def _put_uint(out, k, v):
    """Decimal digits of the non-negative integer ``v`` at ``out[k:]``; returns the new end."""
    n = 1
    t = v // 10
    while t > 0:
        t //= 10
        n += 1
    for i in range(n - 1, -1, -1):
        out[k + i] = 48 + v % 10
        v //= 10
    return k + n


@nb.njit(cache=True, nogil=True)
def _put_fixed(out, k, x, decimals, scale):
    """``x`` rounded to ``decimals`` places, trailing zeros (and a bare point) dropped, no ``-0``."""
    s = np.int64(math.floor(abs(x) * scale + 0.5))
    if s == 0:
        out[k] = 48
        return k + 1
    if x < 0:
        out[k] = 45  # '-'
        k += 1
    p = np.int64(scale)
    k = _put_uint(out, k, s // p)
    frac = s % p
    if frac == 0:
        return k
    out[k] = 46  # '.'
    k += 1
    width = decimals
    while frac % 10 == 0:  # drop trailing zeros
        frac //= 10
        width -= 1
    for i in range(width - 1, -1, -1):
        out[k + i] = 48 + frac % 10
        frac //= 10
    return k + width


@nb.njit(cache=True, nogil=True)
def float_rows(prefix, values, decimals):
    """``prefix v0 v1 ...\\n`` for every row of the (N, K) float64 ``values`` (|v| < 1e12), as uint8."""
    n, m = values.shape
    scale = 10.0 ** decimals
    out = np.empty(n * (len(prefix) + 1 + m * (15 + decimals)), np.uint8)
    k = 0
    for i in range(n):
        for c in range(len(prefix)):
            out[k + c] = prefix[c]
        k += len(prefix)
        for j in range(m):
            out[k] = 32
            k = _put_fixed(out, k + 1, values[i, j], decimals, scale)
        out[k] = 10
        k += 1
    return out[:k]


@nb.njit(cache=True, nogil=True)
def face_rows(indices):
    """``f a/a/a b/b/b c/c/c\\n`` for every row of the (N, 3) int64 one-based ``indices``, as uint8."""
    n = indices.shape[0]
    out = np.empty(n * (2 + 3 * (3 * _MAX_DIGITS + 3)), np.uint8)
    k = 0
    for i in range(n):
        out[k] = 102  # 'f'
        k += 1
        for j in range(3):
            v = indices[i, j]
            out[k] = 32
            k += 1
            for r in range(3):
                if r:
                    out[k] = 47  # '/'
                    k += 1
                k = _put_uint(out, k, v)
        out[k] = 10
        k += 1
    return out[:k]
