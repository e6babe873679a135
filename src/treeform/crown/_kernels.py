"""Compiled kernels of the crown step (numba, imported lazily)."""

from __future__ import annotations

import numba as nb
import numpy as np

from treeform._shared.splitmix import next_u64


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


@nb.njit(cache=True, nogil=True)
def quilt(canvas, wsum, fixed, target, source, cand_y, cand_x, win_y, win_x, patch, n_try, tolerance, seed):
    """Patch-based texture synthesis into ``target`` pixels (in place), one window at a time.

    For each window (top-left ``win_y[k], win_x[k]``, in the order given) ``n_try`` source patches
    (top-left ``cand_y, cand_x``, drawn with a SplitMix64 stream from ``seed``) are compared with
    the window's known pixels (``fixed``, or already synthesized: ``wsum > 0``) by the sum of
    squared differences; one of those within ``(1 + tolerance)`` of the best is taken at random
    (Efros & Freeman 2001) and blended into the window's target pixels with a tent weight, so
    overlapping patches cross-fade instead of meeting at a seam.

    Windows lie inside the canvas. canvas : (H, W, 3) float32, the current colours; wsum : (H, W)
    float32, the weight each
    synthesized pixel has received (0: not yet); fixed, target : (H, W) bool; source :
    (h, w, 3) float32.
    """
    state = np.array([np.uint64(seed) * np.uint64(2654435761) + np.uint64(1)], np.uint64)
    n_cand = len(cand_y)
    tries = min(n_try, n_cand)
    pick = np.empty(tries, np.int64)
    err = np.empty(tries)
    tent = np.empty(patch)
    for i in range(patch):
        tent[i] = min(i, patch - 1 - i) + 1.0
    for k in range(len(win_y)):
        y0, x0 = win_y[k], win_x[k]
        for t in range(tries):
            pick[t] = np.int64(next_u64(state) % np.uint64(n_cand))
        best = np.inf
        for t in range(tries):
            sy, sx = cand_y[pick[t]], cand_x[pick[t]]
            e = 0.0
            for i in range(patch):
                y = y0 + i
                for j in range(patch):
                    x = x0 + j
                    if fixed[y, x] or wsum[y, x] > 0:
                        for c in range(3):
                            d = canvas[y, x, c] - source[sy + i, sx + j, c]
                            e += d * d
                if e > best * (1.0 + tolerance):
                    break
            err[t] = e
            if e < best:
                best = e
        n_ok = 0
        for t in range(tries):  # the candidates within the tolerance, one of them at random
            if err[t] <= best * (1.0 + tolerance):
                pick[n_ok] = pick[t]
                n_ok += 1
        chosen = pick[np.int64(next_u64(state) % np.uint64(max(n_ok, 1)))]
        sy, sx = cand_y[chosen], cand_x[chosen]
        for i in range(patch):
            for j in range(patch):
                y, x = y0 + i, x0 + j
                if not target[y, x] or fixed[y, x]:
                    continue
                w = tent[i] * tent[j]
                old = wsum[y, x]
                for c in range(3):
                    canvas[y, x, c] = (canvas[y, x, c] * old + source[sy + i, sx + j, c] * w) / (old + w)
                wsum[y, x] = old + w


@nb.njit(cache=True, nogil=True)
def frontmost_squares(u, v, depth, half, use, h, w):
    """(M,) bool: cards nearest in at least one pixel, each an axis-aligned square of half side
    ``half`` about (u, v) on an (h, w) image, drawn nearest first (cards with ``use`` False skipped)."""
    m = u.shape[0]
    taken = np.zeros((h, w), np.bool_)
    seen = np.zeros(m, np.bool_)
    order = np.argsort(depth)
    for k in range(m):
        i = order[k]
        if not use[i]:
            continue
        r = max(half[i], 0.5)
        u0 = max(0, int(np.floor(u[i] - r)))
        u1 = min(w, int(np.ceil(u[i] + r)))
        v0 = max(0, int(np.floor(v[i] - r)))
        v1 = min(h, int(np.ceil(v[i] + r)))
        for y in range(v0, v1):
            for x in range(u0, u1):
                if not taken[y, x]:
                    taken[y, x] = True
                    seen[i] = True
    return seen
