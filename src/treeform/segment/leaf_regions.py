"""Leaf regions of a photo's foliage: mean shift in LUV, split or merge, colour clusters, ellipses.

Seed 002 §6.1 (Tan et al. 2007) segments the matted foliage of each photo into candidate
leaves: a mean-shift filter over position and LUV colour makes homogeneous regions
(Comaniciu and Meer 2002; OpenCV's filter, spatial window ``hs``, colour window ``hr``),
8-connected pixels of the same filtered colour form regions, regions too small merge into
their most similar neighbour and regions too large split by region growing from evenly
spread seeds, so each region has about a leaf's size; k-means over the regions' colours
gives 20-30 clusters of which the brightest (the leaves lit and seen, not the shaded ones
behind) are kept, down to half the foliage's area, and each kept region is fitted by an ellipse through the SVD of its
pixels. The paper's user sets the bandwidths (hs 6-8, hr 3-7) and the leaf sizes; here the
sizes are a parameter (the multi-view route takes them from its leaf cards' size).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from treeform._shared.errors import InputError
from treeform.segment.classical import _check_image

__all__ = ["LeafRegions", "leaf_regions"]


@dataclass
class LeafRegions:
    """Candidate leaves of one photo (N regions).

    Attributes
    ----------
    labels : ndarray, shape (H, W), int32
        Region index of each pixel, -1 outside the foliage.
    centroid : ndarray, shape (N, 2), float
        Centre (x, y) in pixels.
    axes : ndarray, shape (N, 2), float
        Ellipse semi-axes (major, minor) in pixels.
    angle : ndarray, shape (N,), float
        Direction of the major axis, radians from the image's x axis (y down).
    color : ndarray, shape (N, 3), float
        Mean-shift colour (LUV, OpenCV's 8-bit scale).
    area : ndarray, shape (N,), int
        Pixels.
    cluster : ndarray, shape (N,), int
        Colour cluster.
    kept : ndarray, shape (N,), bool
        In one of the brightest clusters: a visible leaf.
    """

    labels: np.ndarray
    centroid: np.ndarray
    axes: np.ndarray
    angle: np.ndarray
    color: np.ndarray
    area: np.ndarray
    cluster: np.ndarray
    kept: np.ndarray

    def __len__(self) -> int:
        return len(self.area)


def _neighbours(shape):
    """The four (a, b) slice pairs of an (H, W) grid whose pixels a[i] and b[i] are 8-neighbours
    (right, down, down-right, down-left): each neighbouring pair once."""
    h, w = shape
    for dy, dx in ((0, 1), (1, 0), (1, 1), (1, -1)):
        yield ((slice(0, h - dy), slice(max(0, -dx), w - max(0, dx))),
               (slice(dy, h), slice(max(0, dx), w - max(0, -dx))))


def _components(key: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Labels (-1 outside ``mask``) of the 8-connected pieces of ``mask`` with equal ``key``."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    h, w = mask.shape
    idx = np.full((h, w), -1, np.int64)
    n = int(mask.sum())
    idx[mask] = np.arange(n)
    rows, cols = [], []
    for a, b in _neighbours((h, w)):
        same = mask[a] & mask[b] & (key[a] == key[b])
        rows.append(idx[a][same])
        cols.append(idx[b][same])
    r, c = np.concatenate(rows), np.concatenate(cols)
    g = coo_matrix((np.ones(len(r), np.int8), (r, c)), shape=(n, n))
    _, lab = connected_components(g, directed=False)
    out = np.full((h, w), -1, np.int32)
    out[mask] = lab
    return out


def _relabel(labels: np.ndarray) -> np.ndarray:
    out = np.full(labels.shape, -1, np.int32)
    inside = labels >= 0
    li = labels[inside]
    if len(li):  # the labels in use, in order, numbered 0.. (np.unique's inverse, without its sort)
        used = np.bincount(li) > 0
        out[inside] = (np.cumsum(used) - 1)[li]
    return out


def _merge_small(labels: np.ndarray, color: np.ndarray, min_area: int, rounds: int = 8) -> np.ndarray:
    """Regions under ``min_area`` pixels join the adjacent region of the closest colour, until none
    is left or no small region has a neighbour."""
    h, w = labels.shape
    for _ in range(rounds):
        n = labels.max() + 1
        if n <= 1:
            break
        area = np.bincount(labels[labels >= 0], minlength=n)
        small = area < min_area
        if not small.any():
            break
        pairs = []
        for sa, sb in _neighbours((h, w)):
            a, b = labels[sa], labels[sb]
            d = (a >= 0) & (b >= 0) & (a != b)
            d[d] = small[a[d]] | small[b[d]]  # only the pairs with a small region matter
            pairs.append(np.stack([a[d], b[d]], 1))
        p = np.concatenate(pairs)
        if not len(p):
            break
        p = np.concatenate([p, p[:, ::-1]]).astype(np.int64)
        p = p[small[p[:, 0]]]  # a small region and each of its neighbours (a pair may repeat)
        if not len(p):
            break
        mean = np.stack([np.bincount(labels[labels >= 0], weights=color[..., c][labels >= 0], minlength=n)
                         for c in range(3)], 1) / np.maximum(area, 1)[:, None]
        cost = np.linalg.norm(mean[p[:, 0]] - mean[p[:, 1]], axis=1)
        # each small region's closest-coloured neighbour, the lowest label among equals (no sort)
        best = np.full(n, np.inf)
        np.minimum.at(best, p[:, 0], cost)
        tie = cost == best[p[:, 0]]
        pick = np.full(n, n)
        np.minimum.at(pick, p[tie, 0], p[tie, 1])
        target = np.where(pick < n, pick, np.arange(n))
        # resolve chains (a -> b -> c) and mutual pairs (a <-> b: both go to the smaller index)
        for _ in range(32):
            nxt = target[target]
            if np.array_equal(nxt, target):
                break
            target = np.where(nxt == np.arange(n), np.minimum(target, np.arange(n)), nxt)
        labels = np.where(labels >= 0, target[np.maximum(labels, 0)], -1).astype(np.int32)
        labels = _relabel(labels)
    return labels


def _split_large(labels: np.ndarray, max_area: int, target: float) -> np.ndarray:
    """Regions over ``max_area`` pixels split by region growing from seeds spread on a grid of
    ``sqrt(target)`` pixels over them (a watershed of a flat image: each pixel joins the seed it
    reaches first inside the region)."""
    from scipy import ndimage as ndi
    from skimage.segmentation import watershed

    n = labels.max() + 1
    if n <= 0:
        return labels
    area = np.bincount(labels[labels >= 0], minlength=n)
    big = np.flatnonzero(area > max_area)
    if not len(big):
        return labels
    out = labels.copy()
    nxt = n
    step = max(2, int(round(np.sqrt(target))))
    boxes = ndi.find_objects(labels + 1)
    for r in big:
        sl = boxes[r]
        region = labels[sl] == r
        yy, xx = np.mgrid[sl[0], sl[1]]
        seeds = region & ((yy - sl[0].start) % step == step // 2) & ((xx - sl[1].start) % step == step // 2)
        if seeds.sum() < 2:
            continue
        markers = np.zeros(region.shape, np.int32)
        markers[seeds] = np.arange(1, int(seeds.sum()) + 1)
        grown = watershed(np.zeros(region.shape, np.uint8), markers, mask=region)
        part = out[sl]
        part[region & (grown > 1)] = nxt + grown[region & (grown > 1)] - 2
        nxt += int(seeds.sum()) - 1
    return _relabel(out)


def leaf_regions(image: np.ndarray, foliage: np.ndarray, *, leaf_area: float, hs: int = 7, hr: int = 5,
                 size_range: tuple[float, float] = (0.5, 2.0), clusters: int = 25, keep: float = 0.5,
                 seed: int = 0) -> LeafRegions:
    """Segment a photo's foliage into candidate leaves (seed 002 §6.1).

    Parameters
    ----------
    image : ndarray, shape (H, W, 3), uint8
        RGB photo.
    foliage : ndarray, shape (H, W), bool
        The matted foliage.
    leaf_area : float
        A leaf's (or leaf cluster's) area in pixels; regions end between ``size_range`` times it.
    hs, hr : int
        Mean-shift spatial and colour (LUV) bandwidths (the paper: 6-8 and 3-7).
    size_range : (float, float)
        Valid region sizes as multiples of ``leaf_area``.
    clusters : int
        k-means colour clusters (the paper: about 20-30).
    keep : float
        The brightest clusters are kept down to those that together hold this share of the
        regions' area (the paper keeps about 10 of 25 clusters, "the brightest colours": on a
        backlit crown against the sky those are a few pale regions, so the share is of area).
    seed : int
        k-means initialisation.

    Returns
    -------
    LeafRegions

    Raises
    ------
    InputError
        Mismatched shapes, a non-RGB image or a non-positive ``leaf_area``.

    Examples
    --------
    >>> img = np.zeros((40, 40, 3), np.uint8); img[:, :20] = (40, 120, 40); img[:, 20:] = (90, 200, 90)
    >>> r = leaf_regions(img, np.ones((40, 40), bool), leaf_area=100.0, clusters=2, keep=0.5)
    >>> len(r) >= 8, bool(r.kept.any()), bool((r.color[r.kept, 0] > 150).all())
    (True, True, True)
    """
    import cv2

    img = _check_image(image, min_side=1)
    mask = np.asarray(foliage, bool)
    if mask.shape != img.shape[:2]:
        raise InputError(f"foliage: expected shape {img.shape[:2]}, got {mask.shape}")
    if not leaf_area > 0:
        raise InputError(f"leaf_area: expected a positive number of pixels, got {leaf_area!r}")
    h, w = mask.shape
    empty = LeafRegions(np.full((h, w), -1, np.int32), np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0),
                        np.zeros((0, 3)), np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, bool))
    if not mask.any():
        return empty
    ys, xs = np.nonzero(mask)
    y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
    luv = cv2.cvtColor(np.ascontiguousarray(img[y0:y1, x0:x1]), cv2.COLOR_RGB2Luv)
    ms = cv2.pyrMeanShiftFiltering(luv, int(hs), int(hr), maxLevel=0)
    m = mask[y0:y1, x0:x1]
    key = (ms[..., 0].astype(np.int64) << 16) | (ms[..., 1].astype(np.int64) << 8) | ms[..., 2]
    lab = _components(key, m)
    msf = ms.astype(np.float64)
    lab = _merge_small(lab, msf, max(1, int(round(size_range[0] * leaf_area))))
    lab = _split_large(lab, int(round(size_range[1] * leaf_area)), float(leaf_area))
    n = int(lab.max()) + 1
    if n <= 0:
        return empty
    inside = lab >= 0
    li = lab[inside]
    area = np.bincount(li, minlength=n)
    yy, xx = np.nonzero(inside)
    a = np.maximum(area, 1).astype(np.float64)
    cx, cy = np.bincount(li, xx, n) / a, np.bincount(li, yy, n) / a
    dx, dy = xx - cx[li], yy - cy[li]
    sxx, syy, sxy = np.bincount(li, dx * dx, n) / a, np.bincount(li, dy * dy, n) / a, np.bincount(li, dx * dy, n) / a
    # the ellipse: the SVD (eigen-decomposition) of each region's pixel scatter; a uniform ellipse of
    # semi-axis s has variance s^2 / 4 along it
    tr, det = sxx + syy, sxx * syy - sxy * sxy
    disc = np.sqrt(np.maximum(0.25 * tr * tr - det, 0.0))
    l1, l2 = 0.5 * tr + disc, np.maximum(0.5 * tr - disc, 0.0)
    axes = 2.0 * np.sqrt(np.stack([l1, l2], 1)) + 0.5
    angle = 0.5 * np.arctan2(2.0 * sxy, sxx - syy)
    color = np.stack([np.bincount(li, msf[..., c][inside], n) for c in range(3)], 1) / a[:, None]
    k = int(min(clusters, n))
    if k >= 2:
        cv2.setRNGSeed(int(seed))
        crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 0.5)
        _, cl, centres = cv2.kmeans(color.astype(np.float32), k, None, crit, 3, cv2.KMEANS_PP_CENTERS)
        cl = cl.ravel().astype(np.int64)
        # the brightest clusters, down to those that make up ``keep`` of the regions' area
        order = np.argsort(-centres[:, 0])
        share = np.cumsum(np.bincount(cl, area, k)[order]) / max(1, area.sum())
        bright = order[:int(np.searchsorted(share, keep)) + 1]
        kept = np.isin(cl, bright)
    else:
        cl, kept = np.zeros(n, np.int64), np.ones(n, bool)
    full = np.full((h, w), -1, np.int32)
    full[y0:y1, x0:x1] = lab
    return LeafRegions(full, np.stack([cx + x0, cy + y0], 1), axes, angle, color, area, cl, kept)
