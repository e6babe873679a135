"""Leaf clusters on terminal twigs, and their colours from the photo (seed 001 §3.6)."""

from __future__ import annotations

import numpy as np

from treeform._shared.errors import InputError
from treeform._shared.rng import as_rng
from treeform.structures.foliage import Foliage
from treeform.structures.skeleton import TreeSkeleton


def _unit(v):
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def attach_leaves(skeleton: TreeSkeleton, positions: np.ndarray, *, size: float, center, twig_tips: int = 8,
                  seed=None) -> Foliage:
    """Hang leaf clusters at given positions on their nearest twigs (seed 001 §3.6).

    Twig nodes are those carrying at most ``twig_tips`` tips in their subtree (the
    terminal twigs). Normals face away from the crown centre with random scatter, so
    clusters on the crown surface face outward; the in-plane up vector is random.

    Parameters
    ----------
    skeleton : TreeSkeleton
    positions : ndarray, shape (M, 3)
        Leaf cluster centres (e.g. from :func:`treeform.crown.sample_crown_columns`).
    size : float
        Mean card edge length in metres (each card varies by ±20 %).
    center : array_like, shape (3,)
        Crown centre.

    Returns
    -------
    Foliage
        ``node`` holds each leaf's twig; colours are a neutral green (see :func:`color_leaves`).

    Examples
    --------
    >>> sk = TreeSkeleton(np.array([[0, 0, 0], [0, 1, 0], [0.3, 1.3, 0.]]), np.array([-1, 0, 1]),
    ...                   order=np.array([0, 0, 1]))
    >>> attach_leaves(sk, np.array([[0.3, 1.4, 0.1]]), size=0.1, center=[0, 1, 0]).node.tolist()
    [2]
    """
    from scipy.spatial import cKDTree

    positions = np.asarray(positions, np.float64).reshape(-1, 3)
    n = len(positions)
    if n == 0 or skeleton.n_nodes < 2:
        return Foliage.empty()
    if not size > 0:
        raise InputError(f"size: expected a positive card size, got {size}")
    rng = as_rng(seed)
    parent = skeleton.parent
    tips = np.zeros(skeleton.n_nodes)
    tips[skeleton.tips()] = 1
    for i in range(skeleton.n_nodes - 1, 0, -1):
        tips[parent[i]] += tips[i]
    twigs = np.flatnonzero((tips <= twig_tips) & (skeleton.order > 0))
    if len(twigs) == 0:
        twigs = np.arange(1, skeleton.n_nodes)
    _, j = cKDTree(skeleton.positions[twigs]).query(positions)
    anchor = twigs[j]
    center = np.asarray(center, np.float64)
    normal = _unit(_unit(positions - center) + 0.9 * _unit(rng.normal(size=(n, 3))))
    up = _unit(np.cross(normal, _unit(rng.normal(size=(n, 3)))))
    s = size * rng.uniform(0.8, 1.2, n)
    color = np.tile(np.float32([0.25, 0.45, 0.15]), (n, 1))
    return Foliage(positions, normal, up, s, color, anchor)


def color_leaves(foliage: Foliage, pixels: np.ndarray, visible: np.ndarray, image: np.ndarray,
                 foliage_mask: np.ndarray, *, shade: np.ndarray | None = None, seed=None) -> Foliage:
    """Colour leaves from the photo (seed 001 §3.6 / issue: front leaves take the photo's colour).

    Visible leaves take the mean colour of the foliage pixels in a 3×3 window at the
    pixel they project onto (sky seen through gaps does not tint them); hidden ones draw
    a colour from the photo's foliage pixels (its colour distribution), optionally
    darkened by ``shade``.

    Parameters
    ----------
    foliage : Foliage
    pixels : ndarray, shape (M, 2)
        (column, row) each leaf projects onto.
    visible : ndarray, shape (M,), bool
    image : ndarray, shape (H, W, 3), uint8
    foliage_mask : ndarray, shape (H, W), bool
    shade : ndarray, shape (M,), optional
        Multiplier in [0, 1] for hidden leaves (e.g. deeper = darker).
    """
    m = len(foliage)
    if m == 0:
        return foliage
    rng = as_rng(seed)
    h, w = image.shape[:2]
    img = image.astype(np.float32) / 255.0
    cu = np.clip(pixels[:, 0].astype(np.int64), 0, w - 1)
    cv = np.clip(pixels[:, 1].astype(np.int64), 0, h - 1)
    fm = np.asarray(foliage_mask, bool)
    acc = np.zeros((m, 3), np.float32)
    cnt = np.zeros(m, np.float32)
    for dv in (-1, 0, 1):
        for du in (-1, 0, 1):
            yy, xx = np.clip(cv + dv, 0, h - 1), np.clip(cu + du, 0, w - 1)
            wgt = fm[yy, xx].astype(np.float32)
            acc += img[yy, xx] * wgt[:, None]
            cnt += wgt
    pool = img[fm] if fm.any() else img.reshape(-1, 3)
    hidden = pool[rng.integers(0, len(pool), m)]
    front = np.where(cnt[:, None] > 0, acc / np.maximum(cnt, 1)[:, None], hidden)
    if shade is not None:
        hidden = hidden * np.clip(shade, 0, 1)[:, None]
    color = np.where(np.asarray(visible, bool)[:, None], front, hidden)
    return Foliage(foliage.positions, foliage.normals, foliage.up, foliage.size, np.clip(color, 0, 1), foliage.node)
