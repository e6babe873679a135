"""Depth of a 2D skeleton from a revolved convex hull (seed 004 §3.5, "Depth of branches").

The convex hull of the 2D skeleton, revolved around the trunk's vertical line, bounds the
plant. Each branch whose tip does not touch the 2D hull gets the depth that puts its end on the
boundary of that volume, in front (+z, toward the camera) or behind, the side chosen branch by
branch to maximise the angles between the branches' projections on the ground.
"""

from __future__ import annotations

import cv2
import numpy as np

from treeform._shared.checks import check_array, check_positive
from treeform._shared.errors import InputError
from treeform._shared.rng import as_rng
from treeform.skeleton.foliage import Skeleton2D

__all__ = ["lift_to_3d", "skeleton_hull", "revolved_radius", "touches_hull"]


def skeleton_hull(sk: Skeleton2D) -> tuple[np.ndarray, float]:
    """Convex hull (V, 2) of all skeleton points and the x of the revolution axis (pixels).

    The axis is the vertical line through the trunk's top (tree mode; for the automatic trunk
    it is the trunk itself) or through the cane's middle (vine mode).
    """
    pts = np.vstack([np.asarray(b, float) for b in sk.branches])
    hull = cv2.convexHull(pts.astype(np.float32))[:, 0, :].astype(np.float64)
    trunk = np.asarray(sk.branches[0], float)
    x_axis = float(trunk[-1, 0]) if sk.meta.get("mode", "tree") == "tree" else float(trunk[:, 0].mean())
    return hull, x_axis


def revolved_radius(hull: np.ndarray, x_axis: float, y) -> np.ndarray:
    """Radius of the revolved hull at rows ``y``: the farthest hull point of that row from the axis.

    Parameters
    ----------
    hull : ndarray, shape (V, 2)
    x_axis : float
    y : array_like, shape (Q,)

    Returns
    -------
    ndarray, shape (Q,)
        ``max(|x_left(y) - x_axis|, |x_right(y) - x_axis|)``, 0 for rows the hull misses.
    """
    y = np.atleast_1d(np.asarray(y, float))
    a, b = hull, np.roll(hull, -1, axis=0)
    y0, y1 = a[None, :, 1], b[None, :, 1]
    lo, hi = np.minimum(y0, y1), np.maximum(y0, y1)
    q = y[:, None]
    on = (q >= lo - 1e-9) & (q <= hi + 1e-9)
    dy = np.where(np.abs(y1 - y0) > 1e-12, y1 - y0, 1.0)
    t = np.clip((q - y0) / dy, 0.0, 1.0)
    x = a[None, :, 0] + t * (b[None, :, 0] - a[None, :, 0])
    flat = np.abs(y1 - y0) <= 1e-12
    d = np.where(on, np.abs(x - x_axis), 0.0)
    d_flat = np.where(on & flat, np.maximum(np.abs(a[None, :, 0] - x_axis), np.abs(b[None, :, 0] - x_axis)), 0.0)
    return np.maximum(d.max(1), d_flat.max(1)) if len(hull) else np.zeros(len(y))


