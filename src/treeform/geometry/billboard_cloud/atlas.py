"""Stage 3 of the billboard cloud: the regions' RGBA crops in one texture, and their luminance."""

from __future__ import annotations

import math

import numpy as np
import scipy.ndimage as ndi

from treeform._shared.checks import check_array
from treeform._shared.errors import InputError


def build_atlas(rgba, boxes, masks, *, gutter: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Pack the RGBA crops of all billboards into one texture atlas (shelf packing).

    Crops are placed tallest first, left to right in shelves, ``gutter`` transparent
    texels apart. A crop's alpha is 255 on its mask and 0 elsewhere (binary, for alpha
    testing: a bilinear sample less than half a texel off still lands on the right side
    of the 0.5 cutoff); its colour is the picture's (transparent pixels take their
    nearest tree pixel's colour, so filtering and mipmaps bring no dark fringes).

    Parameters
    ----------
    rgba : ndarray, shape (H, W, 4), uint8
        The tree picture (straight alpha).
    boxes : ndarray, shape (n, 4), int
        ``(x0, y0, w, h)`` crops.
    masks : sequence of ndarray, each shape (h_i, w_i), bool
    gutter : int

    Returns
    -------
    atlas : ndarray, shape (Ha, Wa, 4), uint8
        Sides are multiples of 4.
    rects : ndarray, shape (n, 4), int64
        ``(u0, v0, w, h)`` texel rectangle of each crop.

    Examples
    --------
    >>> img = np.full((8, 8, 4), 255, np.uint8)
    >>> boxes = np.array([[0, 0, 4, 4], [4, 4, 2, 3]])
    >>> atlas, rects = build_atlas(img, boxes, [np.ones((4, 4), bool), np.ones((3, 2), bool)])
    >>> atlas.shape, rects.tolist()
    ((16, 8, 4), [[2, 2, 4, 4], [2, 8, 2, 3]])
    """
    rgba = check_array(rgba, "rgba", ndim=3, dtype_kind="u")
    if rgba.shape[2] != 4:
        raise InputError(f"rgba: expected an (H, W, 4) image, got shape {rgba.shape}")
    boxes = check_array(boxes, "boxes", shape=(None, 4), dtype_kind="iu").astype(np.int64)
    if len(masks) != len(boxes) or len(boxes) == 0:
        raise InputError(f"masks: expected one mask per box ({len(boxes)}, at least one), got {len(masks)}")
    g = int(gutter)
    opaque = rgba[..., 3] > 0
    rgb = rgba[..., :3]
    if opaque.any() and not opaque.all():
        _, (ni, nj) = ndi.distance_transform_edt(~opaque, return_indices=True)
        rgb = rgb[ni, nj]
    widths, heights = boxes[:, 2] + g, boxes[:, 3] + g
    atlas_w = int(max(widths.max() + g, math.ceil(math.sqrt(1.1 * float((widths * heights).sum())))))
    atlas_w += -atlas_w % 4
    order = np.lexsort((np.arange(len(boxes)), -heights))
    rects = np.zeros((len(boxes), 4), np.int64)
    u, v, shelf = g, g, 0
    for i in order:
        if u + widths[i] > atlas_w:
            u, v, shelf = g, v + shelf, 0
        rects[i] = (u, v, boxes[i, 2], boxes[i, 3])
        u += widths[i]
        shelf = max(shelf, heights[i])
    atlas_h = v + shelf
    atlas_h += -atlas_h % 4
    atlas = np.zeros((atlas_h, atlas_w, 4), np.uint8)
    for (x0, y0, w, h), (u0, v0, _, _), m in zip(boxes, rects, masks):
        m = np.asarray(m, bool)
        if m.shape != (h, w):
            raise InputError(f"masks: expected a ({h}, {w}) mask for box {(x0, y0, w, h)}, got {m.shape}")
        tile = atlas[v0:v0 + h, u0:u0 + w]
        tile[..., :3] = rgb[y0:y0 + h, x0:x0 + w]
        tile[..., 3] = np.where(m, 255, 0)
    return atlas, rects


def luminance(rgba, boxes, masks) -> np.ndarray:
    """Mean luma (Rec. 709 weights on the sRGB values, in [0, 1]) of each crop's mask pixels.

    Returns
    -------
    ndarray, shape (n,)
    """
    luma = np.asarray(rgba)[..., :3].astype(np.float32) @ np.array([0.2126, 0.7152, 0.0722], np.float32) / 255.0
    return np.array([luma[y0:y0 + h, x0:x0 + w][m].mean() if m.any() else 0.0
                     for (x0, y0, w, h), m in zip(boxes, masks)])
