"""Learned segmentation: the compact DeepLab-V3+ of :mod:`treeform.learn` run by onnxruntime.

Trained on randomised synthetic scenes and real photo cut-outs (seed 003 §4.2.2; see
``docs/MODELS.md``). The network labels background / foliage / wood at a reduced size; its
probabilities are resampled to the photo, and only the main tree is kept
(:func:`treeform.learn.infer.main_tree`).
"""

from __future__ import annotations

import numpy as np

from treeform._shared.errors import InputError, NoTreeFoundError
from treeform.structures.segmentation import Segmentation

__all__ = ["segment_tree_learned", "tree_probability", "guided_filter", "stand_on_ground", "wood_at_full_size"]

MIN_TREE_FRACTION = 0.01
"""A main tree smaller than this share of the photo counts as no tree."""

HOLE_FRACTION = 0.02
"""Default of ``fill_holes``: enclosed holes below this share of the tree's area are filled."""

REFINE_SIDE = 1024
"""Long side, in pixels, at which the guided-filter edge refinement runs at most."""

SMALLEST_TREE_PX = 100
"""About the smallest tree, in pixels tall, the network finds: six real photos as JPEG thumbnails, tree IoU
against the full-size photo's mask 0.80-0.94 at 150 px, 0.59-0.89 at 100 px, 0.02-0.49 at 80 px (upsampled
4x to the network's 320, the crowns are a blur it never saw). A photo too small for it says so."""

REFINERS = ("matting", "guided", "none")
"""Edge refinements of :func:`segment_tree_learned`."""

MATTE_SIDE = 512
"""Long side, in pixels, at which the matting refinement runs (its alpha is upsampled)."""

LINK = 0.02
"""Pieces of the tree mask closer than this share of the long side are one part when the main
tree is chosen (:func:`~treeform.learn.infer.main_tree`): a crown seen through sky gaps falls
apart into pieces, all of them the tree."""


def guided_filter(guide: np.ndarray, src: np.ndarray, *, radius: int = 4, eps: float = 1e-3) -> np.ndarray:
    """Edge-aware smoothing of ``src`` that follows the edges of the colour ``guide`` (He et al. 2013).

    The colour guided filter: in every (2r+1)² window, ``src`` is modelled as an affine
    function of the guide's RGB; the averaged coefficients give an output whose edges are
    the photo's. Used to move an upsampled probability map's soft edge onto the photo's
    edges (crown outline, sky gaps).

    Parameters
    ----------
    guide : ndarray, shape (H, W, 3), uint8 or float in [0, 1]
    src : ndarray, shape (H, W), float
    radius : int
    eps : float
        Regularisation (larger = smoother, less edge-following).

    Returns
    -------
    ndarray, shape (H, W), float32

    Examples
    --------
    >>> g = np.zeros((20, 20, 3), np.float32); g[:, 10:] = 1.0
    >>> s = np.zeros((20, 20), np.float32); s[:, 8:] = 1.0   # an edge 2 px off the guide's
    >>> out = guided_filter(g, s, radius=3, eps=1e-4)
    >>> bool(out[10, 8] < 0.5 < out[10, 11])
    True
    """
    import cv2

    I = np.asarray(guide, np.float32)
    if I.dtype != np.float32 or I.max() > 1.0:
        I = I / 255.0
    p = np.asarray(src, np.float32)
    k = (2 * int(radius) + 1,) * 2

    def box(x):
        return cv2.blur(x, k, borderType=cv2.BORDER_REFLECT)

    mean_I = box(I)
    mean_p = box(p)
    cov_Ip = box(I * p[..., None]) - mean_I * mean_p[..., None]
    # 3x3 covariance of the guide per pixel (symmetric: six entries), regularised
    def cov(a, b):
        return box(I[..., a] * I[..., b]) - mean_I[..., a] * mean_I[..., b] + (eps if a == b else 0.0)

    rr, rg, rb, gg, gb, bb = cov(0, 0), cov(0, 1), cov(0, 2), cov(1, 1), cov(1, 2), cov(2, 2)
    # solve Sigma a = cov_Ip by the adjugate (closed form, vectorised over pixels)
    i00, i01, i02 = gg * bb - gb * gb, gb * rb - rg * bb, rg * gb - gg * rb
    i11, i12, i22 = rr * bb - rb * rb, rb * rg - rr * gb, rr * gg - rg * rg
    det = rr * i00 + rg * i01 + rb * i02
    c0, c1, c2 = cov_Ip[..., 0], cov_Ip[..., 1], cov_Ip[..., 2]
    coef = np.stack([i00 * c0 + i01 * c1 + i02 * c2, i01 * c0 + i11 * c1 + i12 * c2,
                     i02 * c0 + i12 * c1 + i22 * c2], -1) / det[..., None]
    bias = mean_p - (coef * mean_I).sum(-1)
    return (box(coef) * I).sum(-1) + box(bias)


