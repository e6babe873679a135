"""Scores of one reconstruction against a case's ground truth (issue: one evaluation for every method).

All figures are plain floats (JSON-ready); a score the case cannot support is absent.

- front silhouette (seed 004 eq. 3 and IoU) in the photo's frame, against the true mask and
  against the method's own segmentation, so the gap shows what segmentation costs;
- novel views: both trees in the photo camera's frame (the true one turned by minus the
  camera azimuth, trunk bases at the origin, the reconstruction scaled to the true height),
  silhouettes from 90°, 180° and above through the same near-orthographic camera, IoU;
- RBV error per level: mean absolute difference of the normalised radii, in % (seed 003
  Table 1), reconstruction's RBV vs the true one in that frame;
- tree-form metric distances (seed 003 §6): relative error of height, trunk diameter, LAI and
  biomass, absolute error of the branching angle in degrees;
- species (when the method predicts one).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["VIEWS", "canonical_mesh", "novel_view_ious", "rbv_errors", "reconstruction_scale", "score_reconstruction"]

VIEWS = {"front": (0.0, 0.0), "side": (90.0, 0.0), "back": (180.0, 0.0), "top": (0.0, 90.0)}
"""View name -> (azimuth, elevation) in degrees in the photo camera's frame (front = +Z)."""


def _turn(points: np.ndarray, azimuth_deg: float) -> np.ndarray:
    """Rotate (N, 3) points about +Y by ``-azimuth_deg`` (the camera's azimuth onto +Z)."""
    a = math.radians(azimuth_deg)
    c, s = math.cos(-a), math.sin(-a)
    rot = np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    return points @ rot.T


def canonical_mesh(mesh, root, *, azimuth_deg: float = 0.0, scale: float = 1.0):
    """``mesh`` with ``root`` moved to the origin, turned by ``-azimuth_deg`` about +Y and scaled.

    Parameters
    ----------
    mesh : Mesh
    root : sequence of 3 floats
        The trunk base.
    azimuth_deg : float
        The photo camera's azimuth around the tree: after the turn the camera looks from +Z.
    scale : float

    Returns
    -------
    Mesh
        A new mesh (the input is not changed).
    """
    from dataclasses import replace

    from treeform.structures import Mesh

    root = np.asarray(root, np.float64)
    parts = []
    for p in mesh.parts:
        pos = _turn(p.positions.astype(np.float64) - root, azimuth_deg) * scale
        parts.append(replace(p, positions=pos.astype(np.float32),
                             normals=_turn(p.normals.astype(np.float64), azimuth_deg).astype(np.float32)))
    return Mesh(parts)


def _height(mesh, root_y: float = 0.0) -> float:
    lo, hi = mesh.bounds()
    return float(hi[1] - root_y)


def reconstruction_scale(rec, case) -> float:
    """Factor that gives the reconstruction the true tree's height above its base (1 without a truth).

    A single photo fixes a tree's shape, not its size (every method takes the height as an
    option), so the views compare shapes at the true height.
    """
    if case.gt_mesh is None or case.gt_skeleton is None:
        return 1.0
    h_rec = _height(rec.mesh, float(rec.skeleton.positions[0][1]))
    h_gt = _height(case.gt_mesh, float(case.gt_skeleton.positions[0][1]))
    return h_gt / h_rec if h_rec > 0 else 1.0


def novel_view_ious(gt_mesh, rec_mesh, *, size: int = 160) -> dict:
    """Silhouette IoU of two meshes already in one frame, from each of :data:`VIEWS`.

    Parameters
    ----------
    gt_mesh, rec_mesh : Mesh
        Both in the photo camera's frame (see :func:`canonical_mesh`).
    size : int
        Silhouette edge in pixels.

    Returns
    -------
    dict
        ``{"iou_front", "iou_side", "iou_back", "iou_top"}`` in [0, 1].
    """
    from treeform.metrics import iou
    from treeform.render import Renderer

    (la, ha), (lb, hb) = gt_mesh.bounds(), rec_mesh.bounds()
    lo, hi = np.minimum(la, lb).astype(np.float64), np.maximum(ha, hb).astype(np.float64)
    from treeform.structures.camera import box_camera

    cams = {k: box_camera(lo, hi, az, el, size) for k, (az, el) in VIEWS.items()}
    renderer = Renderer(cams["front"], samples=1)
    out = {}
    try:
        for k, cam in cams.items():
            renderer.camera = cam
            a = renderer.render(gt_mesh).mask
            b = renderer.render(rec_mesh).mask
            out[f"iou_{k}"] = round(float(iou(b, a)), 4)
    finally:
        renderer.release()
    return out


