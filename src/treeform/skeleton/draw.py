"""Overlay of a 2D skeleton on its photo or mask (figures of seed 004 §3, Fig. 4, 6, 7)."""

from __future__ import annotations

import cv2
import numpy as np

from treeform._shared.checks import check_array
from treeform._shared.errors import InputError
from treeform.skeleton.foliage import Skeleton2D

__all__ = ["draw_skeleton", "PALETTE", "ORDER_COLOURS"]

PALETTE = np.array([(230, 25, 75), (60, 180, 75), (0, 130, 200), (245, 130, 48), (145, 30, 180), (70, 240, 240),
                    (240, 50, 230), (210, 245, 60), (250, 190, 212), (0, 128, 128), (220, 190, 255), (170, 110, 40)],
                   np.float64)
"""RGB tints of the partition's areas (cycled)."""

ORDER_COLOURS = {0: (120, 60, 20), 1: (255, 30, 30), 2: (255, 200, 0), 3: (255, 255, 255)}
"""RGB colour of a branch by its order (trunk brown, first order red, second yellow, third white)."""


def _as_rgb(image, shape) -> np.ndarray:
    img = check_array(image, "image", ndim=(2, 3), dtype_kind="biuf")
    if img.shape[:2] != tuple(shape):
        raise InputError(f"image: expected size {tuple(shape)} (the skeleton's mask), got {img.shape[:2]}")
    if img.ndim == 3 and img.shape[2] not in (3, 4):
        raise InputError(f"image: expected 3 or 4 channels, got {img.shape[2]}")
    if img.dtype == bool:
        img = img.astype(np.float64)
    if img.dtype.kind == "f":
        img = np.clip(img * (255.0 if img.max() <= 1.0 else 1.0), 0, 255)
    img = img.astype(np.uint8)
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=2)
    return np.ascontiguousarray(img[..., :3])


def draw_skeleton(image, sk: Skeleton2D, *, show_cuts: bool = True, show_partition: bool = True) -> np.ndarray:
    """Draw a :class:`Skeleton2D` over a photo or mask.

    Parameters
    ----------
    image : array_like, shape (H, W) or (H, W, 3|4)
        Mask (bool / 0..1 / 0..255) or RGB photo at the skeleton's size ``sk.shape``.
    sk : Skeleton2D
    show_cuts : bool
        Draw the first-order cuts (white) and the higher-order cuts (grey), and the ending points.
    show_partition : bool
        Tint each first-order area (:data:`PALETTE`, 40 % opacity).

    Returns
    -------
    ndarray, shape (H, W, 3), uint8
        The overlay; branches coloured by order (:data:`ORDER_COLOURS`), thicker for lower orders.

    Raises
    ------
    InputError
        ``image`` is not an image of the skeleton's size, or ``sk`` is not a Skeleton2D.
    """
    if not isinstance(sk, Skeleton2D):
        raise InputError(f"sk: expected a Skeleton2D, got {type(sk).__name__}")
    out = _as_rgb(image, sk.shape).astype(np.float64)
    H, W = sk.shape
    if show_partition and sk.partition is not None:
        lab = np.asarray(sk.partition)
        inside = lab >= 0
        tint = PALETTE[lab[inside] % len(PALETTE)]
        out[inside] = 0.6 * out[inside] + 0.4 * tint
    out = np.ascontiguousarray(np.clip(out, 0, 255).astype(np.uint8))
    th = max(1, int(round(max(H, W) / 300)))

    def pts(p):
        return (np.round(np.asarray(p, float) * 16).astype(np.int32)).reshape(-1, 1, 2)

    if show_cuts:
        for c0, c1 in sk.meta.get("sub_cuts", []):
            cv2.polylines(out, [pts([c0, c1])], False, (150, 150, 150), th, cv2.LINE_AA, shift=4)
        for c0, c1 in sk.cuts:
            cv2.polylines(out, [pts([c0, c1])], False, (255, 255, 255), th + 1, cv2.LINE_AA, shift=4)
        for e in sk.meta.get("ending_points", []):
            cv2.circle(out, tuple(int(round(v)) for v in e), 2 * th + 1, (0, 90, 255), -1, cv2.LINE_AA)
    for b, o in sorted(zip(sk.branches, sk.order), key=lambda z: -int(z[1])):
        col = ORDER_COLOURS.get(int(o), (255, 255, 255))
        cv2.polylines(out, [pts(b)], False, col, max(1, th * (3 - min(int(o), 2))), cv2.LINE_AA, shift=4)
    return out
