"""Colour agreement between a render and a picture over a region: PSNR, SSIM and colour-histogram distance."""

from __future__ import annotations

import numpy as np

from treeform._shared.errors import InputError

__all__ = ["color_distance", "psnr", "ssim"]


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


def color_distance(rendered, reference, mask=None, *, reference_mask=None, bins: int = 8) -> float:
    """Hellinger distance between the RGB colour histograms of two images over ``mask``.

    Each image's pixels inside ``mask`` fall into ``bins``³ RGB cells; the distance
    ``sqrt(1 - Σ sqrt(p·q))`` is 0 for identical colour distributions and 1 for disjoint
    ones, whatever the pixels' arrangement (SSIM judges the arrangement).

    Parameters
    ----------
    rendered, reference : ndarray, shape (H, W, 3), uint8
    mask : ndarray, shape (H, W), bool, optional
    reference_mask : ndarray, bool, optional
        The reference's own pixels, when they are elsewhere (e.g. a side view against the
        photo's tree): ``reference`` may then have another size, and ``mask`` selects in
        ``rendered`` only.
    bins : int
        Cells per channel (2..64).

    Examples
    --------
    >>> a = np.zeros((4, 4, 3), np.uint8); b = np.full((4, 4, 3), 255, np.uint8)
    >>> color_distance(a, a), color_distance(a, b)
    (0.0, 1.0)
    >>> big = np.zeros((8, 8, 3), np.uint8); big[:4] = 255; top = np.zeros((8, 8), bool); top[:4] = True
    >>> color_distance(b, big, reference_mask=top)
    0.0
    """
    from treeform._shared.checks import check_int

    bins = check_int(bins, "bins", 2, 64)
    if reference_mask is None:
        a, b, m = _images(rendered, reference, mask)
        mb = m
    else:
        a, _, m = _images(rendered, rendered, mask)
        b, _, mb = _images(reference, reference, reference_mask)
    if a.ndim != 3 or a.shape[2] != 3 or b.ndim != 3 or b.shape[2] != 3:
        raise InputError(f"images: expected (H, W, 3) RGB arrays, got {a.shape} and {b.shape}")

    def hist(img, sel):
        q = np.clip((img[sel] * (bins / 256.0)).astype(np.int64), 0, bins - 1)
        h = np.bincount((q[:, 0] * bins + q[:, 1]) * bins + q[:, 2], minlength=bins**3).astype(np.float64)
        return h / h.sum()

    bc = float(np.sqrt(hist(a, m) * hist(b, mb)).sum())
    return float(np.sqrt(max(0.0, 1.0 - min(bc, 1.0))))