def rbv_errors(rec_skeleton, gt_levels) -> list:
    """Mean absolute error (%) of the normalised RBV radii per level 1–5, seed 003 Table 1.

    ``rec_skeleton`` is in the photo camera's frame (camera on +Z, as every method builds).
    """
    from treeform.dataset.synthetic import canonical_rbv

    rec_levels, _, _ = canonical_rbv(rec_skeleton, 0.0)
    return [round(100.0 * float(np.abs(np.asarray(a) - np.asarray(b)).mean()), 3)
            for a, b in zip(rec_levels, gt_levels)]


def _form_errors(rec, case) -> dict:
    from treeform.metrics import tree_metrics

    g = tree_metrics(case.gt_skeleton)
    r = tree_metrics(rec.skeleton)  # skeletons alone on both sides (the truth keeps no foliage)
    out = {}
    for k, name in (("tree_height_m", "height"), ("trunk_diameter_m", "trunk_diameter"), ("biomass_m3", "biomass")):
        gv, rv = float(g[k]), float(r[k])
        if math.isfinite(gv) and math.isfinite(rv) and gv > 0:
            out[f"rel_err_{name}"] = round(abs(rv - gv) / gv, 4)
    ga, ra = float(g["branching_angle_deg"]), float(r["branching_angle_deg"])
    if math.isfinite(ga) and math.isfinite(ra):
        out["abs_err_branching_angle_deg"] = round(abs(ra - ga), 3)
    return out


def _front(rec, gt_mask) -> dict:
    from treeform.metrics import iou, reprojection_error
    from treeform.report import photo_window

    front = rec.renders["front"]
    mask = front.mask[photo_window(front.camera, rec.camera)]
    own = rec.segmentation.labels > 0
    out = {"front_error_own": round(float(reprojection_error(mask, own)), 4),
           "front_iou_own": round(float(iou(mask, own)), 4)}
    if gt_mask is not None:
        gt = np.asarray(gt_mask, bool)
        if gt.shape != mask.shape:
            import cv2

            gt = cv2.resize(gt.astype(np.uint8), mask.shape[::-1], interpolation=cv2.INTER_NEAREST) > 0
        out["front_error"] = round(float(reprojection_error(mask, gt)), 4)
        out["front_iou"] = round(float(iou(mask, gt)), 4)
        if own.shape != gt.shape:
            import cv2

            own = cv2.resize(own.astype(np.uint8), gt.shape[::-1], interpolation=cv2.INTER_NEAREST) > 0
        out["segmentation_iou"] = round(float(iou(own, gt)), 4)
    return out


def score_reconstruction(rec, case, *, view_size: int = 160) -> dict:
    """Every score of ``rec`` (a method's reconstruction) that ``case`` supports.

    Parameters
    ----------
    rec : object
        A single-photo method's result: ``mesh``, ``skeleton``, ``foliage``, ``camera``,
        ``segmentation`` and ``renders`` (with the photo camera's front view); ``species``
        when the method predicts one.
    case : Case
    view_size : int

    Returns
    -------
    dict
        See the module docstring; ``rbv_err_l1`` … ``rbv_err_l5``, ``iou_side`` etc.
    """
    out = _front(rec, case.gt_mask)
    if case.gt_mesh is not None and case.gt_skeleton is not None:
        gt = canonical_mesh(case.gt_mesh, case.gt_skeleton.positions[0], azimuth_deg=case.azimuth_deg)
        rec_mesh = canonical_mesh(rec.mesh, rec.skeleton.positions[0], scale=reconstruction_scale(rec, case))
        out.update(novel_view_ious(gt, rec_mesh, size=view_size))
    if case.rbv is not None:
        for i, e in enumerate(rbv_errors(rec.skeleton, case.rbv)):
            out[f"rbv_err_l{i + 1}"] = e
    if case.gt_skeleton is not None:
        out.update(_form_errors(rec, case))
    if case.species is not None and getattr(rec, "species", None) is not None:
        out["species_correct"] = 1.0 if rec.species == case.species else 0.0
    return out
