"""2D skeleton of a foliage silhouette (seed 004 §3.3–3.5).

:func:`foliage_skeleton` partitions the silhouette with cuts into one area per first-order
branch, recomputes the generalized force field with the cuts as artificial contour points, and
fits one Catmull-Rom branch per area through the attracting points (smallest force on each
scan line). For trees (§3.5) the cuts end on the trunk line and each first-order area is split
again around its branch for the next order. All the work happens on the mask reduced to a
working size (long side ``max_side``); the results are in the input's pixels ``(x, y)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from dataclasses import field as dc_field

import cv2
import numpy as np
from scipy import ndimage as ndi

from treeform._shared.checks import check_array, check_choice, check_int, check_positive
from treeform._shared.errors import InputError, NoTreeFoundError
from treeform._shared.rng import as_rng
from treeform.skeleton.cuts import polyline_arc
from treeform.skeleton.field import check_mask, work_scale
from treeform.skeleton.levels import (N_CANDIDATES, N_SAMPLES, arc_at_height, main_component, resample,
                                      split_around_axis, split_vine, sub_polyline)

__all__ = ["Skeleton2D", "foliage_skeleton", "MIN_PIXELS"]

MIN_PIXELS = 64
"""Fewest mask pixels (at the input size) accepted as a tree."""



@dataclass
class Skeleton2D:
    """A 2D branching skeleton in the pixels of the mask it came from (seed 004 §3.4–3.5).

    Attributes
    ----------
    shape : tuple
        ``(H, W)`` of the mask.
    branches : list of ndarray, each (K_i, 2) float64
        Polylines ``(x, y)`` (column, row), each from its attachment point to its tip.
        Index 0 is the trunk (trees) or the cane (vines).
    widths : list of ndarray, each (K_i,) float64
        Foliage half-width in pixels at each polyline point (0 along the trunk).
    order : ndarray, shape (B,), int32
        0 trunk, 1 first order, 2 second order, ...
    parent : ndarray, shape (B,), int64
        Parent branch index, -1 for the trunk; parents come before their children.
    cuts : list of ((x0, y0), (x1, y1))
        First-order cuts, starting point then ending point.
    partition : ndarray, shape (H, W), int32
        First-order area of each mask pixel (0..n-1), -1 outside the mask;
        ``meta["area_branch"][a]`` is the branch of area ``a`` (-1 if it got none).
    field : ndarray, shape (H, W, 2) or None
        The final first-order force field (seed 004 eq. (1) with the cuts), for figures.
    meta : dict
        JSON-serialisable details: mode, parameters, ``dce_polygon``, ``ending_points``,
        ``cut_tries`` / ``cut_accepted``, ``sub_cuts``, ``crown_bottom``, ...
    """

    shape: tuple
    branches: list
    widths: list
    order: np.ndarray
    parent: np.ndarray
    cuts: list
    partition: np.ndarray
    field: np.ndarray | None = None
    meta: dict = dc_field(default_factory=dict)

    @property
    def n_branches(self) -> int:
        """Number of polylines (trunk included)."""
        return len(self.branches)

    def to_dict(self) -> dict:
        """JSON-ready dict: shape, branches, widths, order, parent, cuts, meta (no partition / field)."""
        return {
            "shape": [int(v) for v in self.shape],
            "branches": [np.asarray(b, float).round(3).tolist() for b in self.branches],
            "widths": [np.asarray(w, float).round(3).tolist() for w in self.widths],
            "order": [int(v) for v in self.order],
            "parent": [int(v) for v in self.parent],
            "cuts": [[[float(a), float(b)] for a, b in cut] for cut in self.cuts],
            "meta": self.meta,
        }


JOIN_SHARE = 0.9
"""Tree mode with a given trunk: when the crown's largest part holds less than this share of it, the parts are
joined along the trunk line first. On the 14 library cut-outs (exact alpha) the abs route on a birch went 47 -> 32 %
error, another birch 49 -> 39 %, a willow 37 -> 30 %, and the crowns in one piece (every isolated photo) do not change."""

JOIN_WIDTH = 0.02
"""Width of that joining line, as a share of the working width."""


# ----------------------------------------------------------------------------- public

def foliage_skeleton(mask, *, n_branches: int = 5, mode: str = "tree", tau: float = 0.15, trunk=None,
                     levels: int = 2, n_sub: int = 3, max_side: int = 160, seed=0,
                     angle_tolerance: float = 22.5, max_tries: int = 48) -> Skeleton2D:
    """2D skeleton of a foliage silhouette with ``n_branches`` first-order branches (seed 004 §3.3–3.5).

    Parameters
    ----------
    mask : array_like, shape (H, W), bool
        Tree / foliage silhouette (non-zero = inside). Its largest 8-connected part, holes
        filled, is skeletonised; every mask pixel still gets a partition label. In tree mode
        with a ``trunk``, a crown in pieces (its largest under :data:`JOIN_SHARE` of it) is
        first joined along the trunk line, so tufts up a stem belong to the tree.
    n_branches : int
        Number n of first-order branches, i.e. of areas, made by n - 1 cuts (1..64).
    mode : {"tree", "vine"}
        "vine": §3.3 as is: ending points uniformly along the bottom of the shape, a cut from
        starting point c to ending point e_i accepted when
        ``|#pixels left of (e_i c) / #pixels - i / n| <= tau`` (eq. (2)), rows as scan lines,
        first order only (``levels`` ignored), index 0 the cane along the bottom.
        "tree": §3.5: ending points on the trunk line at heights ``i / n`` of the crown
        (from the crown's bottom, the lowest row at least 30 % as wide as the widest, to its
        top), cut accepted when its angle to the trunk is within ``angle_tolerance`` of
        ``pi/2 - h (pi/2 - pi/6)`` (h = i / n); the trunk segment from the base up to the
        highest ending point is an artificial contour too, and the area above it holds the
        leader (a first-order branch attached at the trunk's top). Recursion: each
        first-order area is split the same way around its branch, with ``n_sub`` cuts along
        it, giving ``n_sub`` branches of the next order (the area around the parent's tip is
        left to the parent), for ``levels`` orders in all.
    tau : float
        Balance tolerance of eq. (2) (vines), in (0, 1].
    trunk : array_like, shape (K, 2), optional
        Trunk polyline ``(x, y)`` from the base upward; prolonged vertically to the top of
        the mask if it stops lower. None: the vertical line through the centre of the lowest
        mask pixels, from the lowest mask row up. In vine mode: the cane the branches attach to.
    levels : int
        Branch orders to extract (tree mode): 1 = first order only, 2 (default) or 3.
    n_sub : int
        Branches of the next order per area (tree mode, ``levels >= 2``).
    max_side : int
        Long side of the working size (32..4096).
    seed : int or numpy.random.Generator
        Draws of the starting points; same mask and seed give the same skeleton.
    angle_tolerance : float
        Tolerance of the tree mode's angle test, in degrees (0 < . <= 180).
    max_tries : int
        Starting points drawn per cut before the best-scoring one is taken.

    Returns
    -------
    Skeleton2D
        Branch 0 is the trunk (cane), then the first-order branches (vines: left to right;
        trees: by attachment height, the leader last), then the higher orders grouped by
        parent. A first-order area too small to hold a branch gets none, so there may be
        fewer than ``n_branches``.

    Raises
    ------
    InputError
        ``mask`` is not a 2-D array, or an option is out of range.
    NoTreeFoundError
        The mask is empty or has fewer than :data:`MIN_PIXELS` pixels (or too few at the
        working size).

    Notes
    -----
    Deviations made explicit: a drawn starting point is paired with the free ending point
    that scores best (not a random one); after ``max_tries`` draws the best-scoring cut is
    kept; cuts that cross an earlier cut or the axis are never accepted; tree areas are
    scanned perpendicular to the direction from their attachment to their centroid.
    """
    m = check_mask(mask)
    n = check_int(n_branches, "n_branches", 1, 64)
    mode = check_choice(mode, "mode", ("tree", "vine"))
    tau = check_positive(tau, "tau")
    if tau > 1.0:
        raise InputError(f"tau: expected a number in (0, 1], got {tau!r}")
    levels = check_int(levels, "levels", 1, 3)
    n_sub = check_int(n_sub, "n_sub", 1, 16)
    max_side = check_int(max_side, "max_side", 32, 4096)
    max_tries = check_int(max_tries, "max_tries", 1, 10000)
    angle_tolerance = check_positive(angle_tolerance, "angle_tolerance")
    if angle_tolerance > 180.0:
        raise InputError(f"angle_tolerance: expected degrees in (0, 180], got {angle_tolerance!r}")
    H, W = m.shape
    if trunk is not None:
        trunk = check_array(trunk, "trunk", ndim=2, dtype_kind="biuf", shape=(None, 2), min_size=2).astype(float)
    count_px = int(m.sum())
    if count_px == 0:
        raise NoTreeFoundError("mask: empty (no tree pixel)")
    if count_px < MIN_PIXELS:
        raise NoTreeFoundError(f"mask: only {count_px} tree pixels, need at least {MIN_PIXELS}")
    rng = as_rng(seed)

    h, w = work_scale((H, W), max_side)
    sx, sy = w / W, h / H
    scale = np.array([sx, sy])
    mw = m if (h, w) == (H, W) else cv2.resize(m.astype(np.float32), (w, h), interpolation=cv2.INTER_AREA) >= 0.5
    # a light Gaussian smoothing (sigma 1 working pixel) of the silhouette removes the 1-2 pixel
    # ragged bumps where the field has spurious zeros
    smooth = cv2.GaussianBlur(mw.astype(np.float32), (0, 0), 1.0) >= 0.5
    shape = main_component(smooth)

    def to_work(p):
        return (np.asarray(p, float) + 0.5) * scale - 0.5

    if mode == "tree" and trunk is not None and shape.sum() < JOIN_SHARE * ndi.binary_fill_holes(smooth).sum():
        # a crown in pieces along its stem (a birch's tufts, a willow's curtains) is one tree: the
        # trunk line, prolonged to the top, joins them before the largest part is taken
        line = to_work(trunk)
        top = float(np.flatnonzero(smooth.any(1))[0])
        if line[-1, 1] > top:
            line = np.vstack([line, [line[-1, 0], top]])
        bridge = np.zeros((h, w), np.uint8)
        cv2.polylines(bridge, [np.round(line).astype(np.int32).reshape(-1, 1, 2)], False, 1,
                      thickness=max(1, int(round(JOIN_WIDTH * w))))
        shape = main_component(smooth | (bridge > 0))
    if shape.sum() < 30:
        raise NoTreeFoundError(f"mask: too small at the working size ({int(shape.sum())} pixels of {h}x{w})")

    def to_full(p):
        return (np.asarray(p, float) + 0.5) / scale - 0.5

    ctx = {"rng": rng, "angle_tol": np.deg2rad(angle_tolerance), "max_tries": max_tries, "arc_fn": None}
    ys, xs = np.nonzero(shape)
    y_top = int(ys.min())
    meta = {"mode": mode, "n_branches": n, "tau": tau, "angle_tolerance": angle_tolerance,
            "levels": levels if mode == "tree" else 1, "n_sub": n_sub, "max_side": max_side, "max_tries": max_tries,
            "seed": int(seed) if isinstance(seed, (int, np.integer)) else None,
            "work_shape": [h, w], "scale": [float(sx), float(sy)], "trunk_auto": trunk is None}

    if mode == "tree":
        if trunk is None:
            fy, fx = np.nonzero(m)
            keep = shape[np.clip((fy * sy).astype(int), 0, h - 1), np.clip((fx * sx).astype(int), 0, w - 1)]
            fy, fx = (fy[keep], fx[keep]) if keep.any() else (fy, fx)
            yb = fy.max()
            band = fy >= yb - max(1.0, 0.01 * (yb - fy.min()))
            base_full = np.array([fx[band].mean(), float(yb)])
            bw = to_work(base_full)
            axis = np.array([bw, [bw[0], y_top]])
        else:
            axis = to_work(trunk)
            if axis[-1, 1] > y_top + 0.5:
                axis = np.vstack([axis, [axis[-1, 0], y_top]])
        widths_r = shape.sum(1)
        y_cb = int(np.flatnonzero(widths_r >= 0.3 * widths_r.max()).max())
        crown = shape.copy()
        crown[y_cb + 1:] = False
        crown = main_component(crown)
        ctx["arc_fn"] = lambda hf: arc_at_height(axis, y_cb - hf * (y_cb - y_top))
        lvl = split_around_axis(crown, axis, n - 1, ctx=ctx, keep_tip=True, n_candidates=N_CANDIDATES[0], order=1)
        ctx["arc_fn"] = None
        trunk_poly = resample(sub_polyline(axis, lvl["top_arc"]), N_SAMPLES[0])
        meta["crown_bottom"] = float(to_full(np.array([0.0, y_cb]))[1])
    else:
        cane = None if trunk is None else to_work(trunk)
        lvl = split_vine(shape, cane, n, ctx=ctx, tau=tau)
        trunk_poly = lvl["cane"]

    # ---- assemble: trunk, first order, then higher orders (breadth first)
    wscale = 1.0 / float(np.sqrt(sx * sy))
    branches_w = [trunk_poly]
    widths = [np.zeros(len(trunk_poly))]
    order, parent = [0], [-1]
    area_branch_idx = []
    queue = []
    for p, br in lvl["branches"]:
        if br is None:
            area_branch_idx.append(-1)
            continue
        area_branch_idx.append(len(branches_w))
        queue.append((lvl["filled"] == p, br["polyline"], len(branches_w), 1))
        branches_w.append(br["polyline"])
        widths.append(br["width"] * wscale)
        order.append(1)
        parent.append(0)
    sub_cuts = []
    while mode == "tree" and queue:
        area_mask, axis_b, idx, o = queue.pop(0)
        if o >= levels:
            continue
        ys_a, xs_a = np.nonzero(area_mask)
        if len(xs_a) < 40 or polyline_arc(axis_b)[-1] < 4.0:
            continue
        y0, y1 = max(ys_a.min() - 2, 0), min(ys_a.max() + 3, h)
        x0, x1 = max(xs_a.min() - 2, 0), min(xs_a.max() + 3, w)
        off = np.array([x0, y0], float)
        sub = main_component(area_mask[y0:y1, x0:x1])
        res = split_around_axis(sub, axis_b - off, n_sub, ctx=ctx, keep_tip=False, n_candidates=N_CANDIDATES[1],
                                 order=o + 1)
        sub_cuts += [[to_full(c + off).tolist(), to_full(e + off).tolist()] for c, e, _ in res["sel"]["cuts"]]
        for p, br in res["branches"]:
            if br is None:
                continue
            full_mask = np.zeros((h, w), bool)
            full_mask[y0:y1, x0:x1] = res["filled"] == p
            queue.append((full_mask, br["polyline"] + off, len(branches_w), o + 1))
            branches_w.append(br["polyline"] + off)
            widths.append(br["width"] * wscale)
            order.append(o + 1)
            parent.append(idx)

    # a spline may bridge a concavity of the silhouette: bring such points back inside, first at
    # the working size (nearest pixel of the smoothed shape), then at the input size (nearby pixel)
    _, (iy, ix) = ndi.distance_transform_edt(~shape, return_indices=True)
    branches = [np.clip(to_full(branches_w[0]), 0, [W - 1, H - 1])]  # the trunk stays as placed
    for b in branches_w[1:]:
        ij = np.clip(np.round(b).astype(int), 0, [w - 1, h - 1])
        out = ~shape[ij[:, 1], ij[:, 0]]
        b = b.copy()
        b[out] = np.stack([ix[ij[out, 1], ij[out, 0]], iy[ij[out, 1], ij[out, 0]]], axis=1)
        branches.append(_snap_inside(to_full(b), m))

    # ---- partition at the input size (every mask pixel: nearest first-order area)
    rank = np.full(lvl["count"] + 1, -1, np.int32)
    rank[np.asarray(lvl["area_order"], int)] = np.arange(len(lvl["area_order"]), dtype=np.int32)
    lab_w = rank[lvl["filled"]]
    if (lab_w >= 0).any():
        _, (iy, ix) = ndi.distance_transform_edt(lab_w < 0, return_indices=True)
        lab_w = lab_w[iy, ix]
    ry = np.minimum((np.arange(H) * sy).astype(int), h - 1)
    rx = np.minimum((np.arange(W) * sx).astype(int), w - 1)
    partition = lab_w[ry[:, None], rx[None, :]].astype(np.int32)
    partition[~m] = -1

    f = lvl["field"]
    if (h, w) != (H, W):
        f = cv2.resize(f.astype(np.float32), (W, H), interpolation=cv2.INTER_LINEAR).astype(np.float64)
        f *= float(np.sqrt(sx * sy))
    f[~m] = 0.0

    cuts = [(tuple(map(float, to_full(c))), tuple(map(float, to_full(e)))) for c, e, _ in lvl["sel"]["cuts"]]
    b = lvl["boundary"]
    meta.update({
        "n_first_order": int(sum(1 for o in order if o == 1)),
        "dce_polygon": [] if b is None else to_full(b.polygon).round(2).tolist(),
        "inward_vertices": [] if b is None else to_full(b.inward).round(2).tolist(),
        "ending_points": to_full(lvl["ends"]).round(2).tolist() if len(lvl["ends"]) else [],
        "cut_tries": [int(t) for t in lvl["sel"]["tries"]],
        "cut_accepted": [bool(a) for a in lvl["sel"]["accepted"]],
        "cut_scores": [float(s) for s in lvl["sel"]["scores"]],
        "sub_cuts": sub_cuts,
        "area_branch": [int(i) for i in area_branch_idx],
    })
    return Skeleton2D(shape=(H, W), branches=branches, widths=[np.asarray(x, float) for x in widths],
                      order=np.asarray(order, np.int32), parent=np.asarray(parent, np.int64), cuts=cuts,
                      partition=partition, field=f, meta=meta)


def _snap_inside(poly: np.ndarray, mask: np.ndarray) -> np.ndarray:
    """Clip a polyline to the image and move its points outside ``mask`` to the nearest mask pixel nearby."""
    H, W = mask.shape
    out = poly.copy()
    out[:, 0] = np.clip(out[:, 0], 0, W - 1)
    out[:, 1] = np.clip(out[:, 1], 0, H - 1)
    ij = np.round(out).astype(int)
    bad = np.flatnonzero(~mask[ij[:, 1], ij[:, 0]])
    r = max(4, int(np.ceil(3 * max(H, W) / 160)))
    for k in bad:
        x, y = ij[k]
        ya, yb, xa, xb = max(y - r, 0), min(y + r + 1, H), max(x - r, 0), min(x + r + 1, W)
        wy, wx = np.nonzero(mask[ya:yb, xa:xb])
        if len(wx):
            j = int(np.argmin((wx + xa - out[k, 0]) ** 2 + (wy + ya - out[k, 1]) ** 2))
            out[k] = (wx[j] + xa, wy[j] + ya)
    return out
