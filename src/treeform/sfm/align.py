"""From COLMAP's arbitrary world to treeform's frame: up, ground, origin, metres (seed 002 §3).

SfM fixes the world only up to a similarity. Photos of a tree are taken standing, phone
upright, at eye level, on the ground around the tree; so

* **up** is the mean of the cameras' up axes (:func:`up_vector`),
* the **ground** is the plane through the lowest points along up (:func:`ground_plane`),
* the **scale** makes the median camera height above the ground 1.6 m
  (:func:`camera_height_scale`) unless the user gives a true size,

and :func:`similarity_to_frame` applies the similarity: Y up, the given origin (the tree base)
at 0, metres. :func:`to_tree_frame` chains them with defaults.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from treeform._shared.errors import InputError, SfmError
from treeform.sfm.result import SfmResult

__all__ = ["Plane", "up_vector", "ground_plane", "camera_height_scale", "frame_rotation", "similarity_to_frame",
           "to_tree_frame", "EYE_HEIGHT"]

EYE_HEIGHT = 1.6
"""Metres: the height of a phone held at eye level (the default metric scale)."""


@dataclass(frozen=True)
class Plane:
    """The plane ``normal . x = offset`` (``normal`` a unit vector, pointing up).

    Attributes
    ----------
    normal : ndarray, shape (3,)
    offset : float
    inliers : int
        Points within the RANSAC threshold of the plane.
    threshold : float
        That threshold, in world units.
    """

    normal: np.ndarray
    offset: float
    inliers: int = 0
    threshold: float = 0.0

    def height(self, points) -> np.ndarray:
        """Signed distances (N,) of points (N, 3) above the plane."""
        return np.asarray(points, np.float64).reshape(-1, 3) @ self.normal - self.offset

    def project(self, points) -> np.ndarray:
        """Points (N, 3) dropped onto the plane along the normal."""
        p = np.asarray(points, np.float64).reshape(-1, 3)
        return p - np.outer(self.height(p), self.normal)


def _unit(v, name: str = "up") -> np.ndarray:
    v = np.asarray(v, np.float64).reshape(-1)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or np.linalg.norm(v) < 1e-12:
        raise InputError(f"{name}: expected a non-zero 3-vector, got {v.tolist()}")
    return v / np.linalg.norm(v)


def up_vector(result: SfmResult) -> np.ndarray:
    """The up direction of the cameras: the direction most orthogonal to their x axes.

    A phone held upright keeps its x axis (OpenCV: right) level, however far it tilts up to
    a tall tree; so up is the least singular direction of the stacked x axes, signed like
    the mean of the cameras' -y axes. The mean -y axis itself is a biased up wherever the
    cameras do not surround the tree (on an arc their upward tilts, toward the tree, do not
    cancel: 150 degrees of a ring tilted the frame by 10 degrees); it is the answer when the
    x axes span too narrow a fan (their second singular value under half the first: cameras
    on less than about 80 degrees of a ring), where a few degrees of roll tilt the x axes'
    normal more than the pitch tilts the mean up (3 cameras on 40 degrees: 18 degrees off,
    every SfM point above the cameras).

    Returns
    -------
    ndarray, shape (3,)
        A unit vector in the world of ``result``.

    Raises
    ------
    SfmError
        No cameras, or up axes that cancel out.
    """
    if result.n_cameras == 0:
        raise SfmError("no registered cameras to find the up direction from")
    mean_up = -result.cam_to_world[:, :3, 1].mean(axis=0)
    n = np.linalg.norm(mean_up)
    if n < 1e-6:
        raise SfmError("the cameras' up directions cancel out; the up direction is undetermined")
    mean_up /= n
    x = result.cam_to_world[:, :3, 0]
    _, sv, vt = np.linalg.svd(x, full_matrices=False)
    if result.n_cameras >= 2 and sv[1] > 0.5 * sv[0]:
        up = vt[2] if vt[2] @ mean_up >= 0 else -vt[2]
        if up @ mean_up > np.cos(np.radians(45.0)):  # upright photos: anything else is not their up
            return up
    return mean_up


def _scene_scale(result: SfmResult) -> float:
    """A length typical of the scene: median distance from the cameras to the points' median."""
    c = result.centers
    ref = np.median(result.points, axis=0) if len(result.points) else c.mean(0)
    s = float(np.median(np.linalg.norm(c - ref, axis=1))) if len(c) else 0.0
    if not s > 0 and len(result.points):
        s = float(np.median(np.linalg.norm(result.points - ref, axis=1)))
    return s if s > 0 else 1.0


