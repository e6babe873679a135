"""One level of the recursive split (seed 004 §3.3–3.5): cuts, areas, field, one branch per area.

:func:`split_around_axis` (trees, §3.5: ending points on an axis, the angle test) and
:func:`split_vine` (vines, §3.3: ending points on the bottom, the balance test (2)) work on one
shape at the working size and return its cuts, areas, field and branches in working pixels.
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy import ndimage as ndi

from treeform.skeleton.branches import area_branch, attachment_on_axis
from treeform.skeleton.cuts import (boundary_candidates, label_areas, point_at_arc, polyline_arc, rasterise,
                                    select_cuts)
from treeform.skeleton.field import contour_pixels, source_field

__all__ = ["split_around_axis", "split_vine", "N_CANDIDATES", "N_SAMPLES"]

N_CANDIDATES = (120, 64)
"""Candidate starting points on the DCE polygon: first order, higher orders."""

N_SAMPLES = (12, 20, 12, 8)
"""Polyline points per branch order (trunk, 1, 2, 3)."""


# ----------------------------------------------------------------------------- helpers

def main_component(mask: np.ndarray) -> np.ndarray:
    """Largest 8-connected part of ``mask`` with its holes filled."""
    n, lab, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    if n <= 1:
        return np.zeros_like(mask, bool)
    j = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
    return ndi.binary_fill_holes(lab == j)


def sub_polyline(poly: np.ndarray, s_end: float) -> np.ndarray:
    """The part of an open polyline from its start to arc position ``s_end``."""
    cum = polyline_arc(poly)
    s_end = float(np.clip(s_end, 0.0, cum[-1]))
    keep = poly[cum < s_end - 1e-9]
    end, _ = point_at_arc(poly, s_end)
    out = np.vstack([keep, end[None, :]])
    return out if len(out) >= 2 else np.vstack([poly[:1], end[None, :]])


def resample(poly: np.ndarray, count: int) -> np.ndarray:
    cum = polyline_arc(poly)
    if cum[-1] <= 0:
        return np.repeat(poly[:1], count, axis=0)
    pts, _ = point_at_arc(poly, np.linspace(0.0, cum[-1], count))
    return pts


def arc_at_height(axis: np.ndarray, y: float) -> float:
    """Arc position where ``axis`` (base first, going up) first reaches row ``y``."""
    cum = polyline_arc(axis)
    s = np.arange(0.0, cum[-1] + 0.25, 0.25)
    pts, _ = point_at_arc(axis, s)
    hit = np.flatnonzero(pts[:, 1] <= y)
    return float(s[hit[0]] if len(hit) else s[-1])


def _nearest_on(poly: np.ndarray, p: np.ndarray) -> float:
    """Arc position on ``poly`` nearest to point ``p``."""
    cum = polyline_arc(poly)
    s = np.arange(0.0, cum[-1] + 0.25, 0.25)
    pts, _ = point_at_arc(poly, s)
    return float(s[np.argmin(((pts - p) ** 2).sum(1))])


def _label_at(filled: np.ndarray, p: np.ndarray) -> int:
    """Area label at point ``p`` (the nearest labelled pixel when ``p`` has none)."""
    h, w = filled.shape
    x, y = int(np.clip(round(p[0]), 0, w - 1)), int(np.clip(round(p[1]), 0, h - 1))
    if filled[y, x] >= 0:
        return int(filled[y, x])
    ys, xs = np.nonzero(filled >= 0)
    if len(xs) == 0:
        return -1
    k = int(np.argmin((xs - x) ** 2 + (ys - y) ** 2))
    return int(filled[ys[k], xs[k]])


def _angle_score(ends: np.ndarray, tangents: np.ndarray, targets: np.ndarray, min_len: float):
    """Angle error of a cut from ``c`` to ``ends[i]`` against ``targets[i]`` (seed 004 §3.5)."""
    def score(c, i):
        v = c - ends[i]
        n = float(np.hypot(v[0], v[1]))
        if n < min_len:
            return np.inf
        th = float(np.arccos(np.clip((v @ tangents[i]) / n, -1.0, 1.0)))
        return abs(th - targets[i])
    return score


def _angle_targets(n_cuts: int) -> tuple[np.ndarray, np.ndarray]:
    """Height fractions ``h_i = i / (n_cuts + 1)`` and the angle wanted between cut and axis:
    pi/2 at the bottom, pi/6 at the top, linear in between (seed 004 §3.5)."""
    h = np.arange(1, n_cuts + 1) / (n_cuts + 1)
    return h, np.pi / 2 - h * (np.pi / 2 - np.pi / 6)


def _segments(poly: np.ndarray) -> np.ndarray:
    return np.stack([poly[:-1], poly[1:]], axis=1) if len(poly) >= 2 else np.zeros((0, 2, 2))


def _field_of(shape_mask: np.ndarray, sep: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Seed 004 eq. (1) with P = 1 on the separators and on the contour, 0 elsewhere.

    Returns the field (h, w, 2) and the magnitude used to find attracting points, +inf on and
    next to the sources: the field is only meaningful strictly inside (on a straight piece of
    contour the contour's own pull cancels, which would make contour pixels look "attracting").
    """
    src = contour_pixels(shape_mask) | (sep & shape_mask)
    f = source_field(src.astype(np.float64), shape_mask)
    mag = np.hypot(f[..., 0], f[..., 1])
    near = cv2.dilate(src.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    mag[near | ~shape_mask] = np.inf
    return f, mag


# ----------------------------------------------------------------------------- levels

def split_around_axis(shape_mask, axis, n_cuts, *, ctx, keep_tip: bool, n_candidates: int, order: int):
    """Split one shape around an axis (trunk or parent branch) and fit one branch per area.

    Returns a dict with the cuts, the labels, the field and the branches (working pixels,
    in the coordinates of ``shape_mask``); the area holding the axis' end is the leader
    (``keep_tip``) or is left to the parent branch (higher orders).
    """
    h_, targets = _angle_targets(n_cuts)
    cum = polyline_arc(axis)
    if ctx["arc_fn"] is not None:  # trunk: ending points spread over the crown's height
        arcs = np.array([ctx["arc_fn"](hf) for hf in h_]) if n_cuts else np.zeros(0)
        base_arc = ctx["arc_fn"](0.0)
    else:
        arcs = cum[-1] * h_
        base_arc = 0.0
    ends, tangents = point_at_arc(axis, arcs) if n_cuts else (np.zeros((0, 2)), np.zeros((0, 2)))
    b = boundary_candidates(shape_mask, 2 * (n_cuts + 1), n_candidates) if n_cuts else None
    sel = {"cuts": [], "tries": [], "accepted": [], "scores": []}
    if b is not None:
        sel = select_cuts(b, ends, _angle_score(ends, tangents, targets, 3.0), tol=ctx["angle_tol"],
                          rng=ctx["rng"], max_tries=ctx["max_tries"], blockers=_segments(axis))
    top_arc = float(arcs[-1]) if n_cuts else base_arc
    sep_axis = sub_polyline(axis, top_arc)
    sep = rasterise(shape_mask.shape, sel["cuts"], axis=sep_axis, extend_start=2.0)
    f, mag = _field_of(shape_mask, sep)
    n_areas = n_cuts + 1
    areas, filled, count = label_areas(shape_mask, sep, n_areas)
    # the leader / tip area: the one just beyond the axis' separator part
    if keep_tip:
        tip_pt, tip_t = point_at_arc(axis, top_arc)
        tip_label = _label_at(filled, tip_pt + 2.0 * tip_t)
    else:
        tip_label = _label_at(filled, axis[-1])
    attach = attachment_on_axis(areas, sep_axis, count)
    sep_len = polyline_arc(sep_axis)[-1]
    items = []
    for p in range(count):
        if p == tip_label:
            if not keep_tip:
                continue
            s = sep_len + 1.0  # sorts last
            a, _ = point_at_arc(sep_axis, sep_len)
        else:
            s = attach[p]
            if s is None:
                ys, xs = np.nonzero(areas == p)
                s = _nearest_on(sep_axis, np.array([xs.mean(), ys.mean()]))
            a, _ = point_at_arc(sep_axis, s)
        items.append((s, p, a))
    items.sort(key=lambda z: z[0])
    branches = []
    for s, p, a in items:
        br = area_branch(areas == p, mag, a, None, N_SAMPLES[min(order, 3)], max_ctrl=6 if order == 1 else 4)
        branches.append((p, br))
    return {"boundary": b, "sel": sel, "ends": ends, "sep": sep, "field": f, "areas": areas, "filled": filled,
            "count": count, "branches": branches, "area_order": [p for _, p, _ in items], "top_arc": top_arc}


def split_vine(shape_mask, cane, n, *, ctx, tau: float):
    """Seed 004 §3.3 as is: ending points on the bottom, area-balance test (2), rows as scan lines."""
    ys, xs = np.nonzero(shape_mask)
    y0, y1 = ys.min(), ys.max()
    band = ys >= y1 - 0.15 * (y1 - y0)
    xl, xr = np.percentile(xs[band], [2.0, 98.0])
    low = np.full(shape_mask.shape[1], -1)
    np.maximum.at(low, xs, ys)

    def bottom(x):
        c = int(np.clip(round(x), 0, len(low) - 1))
        return float(low[c] if low[c] >= 0 else y1)

    ends = np.array([[xl + i / n * (xr - xl), 0.0] for i in range(1, n)]).reshape(-1, 2)
    ends[:, 1] = [bottom(x) for x in ends[:, 0]]
    if cane is None:
        cx = np.linspace(xl, xr, 9)
        cane = np.stack([cx, ndi.median_filter(np.array([bottom(x) for x in cx]), 3, mode="nearest")], axis=1)
    px, py = xs.astype(np.float64), ys.astype(np.float64)

    def score(c, i):
        d = c - ends[i]
        if abs(d[1]) < 1e-9 or np.hypot(*d) < 3.0:
            return np.inf
        cross = d[0] * (py - ends[i, 1]) - d[1] * (px - ends[i, 0])
        frac = float(np.mean(cross * np.sign(d[1]) > 0))
        return abs(frac - (i + 1) / n)

    b = boundary_candidates(shape_mask, 2 * n, N_CANDIDATES[0]) if n > 1 else None
    sel = {"cuts": [], "tries": [], "accepted": [], "scores": []}
    if b is not None:
        sel = select_cuts(b, ends, score, tol=tau, rng=ctx["rng"], max_tries=ctx["max_tries"])
    sep = rasterise(shape_mask.shape, sel["cuts"], extend_start=2.0, extend_end=2.0)
    f, mag = _field_of(shape_mask, sep)
    areas, filled, count = label_areas(shape_mask, sep, n)
    items = []
    for p in range(count):
        ay, ax = np.nonzero(areas == p)
        lowest = ay >= ay.max() - 1
        q = np.array([ax[lowest].mean(), float(ay.max())])
        a, _ = point_at_arc(cane, _nearest_on(cane, q))
        items.append((float(ax.mean()), p, a))
    items.sort(key=lambda z: z[0])
    branches = [(p, area_branch(areas == p, mag, a, np.array([0.0, -1.0]), N_SAMPLES[1])) for _, p, a in items]
    return {"boundary": b, "sel": sel, "ends": ends, "sep": sep, "field": f, "areas": areas, "filled": filled,
            "count": count, "branches": branches, "area_order": [p for _, p, _ in items], "cane": cane}
