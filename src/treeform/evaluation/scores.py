"""Scores of one reconstruction against a case's ground truth (issue: one evaluation for every method).

All figures are plain floats (JSON-ready); a score the case cannot support is absent.

- front silhouette (seed 004 eq. 3 and IoU) in the photo's frame, against the true mask and
  against the method's own segmentation, so the gap shows what segmentation costs;
- novel views: both trees in the photo camera's frame (the true one turned by minus the
  camera azimuth, trunk bases at the origin; a single-photo reconstruction scaled to the true
  height about its own base, a multi-view one as its registered cameras place it in the
  truth's frame), silhouettes from 90°, 180° and above through the same near-orthographic
  camera, IoU; and from those sides how open each crown is (``gap_err_side`` etc.: the absolute
  difference of the two silhouettes' :func:`~treeform.metrics.silhouette_gaps`), which IoU cannot
  tell: a solid ball where the true crown has lobes and holes scores well on IoU;
- RBV error per level: mean absolute difference of the normalised radii, in % (seed 003
  Table 1), reconstruction's RBV vs the true one in that frame;
- tree-form metric distances (seed 003 §6): relative error of height, trunk diameter, LAI (each
  tree's leaf triangles over its crown's footprint) and biomass, absolute error of the branching
  angle in degrees, and the MRT error: the maximum radial trunk distance of 5 layers (measured
  from the trunk chain), each divided by its tree's height, mean absolute difference in % of
  the height;
- species (when the method predicts one).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["VIEWS", "align_multiview", "aligned_view_mesh", "canonical_mesh", "novel_view_ious", "rbv_errors", "reconstruction_scale",
           "score_multiview", "score_reconstruction"]

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
        ``{"iou_front", "iou_side", "iou_back", "iou_top"}`` in [0, 1], and ``gap_err_side``,
        ``gap_err_back``, ``gap_err_top``: how far the reconstruction's share of open sky
        inside its outline is from the truth's (:func:`~treeform.metrics.silhouette_gaps`).
    """
    from treeform.metrics import iou, silhouette_gaps
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
            if k != "front":  # the front's gaps are the photo's (the front IoU scores them)
                out[f"gap_err_{k}"] = round(abs(silhouette_gaps(b) - silhouette_gaps(a)), 4)
    finally:
        renderer.release()
    return out


def rbv_errors(rec_skeleton, gt_levels, *, azimuth_deg: float = 0.0) -> list:
    """Mean absolute error (%) of the normalised RBV radii per level 1–5, seed 003 Table 1.

    ``rec_skeleton`` is in the photo camera's frame (camera on +Z, as every single-photo
    method builds), or in a frame where the photo camera stands at azimuth ``azimuth_deg``
    (the truth's frame, where the multi-view reconstruction is aligned).
    """
    from treeform.dataset.synthetic import canonical_rbv

    rec_levels, _, _ = canonical_rbv(rec_skeleton, azimuth_deg)
    return [round(100.0 * float(np.abs(np.asarray(a) - np.asarray(b)).mean()), 3)
            for a, b in zip(rec_levels, gt_levels)]


def _mrt_profile(metrics: dict) -> np.ndarray | None:
    """The MRT per layer divided by the tree's height (a shape, free of the tree's scale)."""
    h = float(metrics["tree_height_m"])
    mrt = np.asarray(metrics["mrt_m"], np.float64)
    return mrt / h if math.isfinite(h) and h > 0 and np.all(np.isfinite(mrt)) else None


def _form_errors(rec, case) -> dict:
    from treeform.metrics import tree_metrics

    # the LAI from each tree's own leaf triangles (cards count whole, as the paper's metric space);
    # the truth's metrics once per case, whichever methods are scored on it
    if case.gt_metrics is None:
        case.gt_metrics = tree_metrics(case.gt_skeleton, leaf_triangles=_leaves(case.gt_mesh))
    g = case.gt_metrics
    r = tree_metrics(rec.skeleton, leaf_triangles=_leaves(rec.mesh))
    out = {}
    for k, name in (("tree_height_m", "height"), ("trunk_diameter_m", "trunk_diameter"), ("biomass_m3", "biomass"),
                    ("leaf_area_index", "lai")):
        gv, rv = float(g[k]), float(r[k])
        if math.isfinite(gv) and math.isfinite(rv) and gv > 0:
            out[f"rel_err_{name}"] = round(abs(rv - gv) / gv, 4)
    ga, ra = float(g["branching_angle_deg"]), float(r["branching_angle_deg"])
    if math.isfinite(ga) and math.isfinite(ra):
        out["abs_err_branching_angle_deg"] = round(abs(ra - ga), 3)
    gm, rm = _mrt_profile(g), _mrt_profile(r)
    if gm is not None and rm is not None:
        out["mrt_err_pct"] = round(100.0 * float(np.abs(rm - gm).mean()), 3)
    return out


def _leaves(mesh):
    return None if mesh is None else mesh.triangles("leaves")


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


@dataclass
class AlignedTree:
    """A reconstruction moved into the truth's frame: ``mesh`` (Mesh), ``skeleton`` (TreeSkeleton)."""

    mesh: object
    skeleton: object


