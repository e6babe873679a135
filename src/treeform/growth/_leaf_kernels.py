"""Compiled tree sweeps of the leaf placement (numba).

Imported lazily by :mod:`treeform.growth.leaves` (importing numba costs a few tenths of a
second). The skeleton's parents come first (``parent[i] < i``), so one reverse index sweep
visits every child before its parent: subtree sums need no recursion and no depth buckets.
"""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, nogil=True)
def subtree_tip_counts(parent: np.ndarray) -> np.ndarray:
    """(N,) int64: how many tips (nodes without children) each node's subtree holds (a tip: 1)."""
    n = len(parent)
    has_child = np.zeros(n, np.bool_)
    for i in range(1, n):
        has_child[parent[i]] = True
    tips = np.zeros(n, np.int64)
    for i in range(n):
        if not has_child[i]:
            tips[i] = 1
    for i in range(n - 1, 0, -1):
        tips[parent[i]] += tips[i]
    return tips


@nb.njit(cache=True, nogil=True)
def _scan_cell(c, qx, qy, qz, start, members, sorted_pts, best, bi):
    """The nearest of ``best`` (squared distance, index ``bi``) and the points of cell ``c``."""
    for j in range(start[c], start[c + 1]):
        dx = qx - sorted_pts[j, 0]
        dy = qy - sorted_pts[j, 1]
        dz = qz - sorted_pts[j, 2]
        d = dx * dx + dy * dy + dz * dz
        if d < best or (d == best and members[j] < bi):
            best = d
            bi = members[j]
    return best, bi


@nb.njit(cache=True, nogil=True)
def _box_d2(x, y, z, gx, gy, gz, h):
    """Squared distance (metres) from the query at grid coordinates (gx, gy, gz) to cell (x, y, z)."""
    bx = max(x - gx, 0.0, gx - x - 1.0)
    by = max(y - gy, 0.0, gy - y - 1.0)
    bz = max(z - gz, 0.0, gz - z - 1.0)
    return (bx * bx + by * by + bz * bz) * (h * h)