def touches_hull(sk: Skeleton2D, hull: np.ndarray | None = None) -> np.ndarray:
    """(B,) bool: whether the outer half of each branch comes within max(2 px, 1 % of the hull's size) of the hull.

    The trunk (index 0) counts as touching.
    """
    if hull is None:
        hull, _ = skeleton_hull(sk)
    size = float(np.ptp(hull, axis=0).max()) if len(hull) else 0.0
    tol = max(2.0, 0.01 * size)
    h32 = hull.astype(np.float32).reshape(-1, 1, 2)
    out = np.zeros(len(sk.branches), bool)
    out[0] = True
    for i, b in enumerate(sk.branches[1:], start=1):
        b = np.asarray(b, float)
        tail = b[len(b) // 2:]
        d = [cv2.pointPolygonTest(h32, (float(x), float(y)), True) for x, y in tail]
        out[i] = min(d) <= tol
    return out


def _angle(u: np.ndarray, v: np.ndarray) -> float:
    return float(np.arccos(np.clip(u @ v / (np.linalg.norm(u) * np.linalg.norm(v)), -1.0, 1.0)))


def lift_to_3d(sk: Skeleton2D, *, base, metres_per_pixel, seed=0) -> tuple[list, list]:
    """3D polylines of a 2D skeleton, depth from the revolved hull (seed 004 §3.5).

    Parameters
    ----------
    sk : Skeleton2D
    base : (x, y)
        Pixel of the trunk's base; it becomes the origin.
    metres_per_pixel : float
        Scale of the photo at the tree.
    seed : int or numpy.random.Generator
        Breaks ties between front and back (e.g. the first free branch); same seed, same result.

    Returns
    -------
    polylines : list of ndarray, each (K_i, 3) float64
        Per branch, metres, Y up, base at the origin: ``x = (col - base_x) m``,
        ``y = (base_y - row) m``, ``z`` > 0 toward the camera.
    foliage_radius : list of ndarray, each (K_i,) float64
        ``sk.widths`` in metres.

    Notes
    -----
    Branches whose outer half touches the 2D hull (:func:`touches_hull`) end at ``z = 0``; the
    others end on the revolved volume, ``z_end = ±sqrt(R(y_tip)^2 - (x_tip - x_axis)^2)``
    (:func:`revolved_radius`), the sign chosen in branch order (parents first) to maximise
    the smallest angle between this branch's ground projection (attachment -> tip in the x-z
    plane) and those already placed. Along a branch the depth goes from its parent's depth at
    the attachment to ``z_end`` as ``sin(pi u / 2)`` of the arc-length fraction ``u`` (leaving
    the parent with a slope, arriving flat), bounded by the volume. The trunk stays at z = 0.
    """
    if not isinstance(sk, Skeleton2D):
        raise InputError(f"sk: expected a Skeleton2D, got {type(sk).__name__}")
    base = check_array(base, "base", ndim=1, dtype_kind="biuf", shape=(2,)).astype(float)
    mpp = check_positive(metres_per_pixel, "metres_per_pixel")
    rng = as_rng(seed)
    hull, x_axis = skeleton_hull(sk)
    touch = touches_hull(sk, hull)
    zs: list[np.ndarray] = []
    placed: list[np.ndarray] = []
    for i, b in enumerate(sk.branches):
        b = np.asarray(b, float)
        if i == 0 or sk.parent[i] < 0:
            zs.append(np.zeros(len(b)))
            continue
        pb = np.asarray(sk.branches[sk.parent[i]], float)
        j = int(np.argmin(((pb - b[0]) ** 2).sum(1)))
        z_att = float(zs[sk.parent[i]][j])
        if touch[i]:
            z_end = 0.0
        else:
            r = float(revolved_radius(hull, x_axis, [b[-1, 1]])[0])
            mag = float(np.sqrt(max(r * r - (b[-1, 0] - x_axis) ** 2, 0.0)))
            best, choice = -1.0, []
            for sgn in (1.0, -1.0):
                d = np.array([b[-1, 0] - b[0, 0], sgn * mag - z_att])
                if np.linalg.norm(d) < 1e-9:
                    sc = 0.0
                else:
                    others = [_angle(d, o) for o in placed]
                    sc = min(others) if others else np.pi
                if sc > best + 1e-9:
                    best, choice = sc, [sgn]
                elif abs(sc - best) <= 1e-9:
                    choice.append(sgn)
            sgn = choice[0] if len(choice) == 1 else (1.0 if rng.random() < 0.5 else -1.0)
            z_end = sgn * mag
        seg = np.hypot(*np.diff(b, axis=0).T)
        cum = np.concatenate([[0.0], np.cumsum(seg)])
        u = cum / cum[-1] if cum[-1] > 0 else np.linspace(0, 1, len(b))
        z = z_att + (z_end - z_att) * np.sin(0.5 * np.pi * u)
        bound = np.sqrt(np.maximum(revolved_radius(hull, x_axis, b[:, 1]) ** 2 - (b[:, 0] - x_axis) ** 2, 0.0))
        lim = np.maximum(bound, abs(z_att))
        z = np.clip(z, -lim, lim)
        z[-1] = z_end
        zs.append(z)
        d = np.array([b[-1, 0] - b[0, 0], z_end - z_att])
        if np.linalg.norm(d) > 1e-9:
            placed.append(d)
    polys, radii = [], []
    for b, z, w in zip(sk.branches, zs, sk.widths):
        b = np.asarray(b, float)
        polys.append(np.stack([(b[:, 0] - base[0]) * mpp, (base[1] - b[:, 1]) * mpp, z * mpp], axis=1))
        radii.append(np.asarray(w, float) * mpp)
    return polys, radii
