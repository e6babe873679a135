"""Tangent-space normal maps from height fields (glTF ``normalTexture`` convention)."""

from __future__ import annotations

import numpy as np

from treeform._shared.errors import InputError

__all__ = ["normal_map_from_height", "texture_height"]


def normal_map_from_height(height, *, strength: float = 2.0, wrap: bool = True) -> np.ndarray:
    """A tangent-space normal map whose bumps follow ``height`` (higher = towards the viewer).

    Central differences of the height field, in texels, scaled by ``strength``; the normal
    of texel (row, col) is ``normalize(-dh/dx, -dh/dy, 1)`` with x to the right and y *up*
    the image (rows grow downwards), encoded as ``(n + 1) / 2`` in RGB (glTF: +X right, +Y
    up, +Z out of the surface).

    Parameters
    ----------
    height : array_like, shape (H, W)
        Height in [0, 1] (any finite range works; ``strength`` scales slopes).
    strength : float
        Height units per texel of a 45° slope: larger gives stronger bumps.
    wrap : bool
        Periodic differences (for tileable textures); otherwise one-sided at the borders.

    Returns
    -------
    ndarray, shape (H, W, 4), uint8
        RGB normal, alpha 255.

    Examples
    --------
    >>> flat = normal_map_from_height(np.zeros((4, 4)))
    >>> flat[0, 0].tolist()
    [128, 128, 255, 255]
    >>> ramp = normal_map_from_height(np.tile(np.arange(8.0) / 8, (8, 1)), wrap=False)
    >>> bool(ramp[4, 4, 0] < 128)   # height grows to the right: the normal leans left
    True
    """
    h = np.asarray(height, np.float64)
    if h.ndim != 2 or min(h.shape) < 2 or not np.all(np.isfinite(h)):
        raise InputError(f"height: expected a finite (H, W) array with H, W >= 2, got shape {h.shape}")
    if not (np.isfinite(strength) and strength >= 0):
        raise InputError(f"strength: expected a finite number >= 0, got {strength!r}")
    if wrap:
        dx = 0.5 * (np.roll(h, -1, axis=1) - np.roll(h, 1, axis=1))
        drow = 0.5 * (np.roll(h, -1, axis=0) - np.roll(h, 1, axis=0))
    else:
        drow, dx = np.gradient(h)
    n = np.stack([-strength * dx, strength * drow, np.ones_like(h)], axis=-1)  # dy_up = -drow
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    out = np.empty(h.shape + (4,), np.uint8)
    out[..., :3] = np.clip(np.rint((n + 1.0) * 127.5), 0, 255).astype(np.uint8)
    out[..., 3] = 255
    return out


def texture_height(texture) -> np.ndarray:
    """A height proxy of an RGBA texture: luminance where opaque (dark cracks are deep), (H, W) in [0, 1].

    Transparent texels get the mean opaque luminance, so card edges make no false bumps.

    Examples
    --------
    >>> t = np.zeros((2, 2, 4), np.uint8); t[0, 0] = (255, 255, 255, 255)
    >>> texture_height(t).round(6).tolist()
    [[1.0, 1.0], [1.0, 1.0]]
    """
    t = np.asarray(texture)
    if t.ndim != 3 or t.shape[2] != 4:
        raise InputError(f"texture: expected an (H, W, 4) array, got shape {t.shape}")
    lum = (t[..., :3].astype(np.float64) @ np.array([0.2126, 0.7152, 0.0722])) / 255.0
    opaque = t[..., 3] >= 128
    if opaque.any() and not opaque.all():
        lum = np.where(opaque, lum, lum[opaque].mean())
    return lum