@nb.njit(cache=True, nogil=True)
def nearest_points(points: np.ndarray, queries: np.ndarray) -> np.ndarray:
    """(Q,) int64: index of the nearest of ``points`` (K, 3) to each of ``queries`` (Q, 3); K >= 1.

    Exact Euclidean nearest neighbours on a uniform grid of about one point per cell. Each
    query starts from the nearest point in its own cell and the previous query's answer
    (consecutive queries are often neighbours), then scans the cells that the ball of that
    radius touches; far from every point (or without a first candidate) it searches rings of
    cells outwards instead, until no unseen cell can hold a nearer point. Squared distances
    are summed as ``(dx² + dy²) + dz²`` like SciPy's ``cKDTree``, so the two agree wherever the
    nearest point is unique; exact ties go to the lowest index.
    """
    k = points.shape[0]
    lo = np.empty(3)
    ext = np.empty(3)
    for a in range(3):
        lo[a] = points[:, a].min()
        ext[a] = points[:, a].max() - lo[a]
    big = max(ext[0], ext[1], ext[2])
    floor_ext = max(big * 1e-3, 1e-9)
    vol = max(ext[0], floor_ext) * max(ext[1], floor_ext) * max(ext[2], floor_ext)
    h = max((vol / k) ** (1.0 / 3.0), big / 256.0, 1e-9)
    nx, ny, nz = int(ext[0] / h) + 1, int(ext[1] / h) + 1, int(ext[2] / h) + 1
    # the points sorted by cell (counting sort), so a cell's points lie side by side
    cell = np.empty(k, np.int64)
    for i in range(k):
        x = min(int((points[i, 0] - lo[0]) / h), nx - 1)
        y = min(int((points[i, 1] - lo[1]) / h), ny - 1)
        z = min(int((points[i, 2] - lo[2]) / h), nz - 1)
        cell[i] = (x * ny + y) * nz + z
    n_cells = nx * ny * nz
    start = np.zeros(n_cells + 1, np.int64)
    for i in range(k):
        start[cell[i] + 1] += 1
    for c in range(n_cells):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    members = np.empty(k, np.int64)
    sorted_pts = np.empty((k, 3))
    for i in range(k):
        j = fill[cell[i]]
        members[j] = i
        sorted_pts[j, 0] = points[i, 0]
        sorted_pts[j, 1] = points[i, 1]
        sorted_pts[j, 2] = points[i, 2]
        fill[cell[i]] += 1

    out = np.empty(queries.shape[0], np.int64)
    for q in range(queries.shape[0]):
        qx, qy, qz = queries[q, 0], queries[q, 1], queries[q, 2]
        gx = min(max((qx - lo[0]) / h, -1e15), 1e15)  # the query in grid units
        gy = min(max((qy - lo[1]) / h, -1e15), 1e15)
        gz = min(max((qz - lo[2]) / h, -1e15), 1e15)
        cx, cy, cz = int(np.floor(gx)), int(np.floor(gy)), int(np.floor(gz))
        best = np.inf  # squared distance, metres
        bi = -1
        if q > 0:
            bi = out[q - 1]
            dx = qx - points[bi, 0]
            dy = qy - points[bi, 1]
            dz = qz - points[bi, 2]
            best = dx * dx + dy * dy + dz * dz
        inside = 0 <= cx < nx and 0 <= cy < ny and 0 <= cz < nz
        if inside:
            best, bi = _scan_cell((cx * ny + cy) * nz + cz, qx, qy, qz, start, members, sorted_pts, best, bi)
        # the cells the ball of radius sqrt(best) touches (it only shrinks while they are scanned)
        rad = np.sqrt(best) / h * (1.0 + 1e-9)
        x0, x1 = max(int(np.floor(gx - rad)), 0), min(int(np.floor(gx + rad)), nx - 1)
        y0, y1 = max(int(np.floor(gy - rad)), 0), min(int(np.floor(gy + rad)), ny - 1)
        z0, z1 = max(int(np.floor(gz - rad)), 0), min(int(np.floor(gz + rad)), nz - 1)
        if bi >= 0 and (x1 - x0 + 1) * (y1 - y0 + 1) * (z1 - z0 + 1) <= 64:
            for x in range(x0, x1 + 1):
                for y in range(y0, y1 + 1):
                    for z in range(z0, z1 + 1):
                        c = (x * ny + y) * nz + z
                        if start[c] == start[c + 1] or (inside and x == cx and y == cy and z == cz):
                            continue
                        if _box_d2(x, y, z, gx, gy, gz, h) <= best * (1.0 + 1e-9):
                            best, bi = _scan_cell(c, qx, qy, qz, start, members, sorted_pts, best, bi)
            out[q] = bi
            continue
        # rings of cells at Chebyshev distance r from the query's cell, outwards
        r = max(0, -cx, cx - (nx - 1), -cy, cy - (ny - 1), -cz, cz - (nz - 1))  # nearer rings miss the grid
        r_max = max(cx, nx - 1 - cx, cy, ny - 1 - cy, cz, nz - 1 - cz)  # this ring holds the whole grid
        margin = max(min(gx - cx, cx + 1 - gx, gy - cy, cy + 1 - gy, gz - cz, cz + 1 - gz), 0.0)
        while r <= r_max:
            if bi >= 0 and r >= 1 and best < ((r - 1 + margin) * h) ** 2:
                break  # ring r and beyond lie at least (r - 1 + margin)·h away
            x0, x1 = max(cx - r, 0), min(cx + r, nx - 1)
            y0, y1 = max(cy - r, 0), min(cy + r, ny - 1)
            for x in range(x0, x1 + 1):
                edge_x = abs(x - cx) == r
                for y in range(y0, y1 + 1):
                    if edge_x or abs(y - cy) == r:
                        z0, z1, zstep = max(cz - r, 0), min(cz + r, nz - 1), 1
                    else:  # inside the ring in x and y: only its two z faces
                        z0, z1, zstep = cz - r, cz + r, max(2 * r, 1)
                    for z in range(z0, z1 + 1, zstep):
                        if z < 0 or z >= nz:
                            continue
                        c = (x * ny + y) * nz + z
                        if start[c] == start[c + 1]:
                            continue
                        if _box_d2(x, y, z, gx, gy, gz, h) <= best * (1.0 + 1e-9):
                            best, bi = _scan_cell(c, qx, qy, qz, start, members, sorted_pts, best, bi)
            r += 1
        out[q] = bi
    return out


