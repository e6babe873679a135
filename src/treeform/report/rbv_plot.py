"""Pictures of radial bounding volumes (seed 003 §4.1, Figs. 3 and 7): top and side views.

Drawn with PIL only. The *top* view looks down the -Y axis: +X points right and +Z down
on the image, so sector angles (``atan2(z, x)``) advance clockwise on screen from the
3 o'clock direction. The *side* view looks from +Z towards -Z (treeform's photo camera): +X
right, +Y up.
"""

from __future__ import annotations

import math

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from treeform._shared.errors import InputError
from treeform.structures.rbv import RadialBoundingVolume

__all__ = ["plot_rbv", "plot_rbv_levels"]

_VIRIDIS = np.array([[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]], np.float64)
_BG = (255, 255, 255)
_GRID = (200, 200, 200)
_INK = (40, 40, 40)


def _cmap(v: float) -> tuple:
    """Viridis-like colour of ``v`` in [0, 1]."""
    v = min(max(float(v), 0.0), 1.0) * (len(_VIRIDIS) - 1)
    i = min(int(v), len(_VIRIDIS) - 2)
    f = v - i
    c = _VIRIDIS[i] * (1 - f) + _VIRIDIS[i + 1] * f
    return tuple(int(round(x)) for x in c)


def _font(px: int):
    try:
        return ImageFont.load_default(size=px)
    except TypeError:  # Pillow < 10.1
        return ImageFont.load_default()


def _scale(rbv: RadialBoundingVolume, size: int, margin: int) -> float:
    """Pixels per metre so both the top view (2 r wide) and the side view (h tall) fit."""
    r = max(rbv.radius * rbv.radial_scale, 1e-12)
    h = rbv.physical_height
    avail = size - 2 * margin
    return min(avail / (2 * r), avail / h) if r > 1e-12 else avail / h