def ground_plane(result: SfmResult, up=None, *, lowest: float = 0.3, threshold: float | None = None,
                 max_tilt_deg: float = 30.0, below_weight: int = 2, iterations: int = 1000, seed: int = 0) -> Plane:
    """A robust plane through the lowest SfM points along ``up`` (RANSAC, seeded).

    The ground is the lowest dense surface: a sample plane scores its inliers minus
    ``below_weight`` times the points more than ``threshold`` below it, so the tops and
    sides of low objects (walls, boxes, benches) lose to the ground under them even when the
    ground, seen at a grazing angle, gives fewer points.

    Parameters
    ----------
    result : SfmResult
    up : array_like, shape (3,), optional
        Up direction; :func:`up_vector` by default.
    lowest : float
        Fraction of the points (lowest along ``up``, below the median camera) the plane is
        searched among.
    threshold : float, optional
        Inlier distance in world units; 0.5 % of the scene scale (median camera distance to
        the points' median) by default.
    max_tilt_deg : float
        Planes tilted more than this from ``up`` are rejected (walls, box sides).
    below_weight : int
        Penalty per point below a candidate plane.
    iterations : int
        RANSAC samples.
    seed : int

    Returns
    -------
    Plane
        Refined by least squares on the inliers; ``normal`` oriented along ``up``.

    Raises
    ------
    SfmError
        Fewer than 3 points below the cameras, or no plane within ``max_tilt_deg`` of up.
    """
    up = up_vector(result) if up is None else _unit(up)
    if not 0 < lowest <= 1:
        raise InputError(f"lowest: expected a fraction in (0, 1], got {lowest!r}")
    P = result.points
    h = P @ up
    cam_h = float(np.median(result.centers @ up)) if result.n_cameras else np.inf
    below = P[h < cam_h]
    if len(below) < 3:
        raise SfmError(f"cannot find the ground: only {len(below)} SfM points lie below the cameras")
    hb = below @ up
    cand = below[hb <= np.quantile(hb, lowest)] if len(below) >= 30 else below
    if len(cand) < 3:
        cand = below
    thr = 0.005 * _scene_scale(result) if threshold is None else float(threshold)
    if not thr > 0:
        raise InputError(f"threshold: expected a positive number, got {threshold!r}")
    cos_max = np.cos(np.radians(max_tilt_deg))
    rng = np.random.default_rng(seed)
    best_n, best_d, best_count = None, 0.0, -1
    for _ in range(int(iterations)):
        a, b, c = cand[rng.choice(len(cand), 3, replace=False)]
        nrm = np.cross(b - a, c - a)
        ln = np.linalg.norm(nrm)
        if ln < 1e-12:
            continue
        nrm /= ln
        if nrm @ up < 0:
            nrm = -nrm
        if nrm @ up < cos_max:
            continue
        d = float(nrm @ a)
        hc = cand @ nrm - d
        count = int((np.abs(hc) < thr).sum()) - below_weight * int((hc < -thr).sum())
        if count > best_count:
            best_n, best_d, best_count = nrm, d, count
    if best_n is None:
        raise SfmError(f"cannot find the ground: no plane within {max_tilt_deg:g} degrees of the camera up direction "
                       "through the lowest SfM points")
    inl = cand[np.abs(cand @ best_n - best_d) < thr]
    if len(inl) >= 3:  # least-squares refinement
        mu = inl.mean(0)
        nrm = np.linalg.svd(inl - mu, full_matrices=False)[2][-1]
        nrm = nrm if nrm @ up >= 0 else -nrm
        if nrm @ up >= cos_max:
            best_n, best_d = nrm, float(nrm @ mu)
    count = int((np.abs(cand @ best_n - best_d) < thr).sum())
    return Plane(best_n, best_d, count, thr)


