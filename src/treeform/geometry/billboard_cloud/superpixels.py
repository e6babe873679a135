"""Stage 1 of the billboard cloud: SLIC superpixels of the crown (seed 000 §6)."""

from __future__ import annotations

import math

import cv2
import numpy as np
import scipy.ndimage as ndi

from treeform._shared.checks import check_array, check_positive
from treeform._shared.errors import InputError, NoTreeFoundError


def superpixels(rgb, mask, *, n_segments: int = 256, compactness: float = 0.35, max_side: int = 512) -> np.ndarray:
    """SLIC superpixels of the crown (seed 000 §6, [ASS*12], Fig. 9).

    SLIC runs on the colours in [0, 1] (no Lab conversion: the paper's compactness 0.35
    is on that scale) of the crown's bounding box, reduced so that its longer side is at
    most ``max_side``; the labels are scaled back (nearest) and every crown pixel the
    reduced mask missed takes the label of its nearest labelled pixel. Superpixels are
    then split into 8-connected pieces (a superpixel's box never spans a gap of the
    crown); pieces under a tenth of the mean superpixel area join the nearest large piece
    within half a superpixel side, farther crumbs stay on their own.

    Parameters
    ----------
    rgb : ndarray, shape (H, W, 3), uint8
    mask : ndarray, shape (H, W), bool
        Crown pixels (the superpixels partition exactly these).
    n_segments : int
        Approximate number of superpixels (paper: 256).
    compactness : float
        SLIC compactness (paper: 0.35; lower gives more fractal, less even regions).
    max_side : int
        Longest side SLIC runs at (speed; 512 keeps a 1024² tree well under a second).

    Returns
    -------
    ndarray, shape (H, W), int32
        0 outside ``mask``; 8-connected superpixels labelled 1 .. n consecutively.

    Examples
    --------
    >>> m = np.zeros((64, 64), bool); m[8:56, 8:56] = True
    >>> rgb = np.zeros((64, 64, 3), np.uint8); rgb[:, 32:] = 200
    >>> lab = superpixels(rgb, m, n_segments=8)
    >>> bool((lab[m] > 0).all() and (lab[~m] == 0).all()), int(lab.max()) >= 4
    (True, True)
    """
    from skimage.segmentation import slic

    rgb = check_array(rgb, "rgb", ndim=3, dtype_kind="u")
    mask = check_array(mask, "mask", ndim=2).astype(bool)
    if rgb.shape[:2] != mask.shape or rgb.shape[2] != 3:
        raise InputError(f"rgb: expected shape {mask.shape + (3,)} to match the mask, got {rgb.shape}")
    if isinstance(n_segments, bool) or not isinstance(n_segments, (int, np.integer)) or n_segments < 1:
        raise InputError(f"n_segments: expected a positive integer, got {n_segments!r}")
    compactness = check_positive(compactness, "compactness")
    if compactness > 100:  # colours in [0, 1]: beyond ~10 the regions are a plain grid
        raise InputError(f"compactness: expected a number in (0, 100], got {compactness:g}")
    if isinstance(max_side, bool) or not isinstance(max_side, (int, np.integer)) or max_side < 16:
        raise InputError(f"max_side: expected an integer >= 16, got {max_side!r}")
    if not mask.any():
        raise NoTreeFoundError("mask: no crown pixels to segment into superpixels")
    ys, xs = np.nonzero(mask)
    y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
    crop_rgb, crop_mask = rgb[y0:y1, x0:x1], mask[y0:y1, x0:x1]
    h, w = crop_mask.shape
    scale = min(1.0, max_side / max(h, w))
    if scale < 1.0:
        size = (max(1, round(w * scale)), max(1, round(h * scale)))
        small_rgb = cv2.resize(crop_rgb, size, interpolation=cv2.INTER_AREA)
        small_mask = cv2.resize(crop_mask.astype(np.float32), size, interpolation=cv2.INTER_AREA) >= 0.5
        if not small_mask.any():
            small_mask = cv2.resize(crop_mask.astype(np.uint8), size, interpolation=cv2.INTER_NEAREST) > 0
    else:
        small_rgb, small_mask = crop_rgb, crop_mask
    if small_mask.any():
        lab = slic(small_rgb.astype(np.float32) / 255.0, n_segments=int(n_segments), compactness=compactness,
                   mask=small_mask, start_label=1, convert2lab=False, channel_axis=-1)
    else:  # a crown thinner than one reduced pixel everywhere: one region
        lab = np.ones(small_mask.shape, np.int64)
    if scale < 1.0:
        lab = cv2.resize(lab.astype(np.int32), (w, h), interpolation=cv2.INTER_NEAREST)
    lab = np.where(crop_mask, lab, 0)
    missing = crop_mask & (lab == 0)
    if missing.any():
        _, (ni, nj) = ndi.distance_transform_edt(lab == 0, return_indices=True)
        lab[missing] = lab[ni[missing], nj[missing]]
    lab = _connected(lab, crop_mask.sum() / max(int(lab.max()), 1))
    used = np.unique(lab[crop_mask])
    lut = np.zeros(int(used.max()) + 1, np.int32)
    lut[used] = np.arange(1, used.size + 1)  # consecutive 1 .. n
    out = np.zeros(mask.shape, np.int32)
    out[y0:y1, x0:x1] = lut[lab]
    return out


def _connected(lab: np.ndarray, mean_area: float) -> np.ndarray:
    """Split labels into 8-connected pieces; small pieces join a near large one.

    A piece smaller than a tenth of ``mean_area`` takes, pixel by pixel, the label of the
    nearest pixel of a large piece when that is at most half a superpixel side away;
    farther crumbs (a detached twig) stay superpixels of their own, so that no superpixel's
    box spans a gap of the crown.
    """
    from skimage.measure import label

    pieces = label(lab, background=0, connectivity=2)
    sizes = np.bincount(pieces.ravel())
    small = sizes < 0.1 * mean_area
    small[0] = False
    crumbs = small[pieces]
    large = (pieces > 0) & ~crumbs
    if crumbs.any() and large.any():
        dist, (ni, nj) = ndi.distance_transform_edt(~large, return_indices=True)
        near = crumbs & (dist <= 0.5 * math.sqrt(mean_area))
        pieces[near] = pieces[ni[near], nj[near]]
    return pieces
