"""Relief from luminance by a Gaussian pyramid (seed 001 §3.4)."""

from __future__ import annotations

import numpy as np
import scipy.ndimage as ndi

from treeform._shared.checks import check_array
from treeform._shared.errors import InputError


def relief_map(image: np.ndarray, mask: np.ndarray, *, levels: int = 4, decay: float = 0.5) -> np.ndarray:
    """Relief h in [0, 1] over the crown: brighter is closer to the surface, darker deeper.

    The luminance of the crown is normalised to [0, 1]; a blur pyramid (Burt–Adelson
    style: blur, halve, repeat) gives ``levels`` images, each upsampled back to full
    size; they are summed with exponentially decreasing weights from the blurriest
    (largest weight: large, deep structures) to the finest (small details).

    Parameters
    ----------
    image : ndarray, shape (H, W, 3), uint8
    mask : ndarray, shape (H, W), bool
        Crown pixels; the relief is 0.5 outside.
    levels : int
        Pyramid levels N (the paper tests 4 and 5).
    decay : float
        Weight ratio between consecutive levels (finer = ``decay`` × coarser).

    Returns
    -------
    ndarray, shape (H, W), float32

    Examples
    --------
    >>> img = np.zeros((32, 32, 3), np.uint8); img[:, 16:] = 200
    >>> h = relief_map(img, np.ones((32, 32), bool))
    >>> bool(h[:, 24:].mean() > h[:, :8].mean())
    True
    """
    image = check_array(image, "image", ndim=3)
    mask = check_array(mask, "mask", ndim=2).astype(bool)
    if mask.shape != image.shape[:2]:
        raise InputError(f"mask: shape {mask.shape} does not match image {image.shape[:2]}")
    if not 1 <= levels <= 8:
        raise InputError(f"levels: expected 1..8, got {levels}")
    rgb = image[..., :3].astype(np.float32) / 255.0
    lum = 0.2126 * rgb[..., 0] + 0.7152 * rgb[..., 1] + 0.0722 * rgb[..., 2]
    out = np.full(mask.shape, 0.5, np.float32)
    if not mask.any():
        return out
    lo, hi = np.percentile(lum[mask], [2, 98])
    lum = np.clip((lum - lo) / max(hi - lo, 1e-6), 0, 1)
    mean = float(lum[mask].mean())
    lum = np.where(mask, lum, mean)  # keep the background from bleeding into the blur
    h, w = lum.shape
    level = lum
    acc = np.zeros_like(lum)
    weights = decay ** np.arange(levels)[::-1]  # finest first -> smallest weight
    for i in range(levels):
        up = level if i == 0 else ndi.zoom(level, (h / level.shape[0], w / level.shape[1]), order=1)[:h, :w]
        acc += weights[i] * up
        level = ndi.gaussian_filter(level, 1.0)[::2, ::2]
        if min(level.shape) < 2:
            weights = weights[: i + 1]
            break
    acc /= weights.sum()
    v = acc[mask]
    lo, hi = v.min(), v.max()
    out[mask] = (v - lo) / max(hi - lo, 1e-6)
    return out
