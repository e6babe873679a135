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

__all__ = ["segment_tree_learned", "guided_filter"]

MIN_TREE_FRACTION = 0.01
"""A main tree smaller than this share of the photo counts as no tree."""

HOLE_FRACTION = 0.02
"""Default of ``fill_holes``: enclosed holes below this share of the tree's area are filled."""

REFINE_SIDE = 1024
"""Long side, in pixels, at which the guided-filter edge refinement runs at most."""


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


def segment_tree_learned(image: np.ndarray, *, weights=None, refine: bool = True,
                         fill_holes: float = HOLE_FRACTION) -> Segmentation:
    """Segment the main tree of a photo with the learned network.

    Parameters
    ----------
    image : ndarray, shape (H, W, 3), uint8
        RGB photo.
    weights : path, optional
        ONNX weights (default: the shipped ``seg.onnx``).
    refine : bool
        Snap the tree probability's edge to the photo's edges with :func:`guided_filter`
        (the network sees the photo at about 320 px; its upsampled edge is soft).
    fill_holes : float
        Holes inside the tree smaller than this share of the tree's area become foliage
        (0 keeps every hole).

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
    seg_net = Segmenter(weights)
    p = seg_net.probabilities(img)
    p_tree = 1.0 - p[..., 0]
    if refine:
        import cv2

        H, W = img.shape[:2]
        f = min(1.0, REFINE_SIDE / max(H, W))  # the filter runs at most at REFINE_SIDE
        guide = img if f == 1.0 else cv2.resize(img, (round(W * f), round(H * f)), interpolation=cv2.INTER_AREA)
        src = p_tree if f == 1.0 else cv2.resize(p_tree, guide.shape[1::-1], interpolation=cv2.INTER_AREA)
        scale = max(guide.shape[:2]) / seg_net.side
        if scale > 1.2:  # only when the photo is finer than the network's view
            ref = np.clip(guided_filter(guide, src, radius=max(2, int(round(2 * scale))), eps=2e-3), 0.0, 1.0)
            p_tree = ref if f == 1.0 else cv2.resize(ref, (W, H), interpolation=cv2.INTER_LINEAR)
    # the main tree: the largest part, weighted by sharpness (a blurred tree behind loses)
    tree = main_tree(p_tree > 0.5, focus=focus_map(img, seg_net.side))
    if tree.mean() < MIN_TREE_FRACTION:
        raise NoTreeFoundError("no tree found in the photo")
    labels = np.where(tree, np.where(p[..., 2] > p[..., 1], 2, 1), 0).astype(np.uint8)
    if fill_holes > 0:
        import scipy.ndimage as ndi

        holes, n = ndi.label(ndi.binary_fill_holes(tree) & ~tree)
        if n:
            area = np.bincount(holes.ravel())
            small = np.flatnonzero(area <= fill_holes * tree.sum())
            small = small[small > 0]
            fill = np.isin(holes, small)
            labels[fill] = 1
            tree = tree | fill
            p_tree = np.where(fill, 1.0, p_tree)
    alpha = np.where(tree, np.clip(p_tree, 0.0, 1.0), 0.0).astype(np.float32)
    return Segmentation(labels, alpha)
