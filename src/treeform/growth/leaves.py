"""Leaf clusters on terminal twigs, and their colours from the photo (seed 001 §3.6)."""

from __future__ import annotations

import numpy as np

from treeform._shared.errors import InputError
from treeform._shared.rng import as_rng
from treeform.structures.foliage import Foliage
from treeform.structures.skeleton import TreeSkeleton


def attach_leaves(skeleton: TreeSkeleton, positions: np.ndarray, *, size: float, center, twig_tips: int = 8,
                  scatter: float = 0.9, nodes=None, seed=None) -> Foliage:
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
    scatter : float
        Weight of the random direction added to the outward one in each normal (0: every
        card faces straight out of the crown).
    nodes : array_like of int, shape (M,), optional
        Each cluster's twig when the caller already knows it (clusters grown on a twig):
        no nearest-twig search.

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
    from treeform.growth._leaf_kernels import nearest_points, orient_cards

    positions = np.ascontiguousarray(positions, np.float64).reshape(-1, 3)
    n = len(positions)
    if n == 0 or skeleton.n_nodes < 2:
        return Foliage.empty()
    if not size > 0:
        raise InputError(f"size: expected a positive card size, got {size}")
    if not np.all(np.isfinite(positions)):
        raise InputError("positions: must be finite")
    rng = as_rng(seed)
    if nodes is not None:
        anchor = np.asarray(nodes).reshape(-1)
        if anchor.shape != (n,) or anchor.dtype.kind not in "iu" or anchor.min() < 0 or \
                anchor.max() >= skeleton.n_nodes:
            raise InputError(f"nodes: expected {n} node indices in [0, {skeleton.n_nodes})")
    else:
        tips = subtree_tips(skeleton)
        twigs = np.flatnonzero((tips <= twig_tips) & (skeleton.order > 0))
        if len(twigs) == 0:
            twigs = np.arange(1, skeleton.n_nodes)
        anchor = twigs[nearest_points(skeleton.positions[twigs], positions)]  # cKDTree's answer, 2-3x faster
    center = np.asarray(center, np.float64).reshape(3)
    g_normal = rng.normal(size=(n, 3))
    # normal = unit(unit(p - center) + scatter · unit(g_normal)), up = unit(normal × unit(g_up)), compiled
    normal, up = orient_cards(positions, center, float(scatter), g_normal, rng.normal(size=(n, 3)))
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
    return foliage.with_colors(np.clip(color, 0, 1))


def subtree_tips(skeleton: TreeSkeleton) -> np.ndarray:
    """How many tips (nodes without children) each node's subtree holds; a tip counts itself.

    One compiled reverse sweep (children come after their parents), not a Python loop.

    Returns
    -------
    ndarray of int64, shape (N,)

    Examples
    --------
    >>> sk = TreeSkeleton(np.zeros((4, 3)), np.array([-1, 0, 1, 1]))
    >>> subtree_tips(sk).tolist()
    [2, 2, 1, 1]
    """
    from treeform.growth._leaf_kernels import subtree_tip_counts

    return subtree_tip_counts(skeleton.parent)


def twig_nodes(skeleton: TreeSkeleton, twig_tips: int = 4) -> np.ndarray:
    """Indices of the twig nodes: those carrying at most ``twig_tips`` tips in their subtree (never the root).

    Returns
    -------
    ndarray of int64, shape (K,)
    """
    twigs = np.flatnonzero(subtree_tips(skeleton) <= twig_tips)
    return twigs[twigs > 0]


