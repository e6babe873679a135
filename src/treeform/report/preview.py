"""preview.png: photo | segmentation overlay | front | side | top, side by side."""

from __future__ import annotations

import numpy as np
from PIL import Image

from treeform._shared.errors import InputError
from treeform.structures.segmentation import Segmentation


def segmentation_overlay(image: np.ndarray, seg: Segmentation) -> np.ndarray:
    """Photo with background dimmed, foliage tinted green and wood tinted red.

    Returns
    -------
    ndarray, shape (H, W, 3), uint8
    """
    img = image.astype(np.float32)
    out = img * 0.35
    fol, wood = seg.foliage_mask, seg.wood_mask
    out[fol] = 0.55 * img[fol] + 0.45 * np.float32([40, 220, 60])
    out[wood] = 0.55 * img[wood] + 0.45 * np.float32([230, 50, 40])
    edge = seg.tree_mask & ~np.pad(seg.tree_mask, 1)[2:, 1:-1] | seg.tree_mask & ~np.pad(seg.tree_mask, 1)[:-2, 1:-1]
    out[edge] = (255, 255, 0)
    return np.clip(out, 0, 255).astype(np.uint8)


def compose_strip(tiles: list, *, height: int = 360, gap: int = 6, background=(255, 255, 255)) -> np.ndarray:
    """Scale every (H, W, 3) uint8 tile to ``height`` and place them left to right."""
    scaled = []
    for t in tiles:
        im = Image.fromarray(np.asarray(t)[..., :3])
        w = max(1, round(im.width * height / im.height))
        scaled.append(np.asarray(im.resize((w, height), Image.LANCZOS)))
    total = sum(s.shape[1] for s in scaled) + gap * (len(scaled) + 1)
    out = np.empty((height + 2 * gap, total, 3), np.uint8)
    out[:] = background
    x = gap
    for s in scaled:
        out[gap:gap + height, x:x + s.shape[1]] = s
        x += s.shape[1] + gap
    return out


def over_checkerboard(rgba, *, cell: int = 16) -> np.ndarray:
    """Composite an RGBA image over a grey checkerboard, so transparency shows.

    Returns
    -------
    ndarray, shape (H, W, 3), uint8
    """
    a = np.asarray(rgba)
    if a.ndim != 3 or a.shape[2] != 4:
        raise InputError(f"rgba: expected an (H, W, 4) array, got {a.shape}")
    h, w = a.shape[:2]
    yy, xx = np.mgrid[:h, :w]
    board = np.where(((yy // cell + xx // cell) % 2) == 0, 232.0, 196.0).astype(np.float32)[..., None]
    al = a[..., 3:4].astype(np.float32) / 255.0
    return np.clip(np.rint(a[..., :3] * al + board * (1.0 - al)), 0, 255).astype(np.uint8)