def camera_height_scale(result: SfmResult, plane: Plane, *, eye_height: float = EYE_HEIGHT) -> float:
    """The scale that puts the median camera ``eye_height`` metres above the ground plane.

    The default metric scale when no true size is given: the photos are taken by a person
    holding a phone at eye level.

    Raises
    ------
    SfmError
        The median camera is not above the plane.
    """
    if not (np.isfinite(eye_height) and eye_height > 0):
        raise InputError(f"eye_height: expected a positive number of metres, got {eye_height!r}")
    med = float(np.median(plane.height(result.centers)))
    if not med > 0:
        raise SfmError("the cameras are not above the ground plane; the metric scale is undetermined")
    return float(eye_height) / med


def frame_rotation(result: SfmResult, up, *, reference: int = 0) -> np.ndarray:
    """The rotation taking ``up`` to +Y and camera ``reference``'s horizontal view direction to -Z.

    So that camera sits on the +Z side looking toward -Z (treeform's convention for the main
    photo). A camera looking straight along ``up`` uses its x axis as +X instead.
    """
    y = _unit(up)
    T = result.cam_to_world[reference]
    fwd = T[:3, 2] - (T[:3, 2] @ y) * y
    if np.linalg.norm(fwd) > 1e-6:
        z = -fwd / np.linalg.norm(fwd)
        x = np.cross(y, z)
    else:
        x = T[:3, 0] - (T[:3, 0] @ y) * y
        x /= np.linalg.norm(x)
        z = np.cross(x, y)
    return np.stack([x, y, z])  # rows: world axes -> new axes


def similarity_to_frame(result: SfmResult, *, origin, up, scale: float, reference: int = 0) -> SfmResult:
    """``result`` in treeform's frame: ``up`` -> +Y, ``origin`` -> 0, lengths times ``scale``.

    ``x' = scale * R (x - origin)`` with ``R`` from :func:`frame_rotation` (camera
    ``reference`` looks toward -Z). ``meta["to_frame"]`` records ``scale``, ``rotation`` and
    ``translation`` (``x' = scale * rotation @ x + translation``).
    """
    if not (np.isfinite(scale) and scale > 0):
        raise InputError(f"scale: expected a positive number, got {scale!r}")
    if result.n_cameras == 0:
        raise SfmError("no registered cameras")
    o = np.asarray(origin, np.float64).reshape(-1)
    if o.shape != (3,) or not np.all(np.isfinite(o)):
        raise InputError(f"origin: expected a finite 3-vector, got {o.tolist()}")
    R = frame_rotation(result, up, reference=reference)
    t = -float(scale) * (R @ o)
    out = result.transformed(float(scale), R, t)
    out.meta["to_frame"] = {"scale": float(scale), "rotation": np.round(R, 9).tolist(),
                            "translation": np.round(t, 9).tolist()}
    return out


MIN_GROUND_INLIERS = 50
"""Fewest SfM points on the ground plane for its normal to be the vertical (else the cameras' up)."""


SWEEP_MIN_CONTRAST = 0.04
"""A plane sweep's ground (:func:`~treeform.sfm.sweep.sweep_ground`) is used when its best depth
scores at least this much above the median depth (0.11-0.15 measured on three synthetic park
captures, each within 2.3 % of the true ground)."""

SWEEP_DEPRESSIONS = (8.0, 5.0, 3.0)
"""Least depressions (degrees below the horizon) of the pixels the plane sweep compares, tried in
turn until one sweep's ground stands out (:data:`SWEEP_MIN_CONTRAST`). The steep, near ground moves
most between neighbouring photos, but a phone tilted up to frame a tall tree leaves little of it in
the frame: on the 480-px captures of a 33-m birch and a maple the 8-degree sweep scored 0.027 and
0.018, and the RANSAC plane used instead put the eye-height scale 4.2x and 2.7x off; their
5-degree sweeps stand out (0.055, 0.045) within 17 % of the true ground. Shallower rays first would
cost the captures where steep ground shows (two 480-px oak captures: 1.000 and 1.023 of the true
depth at 8 degrees, 1.030 and 1.112 at 3)."""


