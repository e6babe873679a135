"""Compiled kernels of the crown step (numba, imported lazily)."""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, nogil=True)
def finish_tiles(sample, shape_alpha, detail_lum, pick, dark, detail):
    """See :func:`treeform.crown.photo_leaves._finish_tiles`."""
    n, t = sample.shape[0], sample.shape[1]
    out = np.empty((n, t, t, 4), np.uint8)
    rgb = np.empty((t, t, 3), np.float32)
    alpha = np.empty((t, t), np.float32)
    for i in range(n):
        k = pick[i]
        wsum = 0.0
        msum = np.zeros(3)
        psum = np.zeros(3)
        for y in range(t):
            for x in range(t):
                a = sample[i, y, x, 3] * shape_alpha[k, y, x]
                f = (np.float32(1.0) + detail * (detail_lum[k, y, x] - np.float32(1.0))) * dark[i]
                alpha[y, x] = a
                wsum += a
                for c in range(3):
                    v = sample[i, y, x, c] * f
                    rgb[y, x, c] = v
                    msum[c] += v * a
                    psum[c] += sample[i, y, x, c]
        if wsum > 1e-6:
            mean = msum / wsum
        else:
            mean = psum / (t * t)
        for y in range(t):
            for x in range(t):
                a = alpha[y, x]
                out[i, y, x, 3] = np.uint8(min(max(np.rint(a * 255.0), 0.0), 255.0))
                for c in range(3):
                    v = rgb[y, x, c] if a > 1e-3 else mean[c]
                    out[i, y, x, c] = np.uint8(min(max(np.rint(v * 255.0), 0.0), 255.0))
    return out