def leaf_positions(skeleton: TreeSkeleton, n: int, *, size: float, twig_tips: int = 4, seed=None,
                   return_nodes: bool = False):
    """``n`` leaf-cluster centres scattered around the twigs (seed 003 Appendix: leaves on twigs).

    Each cluster picks a twig node (evenly: every twig gets ``n // twigs`` or one more), a
    random point on the internode leading to it, and a normal offset of σ = ``size / 3``.

    Parameters
    ----------
    skeleton : TreeSkeleton
    n : int
    size : float
        Leaf-cluster card size in metres.
    twig_tips : int
    seed : int or numpy.random.Generator
    return_nodes : bool
        Also return the twig node of each centre.

    Returns
    -------
    ndarray, shape (n, 3)
        (and, with ``return_nodes``, the twig nodes, shape (n,))
    """
    from treeform.growth._leaf_kernels import internode_points

    rng = as_rng(seed)
    twigs = twig_nodes(skeleton, twig_tips)
    if n <= 0 or len(twigs) == 0:
        return (np.zeros((0, 3)), np.zeros(0, np.int64)) if return_nodes else np.zeros((0, 3))
    reps = np.full(len(twigs), n // len(twigs))
    reps[rng.permutation(len(twigs))[: n % len(twigs)]] += 1
    node = np.repeat(twigs, reps)
    t = rng.uniform(0.0, 1.0, (len(node), 1))
    noise = rng.normal(0.0, size / 3.0, (len(node), 3))
    # a + t·(b - a) + noise on the internode a = parent(node) -> b = node, y >= size / 2, compiled
    pts = internode_points(skeleton.positions, skeleton.parent, node, t, noise, size / 2)
    return (pts, node) if return_nodes else pts


def _species_colors(foliage: Foliage, base_rgb, center: np.ndarray, radius: float, rng) -> np.ndarray:
    """Species green with per-leaf brightness / hue variation, darker deep inside the crown."""
    from treeform.growth._leaf_kernels import shaded_colors

    m = len(foliage)
    base = np.asarray(base_rgb, np.float32).reshape(3)
    bright = rng.uniform(0.82, 1.18, (m, 1)).astype(np.float32)
    hue = rng.normal(0.0, 0.035, (m, 3)).astype(np.float32)
    hue[:, 1] *= 0.5
    # clip((base + hue) · bright · shade, 0, 1), shade = 0.72 + 0.28 · clip(depth, 0, 1), compiled
    return shaded_colors(base, hue, bright, foliage.positions, np.asarray(center, np.float64).reshape(3),
                         max(radius, 1e-6))


def twig_foliage(skeleton: TreeSkeleton, *, leaf_color, size: float, leaves: int | None = None,
                 leaves_per_twig: float = 3.0, twig_tips: int = 4, seed=None) -> Foliage:
    """Leaf clusters of a grown tree on its twigs, in the species' colour (seed 003 Appendix).

    :func:`leaf_positions` scatters the clusters around the twigs, :func:`attach_leaves`
    hangs them, and each gets the species green with per-leaf brightness / hue variation,
    darker deep inside the crown.

    Parameters
    ----------
    skeleton : TreeSkeleton
    leaf_color : sequence of 3 floats in [0, 1]
        Mean leaf RGB.
    size : float
        Card edge length in metres.
    leaves : int, optional
        Number of clusters; None: ``leaves_per_twig`` per twig node.
    leaves_per_twig : float
    twig_tips : int
        A node carrying at most this many tips is a twig.
    seed : int or numpy.random.Generator

    Returns
    -------
    Foliage
        M clusters (M = 0 for a tree without twigs).
    """
    rng = as_rng(seed)
    n = leaves if leaves is not None else int(round(leaves_per_twig * len(twig_nodes(skeleton, twig_tips))))
    pts, node = leaf_positions(skeleton, n, size=size, twig_tips=twig_tips, seed=rng, return_nodes=True)
    if not len(pts):
        return Foliage.empty()
    lo, hi = pts.min(0), pts.max(0)
    center = 0.5 * (lo + hi)
    # each cluster hangs on the twig it was scattered around (no nearest-twig search)
    foliage = attach_leaves(skeleton, pts, size=size, center=center, twig_tips=twig_tips, nodes=node, seed=rng)
    radius = 0.5 * float(np.linalg.norm(hi - lo))
    return foliage.with_colors(_species_colors(foliage, leaf_color, center, radius, rng))
