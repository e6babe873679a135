"""Generalized potential field of a binary shape (seed 004 §3.1–3.2, after Cornea et al.).

For every pixel ``p`` of a shape B the force is a weighted sum over source pixels ``m``::

    f(p) = sum_m  w(m) * (p - m) / |p - m|**3

(a unit vector away from the source divided by the squared distance). Cornea's original
field takes the contour pixels of B as sources with ``w = 1``; seed 004 eq. (1) takes every
pixel of B with ``w = P(m)``, a probability map equal to 1 on the contour and in ``[0, 1]``
inside (the probability to be an artificial contour point), so ``P = 0`` inside gives
Cornea's field back. The sum is a convolution of the weight image with the kernel
``d / |d|**3``, computed here by FFT on the mask reduced to a working size.

Coordinates are pixels: ``fx`` along columns (x), ``fy`` along rows (y, down).
"""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np
from scipy import fft as sfft

from treeform._shared.checks import check_array, check_int
from treeform._shared.errors import InputError

__all__ = ["force_field", "contour_pixels", "source_field", "check_mask", "work_scale"]

_CROSS = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], np.uint8)


def check_mask(mask, name: str = "mask") -> np.ndarray:
    """Return ``mask`` as an (H, W) bool array; raise ``InputError`` naming ``name`` otherwise.

    Accepts bool or numeric arrays (non-zero = inside).
    """
    arr = check_array(mask, name, ndim=2, dtype_kind="biuf")
    if min(arr.shape) < 2:
        raise InputError(f"{name}: expected an (H, W) image with H, W >= 2, got shape {arr.shape}")
    return arr.astype(bool) if arr.dtype != bool else arr


def work_scale(shape, max_side: int) -> tuple[int, int]:
    """Working size ``(h, w)`` of an (H, W) mask whose long side is reduced to ``max_side``.

    Examples
    --------
    >>> work_scale((600, 300), 160)
    (160, 80)
    >>> work_scale((50, 40), 160)
    (50, 40)
    """
    H, W = int(shape[0]), int(shape[1])
    s = min(1.0, max_side / max(H, W))
    if s >= 1.0:
        return H, W
    return max(2, int(round(H * s))), max(2, int(round(W * s)))


def contour_pixels(mask: np.ndarray) -> np.ndarray:
    """Pixels of ``mask`` with a 4-neighbour outside it (or outside the image).

    Parameters
    ----------
    mask : ndarray, shape (H, W), bool

    Returns
    -------
    ndarray, shape (H, W), bool
        The contour set Ω of seed 004 §3.1.
    """
    m = mask.astype(np.uint8)
    er = cv2.erode(m, _CROSS, borderType=cv2.BORDER_CONSTANT, borderValue=0)
    return (m > 0) & (er == 0)


