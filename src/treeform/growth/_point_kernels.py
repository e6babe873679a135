"""Compiled point-set kernels (numba, imported lazily): the blue-noise sample elimination
and the space colonization's nearest-node search."""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, nogil=True)
def close_pair_drops(order: np.ndarray, partner: np.ndarray, budget: int) -> np.ndarray:
    """(N,) bool: the points one elimination round drops.

    Points are visited by ``order`` (closest pairs first); a point goes when neither it nor
    its nearest neighbour ``partner[i]`` was touched this round, and both are then protected.
    At most ``budget`` points go. See :func:`treeform.growth.sampling._eliminate`.
    """
    n = len(order)
    drop = np.zeros(n, np.bool_)
    taken = np.zeros(n, np.bool_)
    for k in range(n):
        if budget == 0:
            break
        i = order[k]
        j = partner[i]
        if taken[i] or taken[j]:
            continue
        drop[i] = True
        taken[i] = True
        taken[j] = True
        budget -= 1
    return drop


@nb.njit(cache=True, nogil=True)
def nearest_new_node(att, alive, pos, cand, radius, best_d, best_n):
    """Update each alive attractor's nearest node with the nodes ``cand`` (in place).

    For every attractor index in ``alive``, the nearest of the nodes ``pos[cand]`` closer
    than ``radius`` replaces ``best_d``/``best_n`` where it is closer than the one held. The
    nodes are bucketed in a grid of ``radius``-sized cells, so each attractor looks at the
    27 cells around it only; distances are those of a k-d tree query (the root of the sum of
    squares, taken over x, y, z in order; nodes at ``radius`` or farther ignored).
    """
    m = len(cand)
    if m == 0 or len(alive) == 0:
        return
    lo = np.empty(3)
    hi = np.empty(3)
    for a in range(3):
        lo[a] = np.inf
        hi[a] = -np.inf
    for k in range(m):
        for a in range(3):
            v = pos[cand[k], a]
            lo[a] = min(lo[a], v)
            hi[a] = max(hi[a], v)
    dims = np.empty(3, np.int64)
    for a in range(3):
        dims[a] = np.int64((hi[a] - lo[a]) / radius) + 1
    n_cells = dims[0] * dims[1] * dims[2]
    cell_of = np.empty(m, np.int64)
    start = np.zeros(n_cells + 1, np.int64)
    for k in range(m):
        c = 0
        for a in range(3):
            c = c * dims[a] + min(np.int64((pos[cand[k], a] - lo[a]) / radius), dims[a] - 1)
        cell_of[k] = c
        start[c + 1] += 1
    for c in range(n_cells):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    order = np.empty(m, np.int64)
    for k in range(m):  # counting sort: nodes of a cell in their order in cand
        order[fill[cell_of[k]]] = k
        fill[cell_of[k]] += 1
    r2 = radius * radius
    for i in range(len(alive)):
        t = alive[i]
        x, y, z = att[t, 0], att[t, 1], att[t, 2]
        cx = np.int64(np.floor((x - lo[0]) / radius))
        cy = np.int64(np.floor((y - lo[1]) / radius))
        cz = np.int64(np.floor((z - lo[2]) / radius))
        d2_best = np.inf
        k_best = -1
        for gx in range(max(cx - 1, 0), min(cx + 2, dims[0])):
            for gy in range(max(cy - 1, 0), min(cy + 2, dims[1])):
                for gz in range(max(cz - 1, 0), min(cz + 2, dims[2])):
                    c = (gx * dims[1] + gy) * dims[2] + gz
                    for s in range(start[c], start[c + 1]):
                        k = order[s]
                        j = cand[k]
                        dx = x - pos[j, 0]
                        dy = y - pos[j, 1]
                        dz = z - pos[j, 2]
                        d2 = dx * dx + dy * dy + dz * dz
                        if d2 < d2_best or (d2 == d2_best and k < k_best):
                            d2_best = d2
                            k_best = k
        if k_best >= 0 and d2_best < r2:
            d = np.sqrt(d2_best)
            if d < best_d[t]:
                best_d[t] = d
                best_n[t] = cand[k_best]
