"""Tileable band-limited noise (textures, procedural backgrounds)."""

from __future__ import annotations

import numpy as np

__all__ = ["periodic_noise"]


def periodic_noise(rng: np.random.Generator, h: int, w: int, sigma_y: float, sigma_x: float) -> np.ndarray:
    """Tileable Gaussian-filtered white noise, normalised to zero mean and unit std.

    The white noise's spectrum is weighted by ``exp(-(fy / sigma_y)² / 2 - (fx / sigma_x)² / 2)``
    with frequencies in cycles per image, so ``sigma`` ≈ the number of features across the
    image along that axis (small = smooth).

    Parameters
    ----------
    rng : numpy.random.Generator
    h, w : int
        Shape.
    sigma_y, sigma_x : float
        Spectral widths in cycles per image (> 0).

    Returns
    -------
    ndarray, shape (h, w), float64

    Examples
    --------
    >>> n = periodic_noise(np.random.default_rng(0), 32, 64, 4.0, 8.0)
    >>> n.shape, round(float(n.std()), 6)
    ((32, 64), 1.0)
    """
    fy = np.fft.fftfreq(h)[:, None] * h
    fx = np.fft.rfftfreq(w)[None, :] * w
    spec = np.fft.rfft2(rng.standard_normal((h, w)))
    spec *= np.exp(-0.5 * ((fy / sigma_y) ** 2 + (fx / sigma_x) ** 2))
    n = np.fft.irfft2(spec, s=(h, w))
    n -= n.mean()
    return n / (n.std() + 1e-12)