def _matte_refine(img: np.ndarray, tree: np.ndarray, p_tree: np.ndarray,
                  sky: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The tree mask and alpha re-solved by closed-form matting in a band around the network's edge.

    Trimap: foreground where the network is sure (p >= 0.8) and at least ``band / 2`` inside
    its mask, unknown in a band of 1.5 % of the long side around the mask's edge (both sides),
    background elsewhere and on the ``sky`` pixels inside the mask (blue sky,
    :func:`~treeform.segment.matting.blue_sky`: the gaps between a bare tree's twigs, which
    the network at 320 px fills in). The matte draws the crown's outline and its sky gaps
    from the photo's colours, finer than the network's stride; the tree is alpha > 0.5.
    """
    import cv2

    from treeform.segment.matting import _disc as disc
    from treeform.segment.matting import alpha_matting

    H, W = tree.shape
    band = max(2, int(round(0.015 * max(H, W))))

    t8 = tree.astype(np.uint8)
    tri = np.zeros((H, W), np.float64)
    tri[cv2.dilate(t8, disc(band)) > 0] = 0.5
    sky = sky & tree
    fg = (cv2.erode(t8, disc(max(1, band // 2))) > 0) & (p_tree >= 0.8)
    fg &= cv2.dilate(sky.astype(np.uint8), disc(1)) == 0
    tri[fg] = 1.0
    # blue sky seen between branches and through the crown is background, however the network saw it
    tri[cv2.erode(sky.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))) > 0] = 0.0
    if not (tri == 1).any() or not (tri == 0).any():
        return tree, p_tree
    try:
        alpha = alpha_matting(img, tri, max_side=MATTE_SIDE)
    except ValueError:  # the solver's preconditioner failed (degenerate colours): keep the network's edge
        return tree, p_tree
    return alpha > 0.5, alpha


def stand_on_ground(tree: np.ndarray, ground: np.ndarray, *, margin: float = 0.01,
                    foot_share: float = 0.25, min_width: float = 0.2) -> np.ndarray:
    """A tree mask cut at the ground line, but for the foot of its trunk.

    A tree stands on the ground: what a mask holds more than ``margin`` x H below the
    photo's ground line (lawn, a road, a hedge's foot, the tree's shadow) is not the tree,
    except in the columns of its trunk. The trunk's columns are the narrow runs of the
    mask in a band of 5 % of H just above the ground line (each at most ``foot_share`` of the
    mask's widest row); a run wider than that is undergrowth taken in, not a trunk, and
    keeps nothing below the line. Only pieces that lie like ground go: at least
    ``min_width`` x W wide and wider than tall. A photo looking up into a crown has no
    ground, and a line placed in it would cut tall pieces of trunk, not flat bands.

    Parameters
    ----------
    tree : ndarray, shape (H, W), bool
    ground : ndarray, shape (W,), int
        First ground row of each column (``H`` = no ground; :func:`~treeform.segment.classical.ground_line`).
    margin, foot_share, min_width : float

    Returns
    -------
    ndarray, shape (H, W), bool

    Examples
    --------
    A crown, its trunk down to row 90 and a lawn taken in from row 80, where the ground begins:

    >>> m = np.zeros((100, 60), bool); m[10:50, 10:50] = True; m[50:90, 28:32] = True; m[80:90, :] = True
    >>> out = stand_on_ground(m, np.full(60, 80))
    >>> int(m[85].sum()), int(out[85].sum())  # the lawn goes, the trunk's foot (and a pixel beside) stays
    (60, 6)
    """
    tree = np.asarray(tree, bool)
    H, W = tree.shape
    g = np.asarray(ground, np.int64).reshape(-1)
    if g.shape != (W,):
        raise InputError(f"ground: expected {W} rows (one per column), got shape {g.shape}")
    rows = np.arange(H)[:, None]
    below = rows > g[None, :] + margin * H
    if not (tree & below).any():
        return tree
    widest = int(tree.sum(1).max())
    band = (tree & (rows >= g[None, :] - 0.06 * H) & (rows < g[None, :] - margin * H)).any(0)
    keep = np.zeros(W, bool)
    pad = max(1, int(round(margin * W)))
    edges = np.flatnonzero(np.diff(np.r_[0, band.astype(np.int8), 0]))
    for a, b in zip(edges[::2], edges[1::2]):  # runs [a, b) of the foot band
        if b - a <= foot_share * widest:
            keep[max(0, a - pad):b + pad] = True
    cut = tree & below & ~keep[None, :]
    # only what lies like ground: pieces at least min_width x W wide and wider than tall (a lawn,
    # a road, a hedge's foot); a narrow or tall piece is more likely the tree over a misplaced line
    import cv2

    n, lab, stats, _ = cv2.connectedComponentsWithStats(cut.astype(np.uint8), connectivity=8)
    flat = np.zeros(n, bool)
    flat[1:] = (stats[1:, 2] >= min_width * W) & (stats[1:, 2] >= stats[1:, 3])
    return tree & ~flat[lab]


def tree_probability(img: np.ndarray, seg_net, *, guided: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """The network's class probabilities (H, W, 3) and its tree probability (H, W) at the photo's size.

    With ``guided``, the tree probability's soft edge (the network sees about 320 px) is moved
    onto the photo's edges by :func:`guided_filter` when the photo is finer than that.
    ``seg_net`` is a :class:`~treeform.learn.infer.Segmenter`.
    """
    p = seg_net.probabilities(img)
    p_tree = 1.0 - p[..., 0]
    if guided:
        p_tree = snap_to_edges(img, p_tree, seg_net.side)
    return p, p_tree


def wood_at_full_size(img: np.ndarray, seg_net, *, overlap: float = 0.25) -> np.ndarray:
    """(H, W) probability that a pixel is wood, the network run on tiles of the photo at its own size.

    The network sees a whole photo at ``seg_net.side`` pixels (320): a branch 3 px wide in a
    1024-px photo is under a pixel there, and its wood is lost. Squares of ``side`` pixels cut
    from the photo at full size (``overlap`` of their side shared with the next one) let it see
    every branch at the photo's own resolution; each pixel keeps its highest wood probability
    over the squares that hold it (a pixel the tile calls background counts 0). Nothing here
    says which tree the wood belongs to: the caller decides (the multi-view route's carving
    keeps the wood the views agree on in 3D). ``seg_net`` is a
    :class:`~treeform.learn.infer.Segmenter`.
    """
    from treeform.segment.instances import _windows

    img = np.asarray(img)
    H, W = img.shape[:2]
    side = int(seg_net.side)
    stride = max(1.0, (1.0 - float(overlap)) * side)
    wood = np.zeros((H, W), np.float32)
    for y in _windows(H, side, stride):
        for x in _windows(W, side, stride):
            p = seg_net.probabilities(img[y:y + side, x:x + side])
            w = np.where(p[..., 0] < 0.5, p[..., 2], 0.0)
            np.maximum(wood[y:y + side, x:x + side], w, out=wood[y:y + side, x:x + side])
    return wood


def snap_to_edges(img: np.ndarray, p_tree: np.ndarray, side: int) -> np.ndarray:
    """A tree probability seen at ``side`` pixels, its soft edge moved onto the photo's edges
    (:func:`guided_filter`, run at most at :data:`REFINE_SIDE`); unchanged when the photo is not finer."""
    import cv2

    from treeform.learn.infer import network_scale

    H, W = img.shape[:2]
    f = min(1.0, network_scale((H, W), REFINE_SIDE))  # the filter runs at most at REFINE_SIDE (up to 2:1)
    guide = img if f == 1.0 else cv2.resize(img, (round(W * f), round(H * f)), interpolation=cv2.INTER_AREA)
    scale = f / network_scale((H, W), side)  # guide pixels per pixel of the network's view
    if scale <= 1.2:  # only when the photo is finer than the network's view
        return p_tree
    src = p_tree if f == 1.0 else cv2.resize(p_tree, guide.shape[1::-1], interpolation=cv2.INTER_AREA)
    ref = np.clip(guided_filter(guide, src, radius=max(2, int(round(2 * scale))), eps=2e-3), 0.0, 1.0)
    return ref if f == 1.0 else cv2.resize(ref, (W, H), interpolation=cv2.INTER_LINEAR)


def segment_tree_learned(image: np.ndarray, *, weights=None, refine: str = "matting",
                         fill_holes: float = HOLE_FRACTION, ground: bool = True, trunk: bool = True,
                         side: int | None = None, gaps: bool = True) -> Segmentation:
    """Segment the main tree of a photo with the learned network.

    Parameters
    ----------
    image : ndarray, shape (H, W, 3), uint8
        RGB photo.
    weights : path, optional
        ONNX weights (default: the shipped ``seg.onnx``).
    refine : {'matting', 'guided', 'none'}
        How the tree's edge (seen by the network at about 320 px: soft and coarse) is
        redrawn at the photo's resolution: closed-form alpha matting in a band around it
        (outline and sky gaps from the photo's colours; about 0.15 s at 512 px), or the
        faster :func:`guided_filter` of the tree probability, or not at all.
    fill_holes : float
        Holes inside the tree smaller than this share of the tree's area become foliage
        (0 keeps every hole); with ``refine='matting'``, holes of blue sky stay holes.
    ground : bool
        Cut the tree at the photo's ground line but for its trunk's foot
        (:func:`stand_on_ground`, :func:`~treeform.segment.classical.ground_line`): lawn,
        road and undergrowth the network takes in go.
    trunk : bool
        Label the trunk standing in the tree's foot wood, and (with ``ground``) add the
        trunk below the crown where the network left it out
        (:func:`~treeform.segment.classical.trunk_in_mask`: upright bark from the foot, by
        shape and colour). The network draws thin wood but often calls a wide or shaded
        trunk foliage; an autumn crown stays foliage either way.
    side : int, optional
        Long side, in pixels, at which the network sees the photo (default: the weights'
        own, 320); the sharpness map and the edge snapping work at it too.
    gaps : bool
        With ``refine='matting'``, also open the gaps of the crown the network filled in:
        pixels coloured like what surrounds the tree and rare in it
        (:func:`~treeform.segment.matting.background_gaps`: overcast sky, a wall, a blurred
        hedge seen through the crown) become background in the matting's trimap, as blue sky
        always does. False leaves them to the caller (the multi-view route has its own gap
        rule, tuned with its carving).

    Returns
    -------
    Segmentation
        ``labels`` 0 background / 1 foliage / 2 wood for the main tree only; ``alpha`` the
        network's tree probability (foliage + wood) inside the main tree.

    Raises
    ------
    InputError
        ``image`` is not an (H, W, 3) uint8 array of at least 8 x 8 pixels.
    NoTreeFoundError
        The network finds no tree covering at least 1 % of the photo.
    ModelError
        The weights file is missing or unreadable.
    """
    from treeform.learn.infer import Segmenter, focus_map, main_tree

    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
        raise InputError(f"image: expected an (H, W, 3) uint8 RGB array, got shape {img.shape} {img.dtype}")
    if min(img.shape[:2]) < 8:
        raise InputError(f"image: expected at least 8 x 8 pixels, got {img.shape[1]} x {img.shape[0]}")
    if isinstance(refine, bool):  # the former switch: True was the guided filter
        refine = "guided" if refine else "none"
    from treeform._shared.checks import check_choice

    check_choice(refine, "refine", REFINERS)
    seg_net = Segmenter(weights, side=side)
    p, p_tree = tree_probability(img, seg_net, guided=refine in ("guided", "matting"))
    # the main tree: the largest part, weighted by sharpness (a blurred tree behind loses)
    focus = focus_map(img, seg_net.side)
    tree = main_tree(p_tree > 0.5, focus=focus, link=LINK)
    if ground:
        from treeform.segment.classical import ground_line

        g = ground_line(img)
        tree = main_tree(stand_on_ground(tree, g), focus=focus, link=LINK)
    if tree.mean() < MIN_TREE_FRACTION:
        H, W = img.shape[:2]
        small = (f" (it is {W} x {H} px: the network finds trees about {SMALLEST_TREE_PX} px tall or more; "
                 "give a larger photo)") if max(H, W) < 1.25 * SMALLEST_TREE_PX else ""
        raise NoTreeFoundError("no tree found in the photo" + small)
    if refine == "matting":
        from treeform.segment.matting import background_gaps, blue_sky

        sky = blue_sky(img)
        if gaps:  # the gaps the network filled: whatever colours surround the tree but are rare in it
            sky |= background_gaps(img, tree, wood=p[..., 2] > p[..., 1], ground=g if ground else None)
        matte, a = _matte_refine(img, tree, p_tree, sky)
        if ground:
            matte = stand_on_ground(matte, g)
        matte = main_tree(matte, focus=focus, link=LINK)
        if matte.mean() >= MIN_TREE_FRACTION:
            tree, p_tree = matte, np.asarray(a, np.float32)
    labels = np.where(tree, np.where(p[..., 2] > p[..., 1], 2, 1), 0).astype(np.uint8)
    if trunk:  # the trunk is wood, also where the network left it out below the crown
        from treeform.segment.classical import trunk_in_mask

        # (the focus test applies to a trunk found below the mask, which only the ground line allows)
        stem = trunk_in_mask(img, tree, ground=g if ground else None,
                             focus=focus_map(img, seg_net.side, relative=False) if ground else None)
        labels[stem] = 2
        p_tree = np.where(stem & ~tree, 1.0, p_tree)
        tree = tree | stem
    if fill_holes > 0:
        import scipy.ndimage as ndi

        holes, n = ndi.label(ndi.binary_fill_holes(tree) & ~tree)
        if n:
            area = np.bincount(holes.ravel())
            small = np.flatnonzero(area <= fill_holes * tree.sum())
            small = small[small > 0]
            if refine == "matting":  # blue sky seen through the crown stays a gap
                skyish = np.bincount(holes.ravel(), weights=sky.ravel(), minlength=len(area))
                small = small[skyish[small] <= 0.5 * area[small]]
            fill = np.isin(holes, small)
            labels[fill] = 1
            tree = tree | fill
            p_tree = np.where(fill, 1.0, p_tree)
    alpha = np.where(tree, np.clip(p_tree, 0.0, 1.0), 0.0).astype(np.float32)
    return Segmentation(labels, alpha)