def to_tree_frame(result: SfmResult, *, origin=None, scale: float | None = None, eye_height: float = EYE_HEIGHT,
                  max_up_angle_deg: float = 20.0, seed: int = 0, images=None) -> SfmResult:
    """Put an SfM model into treeform's frame with default choices (seed 002 §3).

    Up is the ground plane's normal when it lies within ``max_up_angle_deg`` of the mean
    camera up (a level ground is the better vertical), else the camera up. The origin is the
    point the cameras look at (:func:`treeform.sfm.colmap.convergence_point`) dropped onto the
    ground, unless given. The scale puts the median camera at ``eye_height`` metres above the
    ground, unless given. Where RANSAC finds no level plane, the ground is taken through the
    5th percentile of the points below the cameras along the camera up.

    With ``images`` (the registered photos in ``result.names`` order), the ground's height
    comes from a plane sweep over the photos' ground pixels (:func:`~treeform.sfm.sweep.sweep_ground`)
    where its best depth stands out (:data:`SWEEP_MIN_CONTRAST`; the pixels looking steeply down
    first, then shallower ones: :data:`SWEEP_DEPRESSIONS`): a lawn gives the matcher few
    points, and a RANSAC plane through 4-7 of them put the eye-height scale off by 0.3-4.9x on
    synthetic captures where the sweep was within 2.3 %.

    Returns
    -------
    SfmResult
        With ``meta["frame"]``: ``up_source`` ("ground" or "cameras"), ``ground_source``
        ("ransac", "lowest_points" or "sweep"), ``ground_inliers`` (RANSAC's), ``scale_source``,
        ``camera_height_median`` (metres) and, with ``images``, ``sweep_contrast`` and
        ``sweep_depression_deg`` (of the sweep used, else of the last tried: :data:`SWEEP_DEPRESSIONS`).
    """
    from treeform.sfm.colmap import convergence_point

    cam_up = up_vector(result)
    ground_source = "ransac"
    try:
        plane = ground_plane(result, cam_up, seed=seed)
    except SfmError:  # no level plane among the lowest points: their 5th percentile along the camera up
        h = result.points @ cam_up
        below = h[h < np.median(result.centers @ cam_up)]
        if len(below) < 3:
            raise
        plane, ground_source = Plane(cam_up, float(np.quantile(below, 0.05))), "lowest_points"
    angle = float(np.degrees(np.arccos(np.clip(plane.normal @ cam_up, -1, 1))))
    # a plane through a handful of points (a sparse model) is no evidence of the ground
    enough = plane.inliers >= max(MIN_GROUND_INLIERS, 0.05 * len(result.points))
    up, up_source = (plane.normal, "ground") if angle <= max_up_angle_deg and enough else (cam_up, "cameras")
    if up_source == "cameras" and ground_source == "ransac":
        plane = ground_plane(result, up, seed=seed)
    sweep = {}
    if images is not None:
        from treeform.sfm.sweep import sweep_ground

        for dep in SWEEP_DEPRESSIONS:  # steep ground first; shallower rays where it shows too little
            sw = sweep_ground(result, images, up, min_depression_deg=dep)
            sweep = {"sweep_contrast": round(sw.contrast, 4), "sweep_depression_deg": dep}
            if sw.contrast >= SWEEP_MIN_CONTRAST:
                top = float(np.median(result.centers @ up))
                plane, ground_source = Plane(np.asarray(up, np.float64), top - sw.depth, plane.inliers), "sweep"
                break
    if origin is None:
        origin = plane.project(convergence_point(result)[0])[0]
    s = camera_height_scale(result, plane, eye_height=eye_height) if scale is None else float(scale)
    out = similarity_to_frame(result, origin=origin, up=up, scale=s)
    out.meta["frame"] = {"up_source": up_source, "ground_camera_up_angle_deg": round(angle, 3),
                         "ground_source": ground_source, "ground_inliers": plane.inliers,
                         "scale_source": "eye_height" if scale is None else "given",
                         "camera_height_median": round(float(np.median(out.centers[:, 1])), 4), **sweep}
    return out
