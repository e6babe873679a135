"""Normalisation of an RGBA tree image (seed 000 §4.1): cropped, scaled into a square, standing on its bottom.

Shared by the variations (every exemplar is normalised before its contours are traced) and by
the growth-form rule (:mod:`treeform.contour.form`), which reads the normalised alpha.
"""

from __future__ import annotations

import cv2
import numpy as np

from treeform._shared.errors import InputError, NoTreeFoundError

__all__ = ["check_rgba", "normalize_rgba"]


def check_rgba(rgba) -> np.ndarray:
    """``rgba`` as an (H, W, 4) uint8 array, or InputError naming what it is instead."""
    a = np.asarray(rgba)
    if a.ndim != 3 or a.shape[2] != 4:
        raise InputError(f"rgba: expected an (H, W, 4) RGBA array, got shape {a.shape}")
    if a.dtype != np.uint8:
        raise InputError(f"rgba: expected dtype uint8, got {a.dtype}")
    return a


def normalize_rgba(rgba, *, size: int = 1024, margin: int | None = None) -> np.ndarray:
    """Normalise an RGBA tree image (seed 000 §4.1).

    Parameters
    ----------
    rgba : ndarray, shape (H, W, 4), uint8
    size : int
        Side of the square output (paper: 1024).
    margin : int, optional
        Transparent border kept around the tree, in output pixels (default ``size // 64``;
        room for the dilation of §4.6).

    Returns
    -------
    ndarray, shape (size, size, 4), uint8
        Straight (not premultiplied) RGBA; every pixel with alpha < 0.5 is (0, 0, 0, 0).
        The tree's opaque box is scaled to fit ``size - 2 margin``, centred horizontally,
        with its bottom on row ``size - 1 - margin``.

    Raises
    ------
    NoTreeFoundError
        No pixel has alpha >= 0.5.
    """
    a = check_rgba(rgba)
    if isinstance(size, bool) or not isinstance(size, (int, np.integer)) or size < 32:
        raise InputError(f"size: expected an integer >= 32, got {size!r}")
    margin = size // 64 if margin is None else int(margin)
    if not 0 <= margin < size // 4:
        raise InputError(f"margin: expected 0 <= margin < {size // 4}, got {margin}")
    opaque = a[..., 3] >= 128  # alpha threshold 0.5
    if not opaque.any():
        raise NoTreeFoundError("rgba: no opaque pixel (alpha >= 0.5): the image shows no tree")
    ys, xs = np.nonzero(opaque)
    crop = a[ys.min():ys.max() + 1, xs.min():xs.max() + 1].astype(np.float32) / 255.0
    keep = crop[..., 3:4] >= 0.5
    alpha = np.where(keep, crop[..., 3:4], 0.0)
    prem = np.concatenate([crop[..., :3] * alpha, alpha], axis=2)  # transparent -> black
    h, w = prem.shape[:2]
    inner = size - 2 * margin
    s = inner / max(h, w)
    nw, nh = max(1, int(round(w * s))), max(1, int(round(h * s)))
    interp = cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR
    small = cv2.resize(prem, (nw, nh), interpolation=interp)
    if small.ndim == 2:  # pragma: no cover - cv2 drops a singleton channel axis only for 1 channel
        small = small[..., None]
    out = np.zeros((size, size, 4), np.float32)
    x0 = (size - nw) // 2
    y0 = size - margin - nh
    out[y0:y0 + nh, x0:x0 + nw] = small
    al = out[..., 3]
    with np.errstate(divide="ignore", invalid="ignore"):
        rgb = np.where(al[..., None] > 1e-6, out[..., :3] / al[..., None], 0.0)
    rgba8 = np.empty((size, size, 4), np.uint8)
    rgba8[..., :3] = np.clip(np.rint(rgb * 255), 0, 255)
    rgba8[..., 3] = np.clip(np.rint(al * 255), 0, 255)
    rgba8[rgba8[..., 3] < 128] = 0
    if not (rgba8[..., 3] >= 128).any():
        raise NoTreeFoundError("rgba: the tree vanished when normalised (too thin for the output size)")
    return rgba8