def align_multiview(res, cameras: dict) -> tuple[AlignedTree, dict]:
    """The multi-view reconstruction in the truth's frame, by the similarity of its cameras.

    Structure from motion fixes the world up to scale, rotation and translation; the
    similarity that best maps the registered camera centres onto the true ones
    (:func:`treeform.sfm.evaluate.pose_errors`) maps the tree as well.

    Parameters
    ----------
    res : MultiviewResult
        ``sfm`` (in the tree's frame), ``mesh``, ``skeleton``.
    cameras : dict
        The true cameras (:attr:`Case.cameras`).

    Returns
    -------
    AlignedTree, dict
        The moved tree, and :func:`~treeform.sfm.evaluate.pose_errors`' figures.

    Raises
    ------
    InputError
        Fewer than 3 of the true photos registered: no similarity.
    """
    from dataclasses import replace

    from treeform._shared.errors import InputError
    from treeform.sfm.evaluate import pose_errors
    from treeform.structures import Mesh, TreeSkeleton

    pe = pose_errors(res.sfm, cameras)
    if pe.get("scale") is None:
        raise InputError(f"{pe['registered']} of {pe['total']} photos registered: too few to align with the truth")
    s, R, t = float(pe["scale"]), np.asarray(pe["rotation"], np.float64), np.asarray(pe["translation"], np.float64)
    parts = [replace(p, positions=(s * p.positions.astype(np.float64) @ R.T + t).astype(np.float32),
                     normals=(p.normals.astype(np.float64) @ R.T).astype(np.float32)) for p in res.mesh.parts]
    sk = res.skeleton
    skel = TreeSkeleton(s * sk.positions @ R.T + t, sk.parent, None if sk.radius is None else s * sk.radius,
                        sk.order, sk.age)
    return AlignedTree(Mesh(parts), skel), pe


def aligned_view_mesh(tree: AlignedTree, case):
    """The aligned tree in the first photo camera's frame, about the true trunk base, as aligned.

    A single-photo reconstruction knows its tree only relative to its own trunk base and not its
    size, so it is compared about that base at the true height; the aligned multi-view tree
    stands where, and as large as, the similarity of its cameras onto the true ones puts it, so
    a crown placed right over a trunk base placed wrong still matches. (Scaling it to the true
    height about its own base, as before, shrank such a tree toward the ground: a birch capture
    whose trunk the route ran 6.5 m under the true ground scored side IoU 0.18, 0.50 as placed.)
    """
    return canonical_mesh(tree.mesh, case.gt_skeleton.positions[0], azimuth_deg=case.azimuth_deg)


def score_multiview(res, case, *, view_size: int = 160) -> dict:
    """Every score of a multi-view reconstruction that a capture case supports.

    The same scores as :func:`score_reconstruction` for the same truth, so the methods share
    one table: the front silhouette is the aligned tree drawn by the first photo's true
    camera against that photo's true mask; the novel views, RBV and tree-form errors are taken
    in that photo camera's frame, the tree where and as large as the similarity of its cameras
    onto the true ones places it (:func:`aligned_view_mesh`). The height is the route's own
    metric estimate: ``rel_err_height`` compares its ``tree_height_m`` (the scale from the
    cameras held at eye height, or the ground the photos show) with the true tree's top above
    its base. Also ``registration_rate`` and
    ``camera_position_err`` (median, fraction of the capture's size). There is no own-mask
    score: the route keeps no per-photo matte.

    Parameters
    ----------
    res : MultiviewResult
    case : Case
        A capture case (``cameras`` and the truth).
    view_size : int

    Returns
    -------
    dict
    """
    from treeform.metrics import iou, reprojection_error
    from treeform.render import Renderer
    from treeform.sfm.result import render_camera

    tree, pe = align_multiview(res, case.cameras)
    out = {"registration_rate": round(float(pe["registration_rate"]), 4)}
    if pe.get("position_median_rel") is not None:
        out["camera_position_err"] = round(float(pe["position_median_rel"]), 5)
    first = case.cameras[min(case.cameras)]  # the first photo (the single-photo methods see it alone)
    renderer = Renderer(render_camera(first["K"], first["cam_to_world"], first["size"], near=0.1, far=1000.0),
                        samples=1)
    try:
        mask = renderer.render(tree.mesh).mask > 0
    finally:
        renderer.release()
    gt = np.asarray(case.gt_mask, bool)
    out["front_error"] = round(float(reprojection_error(mask, gt)), 4)
    out["front_iou"] = round(float(iou(mask, gt)), 4)
    gt_mesh = canonical_mesh(case.gt_mesh, case.gt_skeleton.positions[0], azimuth_deg=case.azimuth_deg)
    out.update(novel_view_ious(gt_mesh, aligned_view_mesh(tree, case), size=view_size))
    if case.rbv is not None:
        for i, e in enumerate(rbv_errors(tree.skeleton, case.rbv, azimuth_deg=case.azimuth_deg)):
            out[f"rbv_err_l{i + 1}"] = e
    out.update(_form_errors(tree, case))
    # _form_errors measured the aligned tree, whose scale is the truth's (the cameras' similarity): its
    # height error would only be the shape's; the route's own metric estimate is in its metrics
    h_gt = _height(case.gt_mesh, float(case.gt_skeleton.positions[0][1]))
    h_rec = float(res.metrics.get("tree_height_m", math.nan))
    if math.isfinite(h_rec) and h_gt > 0:
        out["rel_err_height"] = round(abs(h_rec - h_gt) / h_gt, 4)
    else:
        out.pop("rel_err_height", None)
    return out
