"""Branches from the field: attracting points and Catmull-Rom fits (seed 004 §3.4).

In each area of the partition, each scan line holds one attracting point: the area's pixel of
smallest force magnitude on that line. Seed 004 scans image rows (vines grow upward); for the
oblique areas of trees (§3.5) the scan lines are perpendicular to the direction from the
branch's attachment point to the area's centroid (rows when that direction is vertical), and
only the core of each line competes (:data:`CORE_FRACTION`). The
branch is a uniform Catmull-Rom spline fitted to the attracting points by least squares, its
first point pinned at the attachment point. Working-size pixels ``(x, y)`` throughout.
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["catmull_rom_basis", "fit_catmull_rom", "area_branch", "attachment_on_axis", "CORE_FRACTION"]

CORE_FRACTION = 0.3
"""A scan line's attracting point is sought among its pixels at least this fraction of the
line's largest distance to the area's border away from it."""


def catmull_rom_basis(u: np.ndarray, n_ctrl: int) -> np.ndarray:
    """Matrix (m, n_ctrl) giving a uniform Catmull-Rom spline's points at parameters ``u`` in [0, 1].

    Control points ``P_0 .. P_{C-1}``; the curve runs from ``P_1`` (u = 0) to ``P_{C-2}``
    (u = 1) through the ``C - 3`` segments between them; ``P_0`` and ``P_{C-1}`` set the end
    tangents.

    Examples
    --------
    >>> B = catmull_rom_basis(np.array([0.0, 1.0]), 4)
    >>> B.round(6).tolist()
    [[0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]]
    """
    u = np.clip(np.asarray(u, float), 0.0, 1.0)
    nseg = n_ctrl - 3
    x = u * nseg
    g = np.minimum(x.astype(int), nseg - 1)
    t = x - g
    t2, t3 = t * t, t * t * t
    w = 0.5 * np.stack([-t3 + 2 * t2 - t, 3 * t3 - 5 * t2 + 2, -3 * t3 + 4 * t2 + t, t3 - t2], axis=1)
    B = np.zeros((len(u), n_ctrl))
    rows = np.arange(len(u))
    for j in range(4):
        B[rows, g + j] = w[:, j]
    return B


def fit_catmull_rom(points: np.ndarray, u: np.ndarray, start: np.ndarray, n_ctrl: int,
                    *, smooth: float = 0.15) -> np.ndarray:
    """Least-squares Catmull-Rom control points (n_ctrl, 2) with the curve's start pinned at ``start``.

    Minimises ``sum_j |S(u_j) - q_j|^2 + smooth^2 m sum_k |P_{k-1} - 2 P_k + P_{k+1}|^2`` (a
    small second-difference term that keeps the end controls defined with few points).
    """
    m = len(points)
    B = catmull_rom_basis(u, n_ctrl)
    lam = smooth * np.sqrt(max(m, 1))
    D = np.zeros((n_ctrl - 2, n_ctrl))
    for k in range(n_ctrl - 2):
        D[k, k:k + 3] = (lam, -2 * lam, lam)
    A = np.vstack([B, D])
    rhs = np.vstack([points, np.zeros((n_ctrl - 2, 2))])
    rhs = rhs - A[:, 1:2] * start[None, :]
    free = [j for j in range(n_ctrl) if j != 1]
    sol, *_ = np.linalg.lstsq(A[:, free], rhs, rcond=None)
    P = np.empty((n_ctrl, 2))
    P[1] = start
    P[free] = sol
    return P


def area_branch(area: np.ndarray, mag: np.ndarray, start: np.ndarray, direction: np.ndarray | None,
                n_samples: int, *, max_ctrl: int = 6) -> dict | None:
    """One branch fitted in one area (seed 004 §3.4).

    Parameters
    ----------
    area : ndarray, shape (h, w), bool
        The area's pixels.
    mag : ndarray, shape (h, w)
        Force magnitude.
    start : ndarray, shape (2,)
        Attachment point (the curve's first point).
    direction : ndarray, shape (2,) or None
        Unit growth direction; scan lines are perpendicular to it. None: from ``start`` to the
        area's centroid.
    n_samples : int
        Points of the returned polyline.
    max_ctrl : int
        Most Catmull-Rom control points (4 = one cubic segment); fewer with few attracting
        points (4 below 8 points, 5 below 16).

    Returns
    -------
    dict or None
        ``polyline`` (n_samples, 2), ``width`` (n_samples,) half-width of the area across the
        branch at each point, ``attract`` (m, 2) the attracting points, ``direction``; None when
        the area has no pixel ahead of ``start``.
    """
    ys, xs = np.nonzero(area)
    if len(xs) == 0:
        return None
    if direction is None:
        d = np.array([xs.mean(), ys.mean()]) - start
        nd = np.linalg.norm(d)
        direction = d / nd if nd > 1e-6 else np.array([0.0, -1.0])
    t = (xs - start[0]) * direction[0] + (ys - start[1]) * direction[1]
    ahead = t >= 0.0
    if ahead.sum() < 2:
        return None
    xs, ys, t = xs[ahead], ys[ahead], t[ahead]
    bins = np.floor(t).astype(np.int64)
    # only the core of each scan line competes: pixels at least CORE_FRACTION of the line's
    # deepest distance from the area's border (keeps small bumps of a ragged border, where the
    # field also vanishes, from catching the attracting point)
    dist = cv2.distanceTransform(area.astype(np.uint8), cv2.DIST_L2, 3)[ys, xs]
    dmax = np.zeros(int(bins.max()) + 1)
    np.maximum.at(dmax, bins, dist)
    core = dist >= np.maximum(1.5, CORE_FRACTION * dmax[bins])
    mm = np.where(core, mag[ys, xs], np.inf)
    order = np.lexsort((mm, bins))
    sb = bins[order]
    first = np.r_[True, sb[1:] != sb[:-1]]
    pick = order[first]
    pick = pick[np.isfinite(mm[pick])]  # scan lines with no interior pixel hold no attracting point
    q = np.stack([xs[pick], ys[pick]], axis=1).astype(np.float64)
    tq = t[pick]
    counts = np.bincount(bins).astype(np.float64)
    if len(counts) >= 3:
        counts = np.convolve(np.pad(counts, 1, mode="edge"), np.ones(3) / 3.0, mode="valid")
    tmax = float(t.max())
    if len(q) < 3 or tmax < 1.0:
        tip = q[-1] if len(q) else np.array([xs[np.argmax(t)], ys[np.argmax(t)]], float)
        poly = start[None, :] + np.linspace(0, 1, n_samples)[:, None] * (tip - start)[None, :]
    else:
        n_ctrl = min(max_ctrl, 4 if len(q) < 8 else (5 if len(q) < 16 else 6))
        u = tq / tq.max()
        P = fit_catmull_rom(q, u, start, n_ctrl)
        res = np.linalg.norm(catmull_rom_basis(u, n_ctrl) @ P - q, axis=1)
        good = res <= max(2.0, 3.0 * float(np.median(res)))
        if 4 <= good.sum() < len(q):
            P = fit_catmull_rom(q[good], u[good], start, n_ctrl)
        poly = catmull_rom_basis(np.linspace(0.0, 1.0, n_samples), n_ctrl) @ P
    ts = (poly - start) @ direction
    width = 0.5 * counts[np.clip(np.floor(ts).astype(int), 0, len(counts) - 1)]
    return {"polyline": poly, "width": width, "attract": q, "direction": direction}


def attachment_on_axis(areas: np.ndarray, axis: np.ndarray, n_labels: int, *, quantile: float = 0.35,
                       step: float = 0.5) -> list[float | None]:
    """Arc position on ``axis`` where each area attaches, or None if it does not touch it.

    The axis (the separator part of the trunk or parent branch) is sampled every ``step``
    pixels; an area touches a sample when one of its pixels is in the sample's 3 x 3
    neighbourhood. The attachment is the ``quantile`` of the touching arc positions (from the
    axis' base), a little below the middle of the contact since branches grow upward/outward.
    """
    from treeform.skeleton.cuts import point_at_arc, polyline_arc

    out: list[float | None] = [None] * n_labels
    if axis is None or len(axis) < 2:
        return out
    length = polyline_arc(axis)[-1]
    s = np.arange(0.0, length + 1e-9, step)
    pts, _ = point_at_arc(axis, s)
    h, w = areas.shape
    ij = np.round(pts).astype(int)
    labs = []
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            x = np.clip(ij[:, 0] + dx, 0, w - 1)
            y = np.clip(ij[:, 1] + dy, 0, h - 1)
            labs.append(areas[y, x])
    labs = np.stack(labs, axis=1)
    for p in range(n_labels):
        hit = (labs == p).any(1)
        if hit.any():
            out[p] = float(np.quantile(s[hit], quantile))
    return out
