"""Discrete Curve Evolution and polygon helpers (seed 004 §3.3, after Latecki & Lakämper).

DCE simplifies a closed polygon by deleting, one at a time, the vertex of smallest relevance
``K = beta * l1 * l2 / (l1 + l2)`` (``beta`` the turn angle at the vertex, ``l1``, ``l2`` the
lengths of its two edges), recomputing the relevance of the two neighbours after each
deletion. Seed 004 keeps ``N = 2 n`` vertices and uses its inward (concave) vertices to place
the starting points of the cuts.
"""

from __future__ import annotations

import heapq
import math

import cv2
import numpy as np

from treeform._shared.checks import check_array, check_int
from treeform._shared.errors import InputError

__all__ = ["dce", "outer_contour", "inward_vertices", "resample_closed", "signed_area"]


def dce(polygon, n_vertices) -> np.ndarray:
    """Discrete Curve Evolution of a closed polygon (seed 004 §3.3, Fig. 5).

    Parameters
    ----------
    polygon : array_like, shape (K, 2)
        Vertices of a closed polygon (the last vertex connects to the first), e.g. a contour
        as ``(x, y)`` pixels.
    n_vertices : int
        How many vertices to keep (>= 3). If ``n_vertices >= K`` every vertex is kept.

    Returns
    -------
    ndarray, shape (min(n_vertices, K),), int64
        Indices of the kept vertices, sorted (i.e. in polygon order).

    Raises
    ------
    InputError
        ``polygon`` is not a (K, 2) finite array with K >= 3, or ``n_vertices`` is not an
        integer >= 3.

    Notes
    -----
    Relevance ``K(v) = beta(v) l1 l2 / (l1 + l2)`` with ``beta`` the turn angle in [0, pi].
    Latecki & Lakämper normalise ``l1, l2`` by the perimeter; a common factor does not change
    which vertex is smallest, so raw lengths are used. Ties are broken by the lower index, so
    the result is deterministic. O(K log K) with a heap.

    Examples
    --------
    >>> sq = [(0, 0), (5, 0), (10, 0), (10, 10), (5, 10.2), (0, 10)]
    >>> dce(sq, 4).tolist()
    [0, 2, 3, 5]
    """
    poly = check_array(polygon, "polygon", ndim=2, dtype_kind="biuf", shape=(None, 2)).astype(np.float64)
    k = len(poly)
    if k < 3:
        raise InputError(f"polygon: expected at least 3 vertices, got {k}")
    n = check_int(n_vertices, "n_vertices", 3, 1 << 40)
    if n >= k:
        return np.arange(k, dtype=np.int64)
    xs, ys = poly[:, 0].tolist(), poly[:, 1].tolist()
    prev = list(range(-1, k - 1))
    prev[0] = k - 1
    nxt = list(range(1, k + 1))
    nxt[-1] = 0
    alive = [True] * k

    # initial relevances, vectorised
    a, c = np.roll(poly, 1, axis=0), np.roll(poly, -1, axis=0)
    v1, v2 = poly - a, c - poly
    l1, l2 = np.hypot(v1[:, 0], v1[:, 1]), np.hypot(v2[:, 0], v2[:, 1])
    beta = np.abs(np.arctan2(v1[:, 0] * v2[:, 1] - v1[:, 1] * v2[:, 0], (v1 * v2).sum(1)))
    denom = l1 + l2
    rel = np.where(denom > 0, beta * l1 * l2 / np.where(denom > 0, denom, 1.0), 0.0).tolist()
    heap = [(r, i) for i, r in enumerate(rel)]
    heapq.heapify(heap)

    def relevance(i: int) -> float:
        p, q = prev[i], nxt[i]
        ax, ay = xs[i] - xs[p], ys[i] - ys[p]
        bx, by = xs[q] - xs[i], ys[q] - ys[i]
        la, lb = math.hypot(ax, ay), math.hypot(bx, by)
        if la + lb == 0.0:
            return 0.0
        return abs(math.atan2(ax * by - ay * bx, ax * bx + ay * by)) * la * lb / (la + lb)

    count = k
    while count > n:
        r, i = heapq.heappop(heap)
        if not alive[i] or r != rel[i]:
            continue  # stale entry
        p, q = prev[i], nxt[i]
        nxt[p], prev[q] = q, p
        alive[i] = False
        count -= 1
        for j in (p, q):
            rel[j] = relevance(j)
            heapq.heappush(heap, (rel[j], j))
    return np.flatnonzero(np.asarray(alive)).astype(np.int64)


def signed_area(poly: np.ndarray) -> float:
    """Shoelace area of a closed (K, 2) polygon (its sign gives the orientation)."""
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def inward_vertices(poly: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Concave ("inward") vertices of a closed polygon and their opening angles.

    Parameters
    ----------
    poly : ndarray, shape (N, 2)

    Returns
    -------
    idx : ndarray, shape (M,), int64
        Indices of the vertices where the boundary turns inward (interior angle > pi).
    alpha : ndarray, shape (M,), float64
        The angle between the two edges measured outside the shape, in (0, pi): small for
        a sharp notch (seed 004's ``alpha_l``, Fig. 5's blue angles).
    """
    a, c = np.roll(poly, 1, axis=0), np.roll(poly, -1, axis=0)
    v1, v2 = poly - a, c - poly
    cross = v1[:, 0] * v2[:, 1] - v1[:, 1] * v2[:, 0]
    turn = np.arctan2(cross, (v1 * v2).sum(1))  # signed turn angle
    orient = 1.0 if signed_area(poly) >= 0 else -1.0
    turn = turn * orient  # > 0: convex, < 0: concave
    idx = np.flatnonzero(turn < -1e-9)
    alpha = np.pi + turn[idx]  # outside angle = pi - |turn|
    return idx.astype(np.int64), alpha


def resample_closed(poly: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray, float]:
    """``count`` points uniformly spaced along a closed polygon.

    Returns
    -------
    points : ndarray, shape (count, 2)
    arc : ndarray, shape (count,)
        Arc-length position of each point from vertex 0.
    perimeter : float
    """
    closed = np.vstack([poly, poly[:1]])
    seg = np.hypot(*np.diff(closed, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    per = float(cum[-1])
    arc = np.arange(count) * (per / count)
    x = np.interp(arc, cum, closed[:, 0])
    y = np.interp(arc, cum, closed[:, 1])
    return np.stack([x, y], axis=1), arc, per


def outer_contour(mask: np.ndarray, *, simple: bool = False) -> np.ndarray:
    """Outer contour of the largest 8-connected part of ``mask`` as a (K, 2) float ``(x, y)`` array.

    ``simple=True`` keeps only the end points of straight pixel runs (OpenCV's
    ``CHAIN_APPROX_SIMPLE``), a lossless start for :func:`dce`. Empty mask: shape (0, 2).
    """
    mode = cv2.CHAIN_APPROX_SIMPLE if simple else cv2.CHAIN_APPROX_NONE
    cs, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, mode)
    if not cs:
        return np.zeros((0, 2))
    c = max(cs, key=lambda z: (cv2.contourArea(z), len(z)))
    return c[:, 0, :].astype(np.float64)