def _top_view(rbv: RadialBoundingVolume, radii: np.ndarray, size: int, px_per_m: float, margin: int,
              rmax: float) -> Image.Image:
    im = Image.new("RGB", (size, size), _BG)
    d = ImageDraw.Draw(im)
    cx = cy = size / 2
    big = rmax * px_per_m
    d.ellipse([cx - big, cy - big, cx + big, cy + big], outline=_GRID, width=1)  # the cylinder
    edges = np.degrees(rbv.sector_edges())
    for j, r in enumerate(radii):
        rp = r * px_per_m
        if rp <= 0:
            continue
        box = [cx - rp, cy - rp, cx + rp, cy + rp]
        col = _cmap(r / rmax if rmax > 0 else 0)
        if len(radii) == 1:
            d.ellipse(box, fill=col, outline=_INK)
        else:
            d.pieslice(box, float(edges[j]), float(edges[j + 1]), fill=col, outline=_INK)
    if len(radii) > 1:
        for a in np.radians(edges[:-1]):  # sector boundaries, thin
            d.line([cx, cy, cx + big * math.cos(a), cy + big * math.sin(a)], fill=_GRID, width=1)
    d.line([cx, cy, cx + big + margin * 0.6, cy], fill=(200, 60, 60), width=1)
    d.line([cx, cy, cx, cy + big + margin * 0.6], fill=(60, 60, 200), width=1)
    f = _font(max(9, size // 24))
    d.text((min(cx + big + margin * 0.6 + 2, size - 12), cy - 6), "x", fill=(200, 60, 60), font=f)
    d.text((cx + 3, min(cy + big + margin * 0.4, size - 14)), "z", fill=(60, 60, 200), font=f)
    d.text((3, size - max(9, size // 24) - 4), f"r max {rmax:.2f} m", fill=_INK, font=f)
    return im


def _sector_reach(lo: float, hi: float) -> tuple[float, float]:
    """(max cos, max -cos) over the angle interval [lo, hi] within [0, 2π]."""
    right = 1.0 if lo <= 0.0 or hi >= 2 * math.pi else max(math.cos(lo), math.cos(hi))
    left = 1.0 if lo <= math.pi <= hi else max(-math.cos(lo), -math.cos(hi))
    return right, left


def _side_view(rbv: RadialBoundingVolume, size: int, px_per_m: float, margin: int) -> Image.Image:
    im = Image.new("RGB", (size, size), _BG)
    d = ImageDraw.Draw(im)
    cx = size / 2
    base = size - margin
    radii = rbv.physical_radii
    ye = rbv.layer_edges()
    se = rbv.sector_edges()
    reach = np.array([_sector_reach(se[j], se[j + 1]) for j in range(rbv.n_sectors)])  # (m, 2)
    rmax = max(float(radii.max()), 1e-12)
    for i in range(rbv.n_layers):
        y0, y1 = base - ye[i] * px_per_m, base - ye[i + 1] * px_per_m
        rm = radii[i].max()
        if rm <= 0:
            continue
        light = tuple(int(0.35 * c + 0.65 * 255) for c in _cmap(rm / rmax))
        d.rectangle([cx - rm * px_per_m, y1, cx + rm * px_per_m, y0], fill=light, outline=_GRID)
        # the silhouette seen from +Z: how far the sectors reach to +X and to -X
        right = float(np.max(radii[i] * reach[:, 0]))
        left = float(np.max(radii[i] * reach[:, 1]))
        if right + left > 0:
            d.rectangle([cx - left * px_per_m, y1, cx + right * px_per_m, y0], fill=_cmap(rm / rmax), outline=_INK)
    d.line([margin * 0.5, base, size - margin * 0.5, base], fill=_INK, width=1)  # ground
    d.line([cx, base, cx, base - rbv.physical_height * px_per_m], fill=(120, 70, 30), width=2)  # axis
    f = _font(max(9, size // 24))
    d.text((size - margin * 0.5 - 8, base - 14), "x", fill=(200, 60, 60), font=f)
    d.text((cx + 4, margin * 0.3), "y", fill=(60, 160, 60), font=f)
    return im


def plot_rbv(rbv: RadialBoundingVolume, *, size: int = 320, layer: int | None = None,
             title: str | None = None) -> np.ndarray:
    """Top and side view of a radial bounding volume, side by side.

    Top (left panel): every sector as a pie wedge of its radius, filled by radius (viridis,
    relative to the largest sector); the grey circle is the bounding cylinder. By default
    each sector shows its maximum over the layers (the crown's footprint); ``layer`` picks
    one layer. Side (right panel): every layer as a horizontal bar; the pale bar spans its
    maximum radius on both sides of the axis, the solid bar the silhouette seen from +Z
    (how far the layer's sectors reach towards +X and -X). Both panels share one scale in
    pixels per metre.

    Parameters
    ----------
    rbv : RadialBoundingVolume
    size : int, keyword-only
        Side of each square panel in pixels, >= 64.
    layer : int, keyword-only, optional
        Layer for the top view (0 = bottom); default the maximum over layers.
    title : str, keyword-only, optional
        Caption; default "level k (n x n)".

    Returns
    -------
    ndarray, shape (H, W, 3), uint8
        ``H = size + caption``, ``W = 2 * size``.
    """
    if not isinstance(rbv, RadialBoundingVolume):
        raise InputError(f"rbv: expected a RadialBoundingVolume, got {type(rbv).__name__}")
    if isinstance(size, bool) or not isinstance(size, (int, np.integer)) or size < 64:
        raise InputError(f"size: expected an integer >= 64, got {size!r}")
    size = int(size)
    radii = rbv.physical_radii
    if layer is None:
        top = radii.max(axis=0)
        top_label = "top (max over layers)"
    else:
        if isinstance(layer, bool) or not isinstance(layer, (int, np.integer)) or not 0 <= layer < rbv.n_layers:
            raise InputError(f"layer: expected an integer in 0..{rbv.n_layers - 1}, got {layer!r}")
        top = radii[int(layer)]
        top_label = f"top (layer {int(layer)})"
    margin = max(12, size // 12)
    s = _scale(rbv, size, margin)
    rmax = float(radii.max())
    panels = [_top_view(rbv, top, size, s, margin, rmax), _side_view(rbv, size, s, margin)]
    cap = max(14, size // 14)
    out = Image.new("RGB", (2 * size, size + cap), _BG)
    d = ImageDraw.Draw(out)
    f = _font(max(10, cap - 4))
    title = title if title is not None else f"level {rbv.level} ({rbv.n_layers} x {rbv.n_sectors})"
    d.text((4, 1), f"{title}: {top_label}", fill=_INK, font=f)
    d.text((size + 4, 1), f"side (from +Z), h = {rbv.physical_height:.2f} m", fill=_INK, font=f)
    for k, p in enumerate(panels):
        out.paste(p, (k * size, cap))
    d.line([size, cap, size, size + cap], fill=_GRID, width=1)
    return np.asarray(out, np.uint8).copy()


def plot_rbv_levels(rbv: RadialBoundingVolume, *, levels=(2, 3, 4, 5), size: int = 320) -> np.ndarray:
    """One :func:`plot_rbv` row per level (``rbv.at_level(k)``), stacked top to bottom.

    Parameters
    ----------
    rbv : RadialBoundingVolume
        Best built at the finest level shown, so every row is an exact maximum.
    levels : sequence of int, keyword-only
        Levels 1..5 to draw.
    size : int, keyword-only
        Panel side in pixels.

    Returns
    -------
    ndarray, shape (H, 2 * size, 3), uint8
    """
    if not isinstance(rbv, RadialBoundingVolume):
        raise InputError(f"rbv: expected a RadialBoundingVolume, got {type(rbv).__name__}")
    levels = list(levels)
    if not levels:
        raise InputError("levels: expected at least one level")
    rows = [plot_rbv(rbv.at_level(k), size=size) for k in levels]
    gap = 4
    out = np.full((sum(r.shape[0] for r in rows) + gap * (len(rows) - 1), rows[0].shape[1], 3), 255, np.uint8)
    y = 0
    for i, r in enumerate(rows):
        out[y:y + r.shape[0]] = r
        y += r.shape[0]
        if i < len(rows) - 1:
            out[y:y + gap] = 180
            y += gap
    return out
