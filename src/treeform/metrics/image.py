"""Colour agreement between a render and a picture over a region: PSNR and SSIM."""

from __future__ import annotations

import numpy as np

from treeform._shared.errors import InputError

__all__ = ["psnr", "ssim"]


def _images(rendered, reference, mask):
    a = np.asarray(rendered)
    b = np.asarray(reference)
    if a.shape != b.shape or a.ndim not in (2, 3):
        raise InputError(f"images: expected two (H, W) or (H, W, C) arrays of one shape, got {a.shape} and {b.shape}")
    m = np.ones(a.shape[:2], bool) if mask is None else np.asarray(mask, bool)
    if m.shape != a.shape[:2]:
        raise InputError(f"mask: expected shape {a.shape[:2]}, got {m.shape}")
    if not m.any():
        raise InputError("mask: selects no pixel")
    return a.astype(np.float64), b.astype(np.float64), m


def psnr(rendered, reference, mask=None, *, data_range: float = 255.0) -> float:
    """Peak signal-to-noise ratio (dB) over the pixels of ``mask`` (every channel).

    Parameters
    ----------
    rendered, reference : ndarray, shape (H, W) or (H, W, C)
    mask : ndarray, shape (H, W), bool, optional
        Pixels compared (default: all).
    data_range : float
        Peak value (255 for uint8 images).

    Returns
    -------
    float
        ``inf`` when the pixels are identical.

    Examples
    --------
    >>> a = np.zeros((4, 4), np.uint8); b = a.copy(); b[0, 0] = 255
    >>> round(psnr(a, b), 2), psnr(a, b, a == 0) == psnr(a, b)
    (12.04, True)
    """
    a, b, m = _images(rendered, reference, mask)
    mse = float(((a[m] - b[m]) ** 2).mean())
    return float("inf") if mse == 0 else float(10.0 * np.log10(data_range**2 / mse))


def ssim(rendered, reference, mask=None, *, data_range: float = 255.0) -> float:
    """Mean structural similarity (Wang et al. 2004, 7×7 windows) over the pixels of ``mask``.

    The SSIM map of the whole images (``skimage.metrics.structural_similarity``, channels
    averaged) is averaged over ``mask``.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> a = rng.integers(0, 256, (32, 32, 3)).astype(np.uint8)
    >>> ssim(a, a)
    1.0
    """
    from skimage.metrics import structural_similarity

    a, b, m = _images(rendered, reference, mask)
    if min(a.shape[:2]) < 7:
        raise InputError(f"images: SSIM needs at least 7x7 pixels, got {a.shape[:2]}")
    _, smap = structural_similarity(a, b, data_range=data_range, channel_axis=-1 if a.ndim == 3 else None,
                                    full=True)
    if smap.ndim == 3:
        smap = smap.mean(axis=2)
    return float(smap[m].mean())
