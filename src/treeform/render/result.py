"""What a render gives back (:class:`RenderResult`) and the readback's colour conversions."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from treeform._shared.errors import InputError
from treeform.structures.camera import Camera

__all__ = ["RenderResult", "to_uint8_rgb"]


@dataclass
class RenderResult:
    """What one render produced; every array has row 0 at the top of the image.

    Attributes
    ----------
    color : ndarray, shape (H, W, 4), uint8
        Display-referred RGBA, straight (not premultiplied) alpha; alpha 0 (and RGB = the
        background colour) where nothing was drawn and the background is transparent.
    mask : ndarray, shape (H, W), bool
        Silhouette: pixel centres covered by any geometry after the alpha test (no MSAA).
    depth : ndarray, shape (H, W), float32
        Distance along the camera's view axis in metres (as ``Camera.project(...)[:, 2]``);
        ``np.inf`` where ``mask`` is False.
    camera : Camera
        The camera the image was rendered with.
    part : ndarray, shape (H, W), int16
        Index into the rendered mesh's ``parts`` of the surface seen at each pixel centre
        (the same samples as ``mask``); -1 where ``mask`` is False. E.g. a label image is
        ``np.where(part >= 0, labels_of_parts[part], 0)``.
    triangle : ndarray, shape (H, W), int32
        Index of the triangle within that part (``gl_PrimitiveID``); -1 where empty.
    normal : ndarray, shape (H, W, 3), float32, or None
        World-space unit normal of the surface (flipped toward the viewer on the back of
        double-sided parts; without normal maps); zeros where empty. Only with ``aux=True``.
    uv : ndarray, shape (H, W, 2), float32, or None
        Interpolated texture coordinates; zeros where empty. Only with ``aux=True``.
    """

    color: np.ndarray
    mask: np.ndarray
    depth: np.ndarray
    camera: Camera | None = field(default=None, repr=False)
    part: np.ndarray | None = field(default=None, repr=False)
    triangle: np.ndarray | None = field(default=None, repr=False)
    normal: np.ndarray | None = field(default=None, repr=False)
    uv: np.ndarray | None = field(default=None, repr=False)

    def rgb(self, background=(255, 255, 255)) -> np.ndarray:
        """``color`` composited over ``background``: (H, W, 3) uint8."""
        return to_uint8_rgb(self.color, background)


def to_uint8_rgb(color: np.ndarray, background=(255, 255, 255)) -> np.ndarray:
    """Composite straight-alpha RGBA over an opaque background colour (for previews).

    Parameters
    ----------
    color : ndarray, shape (H, W, 4), uint8
        RGBA image, e.g. ``RenderResult.color``.
    background : sequence of 3 ints in [0, 255]
        Background RGB.

    Returns
    -------
    ndarray, shape (H, W, 3), uint8

    Examples
    --------
    >>> px = np.array([[[255, 0, 0, 255], [255, 0, 0, 0], [0, 0, 0, 128]]], np.uint8)
    >>> to_uint8_rgb(px, background=(0, 0, 255)).tolist()
    [[[255, 0, 0], [0, 0, 255], [0, 0, 127]]]
    """
    c = np.asarray(color)
    if c.ndim != 3 or c.shape[2] != 4:
        raise InputError(f"color: expected an (H, W, 4) RGBA array, got shape {c.shape}")
    if c.dtype != np.uint8:
        raise InputError(f"color: expected dtype uint8, got {c.dtype}")
    bg = np.asarray(background, np.float32).reshape(-1)
    if bg.shape != (3,) or not np.all((bg >= 0) & (bg <= 255)):
        raise InputError(f"background: expected 3 values in [0, 255], got {background!r}")
    a = c[..., 3:4].astype(np.float32) / 255.0
    out = c[..., :3].astype(np.float32) * a + bg * (1.0 - a)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def _unpremultiply(premult: np.ndarray, background) -> np.ndarray:
    """Premultiplied (H, W, 4) uint8 -> straight alpha; background RGB where alpha is 0."""
    out = np.array(premult)  # contiguous copy
    a = out[..., 3]
    zero = a == 0
    if zero.any():
        out[zero, :3] = np.rint(np.asarray(background[:3]) * 255).astype(np.uint8)
    partial = (a > 0) & (a < 255)
    if partial.any():
        px = out[partial].astype(np.float32)
        rgb = np.clip(np.rint(px[:, :3] * 255.0 / px[:, 3:4]), 0, 255)
        out[partial, :3] = rgb.astype(np.uint8)
    return out
