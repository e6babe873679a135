"""Silhouette agreement between a render and the photo's tree mask."""

from __future__ import annotations

import numpy as np

from treeform._shared.errors import InputError


def _pair(rendered, reference):
    a = np.asarray(rendered, bool)
    b = np.asarray(reference, bool)
    if a.shape != b.shape:
        raise InputError(f"masks: shapes differ, {a.shape} vs {b.shape}")
    return a, b


def reprojection_error(rendered: np.ndarray, reference: np.ndarray) -> float:
    """Reprojection error of seed 004 eq. (3): ``#((I - B)^2 == 1) / #B``.

    The count of pixels where the rendered silhouette I and the photo's mask B
    disagree (their XOR), divided by the mask's pixel count.

    Parameters
    ----------
    rendered, reference : ndarray, shape (H, W), bool

    Examples
    --------
    >>> b = np.zeros((4, 4), bool); b[:2] = True
    >>> i = np.zeros((4, 4), bool); i[:3] = True
    >>> reprojection_error(i, b)
    0.5
    """
    a, b = _pair(rendered, reference)
    nb = int(b.sum())
    if nb == 0:
        raise InputError("reference: the tree mask is empty")
    return float(np.logical_xor(a, b).sum() / nb)


def iou(rendered: np.ndarray, reference: np.ndarray) -> float:
    """Intersection over union of two masks (1.0 when both are empty).

    Examples
    --------
    >>> a = np.zeros((4, 4), bool); a[:2] = True
    >>> iou(a, a)
    1.0
    """
    a, b = _pair(rendered, reference)
    union = int((a | b).sum())
    return 1.0 if union == 0 else float((a & b).sum() / union)


def extent_ratio(side_mask: np.ndarray, front_mask: np.ndarray, *, percentile: float = 1.0) -> float:
    """Depth/width of a tree: horizontal extent of its side silhouette over its front one.

    Both masks must come from cameras at the same distance and field of view (the side
    camera is the front one orbited 90° about the tree). Extents are measured between
    the ``percentile`` and ``100 - percentile`` percentiles of the silhouette columns.
    """
    def extent(m):
        cols = np.nonzero(np.asarray(m, bool))[1]
        if len(cols) == 0:
            return 0.0
        lo, hi = np.percentile(cols, [percentile, 100 - percentile])
        return float(hi - lo + 1)

    w = extent(front_mask)
    if w == 0:
        raise InputError("front_mask: empty silhouette")
    return extent(side_mask) / w


def silhouette_gaps(mask: np.ndarray, *, reach: float = 0.025) -> float:
    """Share of a silhouette's outline that is open: sky seen through and between its parts.

    The outline is the silhouette closed by ``reach`` times its image's longer side (a
    city-block closing: gaps narrower than about twice that are bridged) with its holes
    filled; the gaps are the outline's pixels the silhouette leaves empty. A crown drawn as
    a solid ball scores about 0; real crowns, with lobes and holes between their limbs,
    0.1-0.3 from any side (the synthetic trees of ``treeform eval``: about 0.2).

    Parameters
    ----------
    mask : ndarray, shape (H, W), bool
    reach : float
        Closing radius as a fraction of ``max(H, W)`` (at least 1 pixel).

    Returns
    -------
    float
        In [0, 1); 0 for an empty mask.

    Examples
    --------
    >>> ring = np.zeros((40, 40), bool); ring[5:35, 5:35] = True; ring[15:25, 15:25] = False
    >>> silhouette_gaps(ring), silhouette_gaps(np.ones((40, 40), bool))
    (0.1111, 0.0)
    """
    import scipy.ndimage as ndi

    m = np.asarray(mask)
    if m.ndim != 2:
        raise InputError(f"mask: expected an (H, W) array, got shape {m.shape}")
    m = m.astype(bool)
    if not m.any():
        return 0.0
    k = max(1, int(round(reach * max(m.shape))))
    closed = ndi.binary_closing(np.pad(m, k), ndi.generate_binary_structure(2, 1), iterations=k)[k:-k, k:-k] | m
    outline = ndi.binary_fill_holes(closed)
    return round(1.0 - float(m.sum()) / float(outline.sum()), 4)
