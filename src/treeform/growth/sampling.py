"""Blue-noise point sampling inside an arbitrary volume."""

from __future__ import annotations

from typing import Callable

import numpy as np

from treeform._shared.checks import check_array
from treeform._shared.errors import InputError
from treeform._shared.rng import as_rng


def blue_noise_points(contains: Callable[[np.ndarray], np.ndarray], bounds, n: int, *, seed=None,
                      oversample: float = 1.6, max_rounds: int = 6) -> np.ndarray:
    """About ``n`` well-spread points inside a volume (or a plane region) by stratified (jittered-grid) sampling.

    Candidates come from a jittered grid (one uniform point per cell, about
    ``oversample × n`` inside the volume); then sample elimination in the spirit of
    Yuksel (2015) removes, in batches, one point of each closest pair until exactly
    ``n`` remain, which pushes the nearest-neighbour distances up to a Poisson-disk-like
    distribution (blue noise) in a few vectorised k-d tree rounds.

    Parameters
    ----------
    contains : callable
        ``contains(points (N, D)) -> (N,) bool``.
    bounds : tuple of two array_like, shape (D,)
        Axis-aligned box (min, max) enclosing the volume; D = 3, or 2 for points in a plane.
    n : int
        Number of points wanted.
    seed : int or Generator, optional

    Returns
    -------
    ndarray, shape (n, D)
        Fewer than ``n`` only if the volume is too small to hold them.

    Examples
    --------
    >>> pts = blue_noise_points(lambda p: np.linalg.norm(p, axis=1) < 1, ([-1] * 3, [1] * 3), 500, seed=0)
    >>> pts.shape
    (500, 3)
    >>> blue_noise_points(lambda p: np.ones(len(p), bool), ([0, 0], [100, 50]), 200, seed=0).shape
    (200, 2)
    """
    lo = check_array(bounds[0], "bounds[0]", ndim=1).astype(np.float64)
    hi = check_array(bounds[1], "bounds[1]", shape=lo.shape).astype(np.float64)
    if lo.shape[0] not in (2, 3):
        raise InputError(f"bounds: expected 2 or 3 coordinates, got {lo.shape[0]}")
    if not np.all(hi > lo):
        raise InputError(f"bounds: expected min < max on every axis, got {lo} and {hi}")
    n = int(n)
    if n < 1:
        raise InputError(f"n: expected a positive count, got {n}")
    rng = as_rng(seed)
    ext = hi - lo
    fraction = 1.0
    dim = lo.shape[0]
    pts = np.zeros((0, dim))
    for _ in range(max_rounds):
        cells = oversample * n / max(fraction, 1e-3) * 1.1
        cell = (np.prod(ext) / cells) ** (1 / dim)
        dims = np.maximum(1, np.ceil(ext / cell).astype(int))
        if np.prod(dims) > 5e7:
            raise InputError(f"n: {n} points in a volume this thin would need too many cells")
        grid = np.stack(np.meshgrid(*(np.arange(d) for d in dims), indexing="ij"), -1).reshape(-1, dim)
        cand = lo + (grid + rng.random(grid.shape)) * (ext / dims)
        inside = np.asarray(contains(cand), bool)
        pts = cand[inside]
        fraction = max(inside.mean(), 1e-4)
        if len(pts) >= n:
            break
    return _eliminate(pts, n)


def _eliminate(pts: np.ndarray, n: int) -> np.ndarray:
    """Drop points of the closest pairs, a batch per round, until ``n`` remain (order kept)."""
    from scipy.spatial import cKDTree

    from treeform.growth._point_kernels import close_pair_drops

    keep = np.arange(len(pts))
    while len(keep) > n:
        excess = len(keep) - n
        d, j = cKDTree(pts[keep]).query(pts[keep], k=2, workers=-1)
        nn, partner = d[:, 1], j[:, 1]
        order = np.argsort(nn, kind="stable")
        # one point of each close pair goes; its partner is protected this round
        drop = close_pair_drops(order, partner.astype(np.int64), max(1, min(excess, len(keep) // 8)))
        keep = keep[~drop]
    return pts[keep]