@lru_cache(maxsize=24)
def _kernel_fft(sh: int, sw: int) -> np.ndarray:
    """FFT of the complex kernel ``(dx + i dy) / |d|**3`` laid out for a circular convolution."""
    iy = np.arange(sh)
    iy = np.where(iy <= sh // 2, iy, iy - sh).astype(np.float64)
    ix = np.arange(sw)
    ix = np.where(ix <= sw // 2, ix, ix - sw).astype(np.float64)
    dy, dx = iy[:, None], ix[None, :]
    r2 = dx * dx + dy * dy
    r2[0, 0] = 1.0
    inv = r2 ** -1.5
    inv[0, 0] = 0.0
    kf = sfft.fft2((dx + 1j * dy) * inv)
    kf.setflags(write=False)
    return kf


def source_field(weights: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Force field of a weight image, exactly (no resizing): seed 004 eq. (1).

    Parameters
    ----------
    weights : ndarray, shape (h, w), float
        Source weight ``w(m)`` of every pixel (1 on the contour, ``P`` inside, 0 outside).
    mask : ndarray, shape (h, w), bool
        Where the field is wanted; it is set to 0 elsewhere.

    Returns
    -------
    ndarray, shape (h, w, 2), float64
        ``(fx, fy)`` = ``sum_m w(m) (p - m) / |p - m|**3`` in pixel units.

    Notes
    -----
    A circular FFT convolution on a grid of at least ``(2h - 1, 2w - 1)`` equals the linear
    one on the ``(h, w)`` window; the kernel's FFT is cached per grid size.
    """
    h, w = weights.shape
    sh, sw = sfft.next_fast_len(2 * h - 1), sfft.next_fast_len(2 * w - 1)
    wf = sfft.fft2(weights.astype(np.float64), s=(sh, sw))
    out = sfft.ifft2(wf * _kernel_fft(sh, sw))[:h, :w]
    f = np.empty((h, w, 2))
    f[..., 0] = out.real
    f[..., 1] = out.imag
    f[~mask] = 0.0
    return f


def _downsample_probability(p: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Reduce a probability map keeping thin lines (max filter over one working pixel, then area mean)."""
    H, W = p.shape
    h, w = size
    k = int(np.ceil(max(H / h, W / w)))
    if k > 1:
        p = cv2.dilate(p.astype(np.float32), np.ones((k, k), np.uint8))
    return np.clip(cv2.resize(p.astype(np.float32), (w, h), interpolation=cv2.INTER_AREA), 0.0, 1.0).astype(np.float64)


def force_field(mask, *, probability=None, max_side: int = 160) -> np.ndarray:
    """Generalized potential field of a binary shape (seed 004 §3.1–3.2, eq. (1)).

    Parameters
    ----------
    mask : array_like, shape (H, W), bool
        The binary shape B.
    probability : array_like, shape (H, W), float in [0, 1], optional
        Probability map P: the weight of each interior pixel as an artificial contour point.
        ``None`` (all zero) gives Cornea et al.'s field, whose sources are the contour pixels
        only. The contour always has weight 1.
    max_side : int
        The field is computed on the mask reduced so that its long side is ``max_side``
        pixels (area resampling, threshold 1/2; P reduced by a max filter then an area mean so
        that 1-pixel cuts survive), then brought back to (H, W) by bilinear interpolation.

    Returns
    -------
    ndarray, shape (H, W, 2), float64
        Force ``(fx, fy)`` per pixel, 0 outside the mask. At the working size the vectors are
        exact sums over the sources; brought back to (H, W) they are multiplied by the working
        scale ``s = max_side / max(H, W)`` (the exact factor for contour sources of a scaled
        shape), so magnitudes compare across sizes. Inside a convex shape it points away from
        the contour and vanishes at the shape's "centre".

    Raises
    ------
    InputError
        ``mask`` is not 2-D, ``probability`` has another shape or leaves [0, 1], or
        ``max_side`` is not an integer >= 8.

    Examples
    --------
    >>> yy, xx = np.mgrid[:21, :21]
    >>> f = force_field((xx - 10) ** 2 + (yy - 10) ** 2 <= 81)
    >>> bool(f[10, 15, 0] < 0 and abs(f[10, 15, 1]) < 1e-9)   # points toward the centre
    True
    """
    m = check_mask(mask)
    max_side = check_int(max_side, "max_side", 8, 1 << 16)
    H, W = m.shape
    p = None
    if probability is not None:
        p = check_array(probability, "probability", ndim=2, dtype_kind="biuf", shape=(H, W)).astype(np.float64)
        if p.size and (p.min() < 0.0 or p.max() > 1.0):
            raise InputError(f"probability: expected values in [0, 1], got [{p.min():.3g}, {p.max():.3g}]")
    if not m.any():
        return np.zeros((H, W, 2))
    h, w = work_scale((H, W), max_side)
    if (h, w) == (H, W):
        mw, pw = m, p
    else:
        mw = cv2.resize(m.astype(np.float32), (w, h), interpolation=cv2.INTER_AREA) >= 0.5
        pw = None if p is None else _downsample_probability(p, (h, w))
    weights = np.zeros((h, w)) if pw is None else np.where(mw, pw, 0.0)
    weights[contour_pixels(mw)] = 1.0
    f = source_field(weights, mw)
    if (h, w) != (H, W):
        s = float(np.sqrt((h / H) * (w / W)))
        f = cv2.resize(f.astype(np.float32), (W, H), interpolation=cv2.INTER_LINEAR).astype(np.float64) * s
        f[~m] = 0.0
    return f