@nb.njit(cache=True, nogil=True)
def _unit3(x, y, z):
    """(x, y, z) / max(|(x, y, z)|, 1e-12), summed as NumPy's ``norm(axis=-1)`` sums a row."""
    d = max(np.sqrt(x * x + y * y + z * z), 1e-12)
    return x / d, y / d, z / d


@nb.njit(cache=True, nogil=True)
def orient_cards(positions: np.ndarray, center: np.ndarray, scatter: float, g_normal: np.ndarray,
                 g_up: np.ndarray):
    """Card normals and up vectors of :func:`treeform.growth.leaves.attach_leaves`, in one pass.

    ``normal = unit(unit(p - center) + scatter · unit(g_normal))`` and
    ``up = unit(normal × unit(g_up))`` with ``unit(v) = v / max(|v|, 1e-12)``, operation for
    operation as the NumPy expressions compute them (the same bits).

    Returns
    -------
    normal, up : ndarray, shape (M, 3)
    """
    m = positions.shape[0]
    normal = np.empty((m, 3))
    up = np.empty((m, 3))
    for i in range(m):
        ox, oy, oz = _unit3(positions[i, 0] - center[0], positions[i, 1] - center[1], positions[i, 2] - center[2])
        rx, ry, rz = _unit3(g_normal[i, 0], g_normal[i, 1], g_normal[i, 2])
        nx, ny, nz = _unit3(ox + scatter * rx, oy + scatter * ry, oz + scatter * rz)
        bx, by, bz = _unit3(g_up[i, 0], g_up[i, 1], g_up[i, 2])
        ux, uy, uz = _unit3(ny * bz - nz * by, nz * bx - nx * bz, nx * by - ny * bx)
        normal[i, 0], normal[i, 1], normal[i, 2] = nx, ny, nz
        up[i, 0], up[i, 1], up[i, 2] = ux, uy, uz
    return normal, up


@nb.njit(cache=True, nogil=True)
def shaded_colors(base: np.ndarray, hue: np.ndarray, bright: np.ndarray, positions: np.ndarray,
                  center: np.ndarray, radius: float) -> np.ndarray:
    """(M, 3) float32 leaf colours of :func:`treeform.growth.leaves._species_colors`, in one pass.

    ``clip((base + hue) · bright · shade, 0, 1)`` with ``shade = 0.72 + 0.28 · clip(|p - center| / radius, 0, 1)``;
    ``base`` (3,), ``hue`` (M, 3) and ``bright`` (M, 1) are float32, the shade is computed in float64
    and rounded to float32, as the NumPy expressions do (the same bits).
    """
    m = positions.shape[0]
    out = np.empty((m, 3), np.float32)
    for i in range(m):
        dx = positions[i, 0] - center[0]
        dy = positions[i, 1] - center[1]
        dz = positions[i, 2] - center[2]
        depth = np.sqrt(dx * dx + dy * dy + dz * dz) / radius
        shade = np.float32(0.72 + 0.28 * min(max(depth, 0.0), 1.0))
        for a in range(3):
            v = (base[a] + hue[i, a]) * bright[i, 0] * shade
            out[i, a] = min(max(v, np.float32(0.0)), np.float32(1.0))
    return out


@nb.njit(cache=True, nogil=True)
def internode_points(positions: np.ndarray, parent: np.ndarray, node: np.ndarray, t: np.ndarray,
                     noise: np.ndarray, min_y: float) -> np.ndarray:
    """(M, 3) points ``a + t·(b - a) + noise`` on the internodes ``parent[node] -> node``, ``y >= min_y``.

    :func:`treeform.growth.leaves.leaf_positions` in one pass, operation for operation (the same bits).
    """
    m = node.shape[0]
    out = np.empty((m, 3))
    for i in range(m):
        b = node[i]
        a = parent[b]
        for c in range(3):
            pa = positions[a, c]
            out[i, c] = pa + t[i, 0] * (positions[b, c] - pa) + noise[i, c]
        out[i, 1] = max(out[i, 1], min_y)
    return out
