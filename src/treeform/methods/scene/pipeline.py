"""Several trees in one photo -> a placed group of 3D trees (``treeform reconstruct PHOTO --all-trees``).

Issue 16 item 2, beyond seed 003 (Fig. 16 and §5: there the trees of a photo are cropped and
placed by hand). Stages:

1. ``instances``: every tree of the photo with the pixel of its foot
   (:func:`treeform.segment.instances.find_tree_instances`);
2. ``place``: their feet on a common ground plane seen by the photo's camera
   (:func:`treeform.methods.scene.placement.place_on_ground`; the camera ``camera_height``
   metres up sets the scale, or, when ``tree_height`` is given, the tallest tree in pixels);
3. ``trees``: each tree reconstructed from its own crop by any single-photo method, with its
   instance mask as the tree mask and its height from the placement; a tree whose
   reconstruction fails is recorded with its one-line reason and the others go on;
4. ``preview``: the photo with its numbered instances beside the placed group drawn by the
   photo's camera;
5. ``export``: ``scene.glb`` (one node per tree, placed and turned), ``scene.json``,
   ``preview.png`` and ``tree_K/`` (each tree's own outputs), all or nothing.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from treeform._shared.errors import InputError, TreeformError
from treeform._shared.timing import ProgressCallback, StageTimer

__all__ = ["SCENE_STAGES", "SceneReconstruction", "reconstruct_all"]

SCENE_STAGES = ("load", "instances", "place", "trees", "preview", "export")

MARGIN = 0.06
"""Each tree's crop reaches this share of its height beyond its box on every side."""


@dataclass
class SceneReconstruction:
    """What :func:`reconstruct_all` made; ``files`` maps output names to paths (if written)."""

    image: np.ndarray
    instances: list
    placement: object
    trees: list
    """Each instance's reconstruction (the method's result), None where it failed."""
    failures: dict
    """Instance index (from 0) -> the one-line reason its reconstruction failed."""
    preview: np.ndarray | None = None
    metrics: dict = field(default_factory=dict)
    files: dict = field(default_factory=dict)


def _crop(image: np.ndarray, inst, max_size: int) -> tuple[np.ndarray, np.ndarray]:
    """The photo and the instance's mask cut to its box plus :data:`MARGIN`, at most ``max_size`` on the long side."""
    import cv2

    H, W = image.shape[:2]
    y0, y1, x0, x1 = inst.box
    pad = int(round(MARGIN * (y1 - y0)))
    y0, y1, x0, x1 = max(0, y0 - pad), min(H, y1 + pad), max(0, x0 - pad), min(W, x1 + pad)
    img = image[y0:y1, x0:x1]
    mask = (inst.mask[y0:y1, x0:x1] * 255).astype(np.uint8)
    s = max_size / max(img.shape[:2])
    if s < 1.0:
        size = (max(8, round(img.shape[1] * s)), max(8, round(img.shape[0] * s)))
        img = cv2.resize(img, size, interpolation=cv2.INTER_AREA)
        mask = cv2.resize(mask, size, interpolation=cv2.INTER_NEAREST)
    return np.ascontiguousarray(img), mask


def _outline_picture(image: np.ndarray, instances) -> np.ndarray:
    """The photo with each instance's outline and its number at its foot."""
    import cv2

    out = image.copy()
    colours = [(255, 80, 60), (60, 160, 255), (255, 210, 40), (200, 80, 255), (40, 230, 160), (255, 140, 200)]
    th = max(1, round(max(image.shape[:2]) / 400))
    for k, t in enumerate(instances):
        c = colours[k % len(colours)]
        contours, _ = cv2.findContours(t.mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        cv2.drawContours(out, contours, -1, c, th)
        u, v = (int(round(x)) for x in t.base)
        cv2.circle(out, (u, v), 3 * th, c, -1)
        scale = max(0.8, max(image.shape[:2]) / 450)
        (tw, tht), _ = cv2.getTextSize(str(k + 1), cv2.FONT_HERSHEY_SIMPLEX, scale, 2 * th)
        y0, _, x0, x1 = t.box  # the number above the crown (inside the photo)
        org = (int(np.clip((x0 + x1 - tw) / 2, 0, image.shape[1] - tw)), int(max(tht + 4, y0 - 6)))
        cv2.putText(out, str(k + 1), org, cv2.FONT_HERSHEY_SIMPLEX, scale, (0, 0, 0), 4 * th, cv2.LINE_AA)
        cv2.putText(out, str(k + 1), org, cv2.FONT_HERSHEY_SIMPLEX, scale, c, 2 * th, cv2.LINE_AA)
    return out


def _scene_render(placement, meshes: list, size: tuple) -> np.ndarray:
    """The placed trees drawn by the photo's camera at ``size`` (width, height)."""
    from treeform.render import Renderer
    from treeform.structures import Camera

    cam = placement.camera
    w, h = size
    cam = Camera(int(w), int(h), cam.fov_y, cam.position, cam.target, cam.up, cam.near, cam.far)
    from treeform.geometry.ground import ground_plane
    from treeform.structures.mesh import Mesh

    r = Renderer(cam, background=(0.78, 0.86, 0.95, 1.0))
    try:
        pos = placement.positions
        reach = 0.75 * cam.far  # far enough that the ground meets the sky at the horizon, inside the far plane
        ground = Mesh([ground_plane(float(pos[:, 0].min()) - reach, float(pos[:, 0].max()) + reach,
                                    float(pos[:, 2].min()) - reach, float(cam.position[2]) + 1.0)])
        items = [(ground, None)] + [(m, np.array([[*pos[k], 1.0, placement.yaws[k], 0.0]], np.float32))
                                    for k, m in meshes]
        return r.render_scene(items).color[..., :3]
    finally:
        r.release()


def reconstruct_all(photo, *, out=None, method_api=None, method: str = "envelope", tree_height: float | None = None,
                    camera_height: float = 1.6, fov_y: float = 40.0, max_size: int = 1280, tree_max_size: int = 640,
                    seed: int = 0, weights=None, feet: str | None = None, progress: ProgressCallback | None = None,
                    **method_options) -> SceneReconstruction:
    """Find every tree of a photo, reconstruct each, and place them together.

    Parameters
    ----------
    photo : path, ndarray (H, W, 3) uint8, or Photo
    out : path, optional
        Output folder: scene.glb, scene.json, preview.png and tree_1/ ... tree_N/ (each the
        method's own outputs); nothing is written unless every stage succeeds (a tree whose
        reconstruction failed is listed in scene.json and has no folder).
    method_api : callable, optional
        The single-photo method's ``reconstruct(photo, mask=, out=, tree_height=, seed=, ...)``
        (default: the envelope route's).
    method : str
        Its name, recorded in scene.json.
    tree_height : float, optional
        Height in metres of the tallest tree in pixels; when given, it sets the scene's scale.
    camera_height : float
        Metres from the ground to the camera: the scene's scale unless ``tree_height`` is given
        (1.6: a photo taken standing).
    fov_y : float
        The photo's vertical field of view in degrees.
    max_size, tree_max_size : int
        Long side of the photo for finding the trees, and of each tree's crop.
    seed : int
        Tree ``k`` (from 0) is reconstructed with seed ``seed + k``.
    weights : path, optional
        Segmentation weights (default: the shipped ones).
    feet : {'rules', 'learned', 'both'}, optional
        Where each tree's trunk foot comes from (:func:`~treeform.segment.instances.find_tree_instances`):
        the mask's rules, the learned foot detector, or both (default:
        :data:`~treeform.segment.instances.DEFAULT_FEET`).
    progress : callable, optional
        ``progress(stage, event, seconds)`` for :data:`SCENE_STAGES`.
    **method_options
        Passed to ``method_api`` (e.g. ``leaves=``, ``lod=``).

    Returns
    -------
    SceneReconstruction

    Raises
    ------
    NoTreeFoundError
        No tree in the photo.
    TreeformError
        Every tree's reconstruction failed (the first reason).
    """
    from treeform._shared.checks import check_height
    from treeform._shared.rng import check_seed
    from treeform.io.outputs import check_out_dir
    from treeform.methods._single_photo import as_photo, fit_photo
    from treeform.methods.scene.placement import place_on_ground
    from treeform.segment.instances import DEFAULT_FEET, find_tree_instances

    feet = feet or DEFAULT_FEET
    if tree_height is not None:
        check_height(tree_height)
    seed = check_seed(seed)
    if method_api is None:
        from treeform.methods.envelope.pipeline import reconstruct as method_api
    if "mask" in method_options:
        raise InputError("mask: each tree's mask comes from the photo's instances (--all-trees takes no --mask)")
    out_dir = check_out_dir(out) if out is not None else None
    timer = StageTimer(progress)
    with timer.stage("load"):
        ph = fit_photo(as_photo(photo, max_size), max_size)
        image = ph.image
    with timer.stage("instances"):
        instances = find_tree_instances(image, weights=weights, feet=feet)
    with timer.stage("place"):
        placement = place_on_ground([t.base for t in instances], [t.top for t in instances], image.shape[1],
                                    image.shape[0], fov_y=fov_y, camera_height=camera_height,
                                    main_height=tree_height)
    staged = None
    if out_dir is not None:
        from treeform.io.outputs import StagedOutputs

        staged = StagedOutputs(out_dir)
    try:
        trees, failures = [], {}
        with timer.stage("trees"):
            for k, inst in enumerate(instances):
                crop, mask = _crop(image, inst, tree_max_size)
                h = float(np.clip(placement.heights[k], 0.5, 150.0))
                try:
                    res = method_api(crop, mask=mask, out=None if staged is None else staged.staging_dir / f"tree_{k + 1}",
                                     tree_height=h, seed=seed + k, **method_options)
                except TreeformError as exc:
                    trees.append(None)
                    failures[k] = str(exc)
                    continue
                trees.append(res)
        if len(failures) == len(instances):
            first = failures[0]
            raise TreeformError(f"no tree could be reconstructed (tree 1: {first})")
        with timer.stage("preview"):
            meshes = [(k, r.mesh) for k, r in enumerate(trees) if r is not None]
            left = _outline_picture(image, instances)
            s = min(1.0, 640 / max(image.shape[:2]))
            size = (max(8, round(image.shape[1] * s)), max(8, round(image.shape[0] * s)))
            import cv2

            left = cv2.resize(left, size, interpolation=cv2.INTER_AREA)
            right = _scene_render(placement, meshes, size)
            preview = np.concatenate([left, np.full((size[1], 8, 3), 255, np.uint8), right], 1)
        metrics = _scene_json(ph, instances, placement, trees, failures, method, tree_height, fov_y)
        metrics["feet"] = feet
        result = SceneReconstruction(image, instances, placement, trees, failures, preview, metrics)
        if staged is not None:
            with timer.stage("export"):
                from treeform.io.gltf import GlbNode, write_glb_scene
                from treeform.io.images import write_png

                nodes = [GlbNode(r.mesh, name=f"tree_{k + 1}", translation=tuple(placement.positions[k]),
                                 yaw=float(placement.yaws[k])) for k, r in enumerate(trees) if r is not None]
                metrics["stage_seconds"] = {k: round(v, 3) for k, v in timer.timings.items()}
                staged.submit(lambda d: write_glb_scene(nodes, d / "scene.glb"),
                              lambda d: write_png(preview, d / "preview.png"),
                              lambda d: (d / "scene.json").write_text(json.dumps(metrics, indent=2)))
                result.files = staged.commit()
        return result
    finally:
        if staged is not None:
            staged.abort()


def _scene_json(ph, instances, placement, trees, failures, method, tree_height, fov_y) -> dict:
    cam = placement.camera
    f = 0.5 * cam.height / math.tan(math.radians(fov_y) / 2)
    src = getattr(ph, "source", None)
    rows = []
    for k, t in enumerate(instances):
        y0, y1, x0, x1 = t.box
        rows.append({
            "tree": k + 1,
            "folder": None if trees[k] is None else f"tree_{k + 1}",
            "error": failures.get(k),
            "foot_px": [round(float(t.base[0]), 1), round(float(t.base[1]), 1)],
            "top_px": int(t.top),
            "box_px": [int(x0), int(y0), int(x1), int(y1)],
            "foot_from_trunk": bool(t.trunk),
            "position_m": [round(float(x), 3) for x in placement.positions[k]],
            "yaw_deg": round(math.degrees(float(placement.yaws[k])), 2),
            "height_m": round(float(placement.heights[k]), 3),
            "distance_m": round(float(placement.distances[k]), 3),
        })
    return {
        "photo": str(Path(src).name) if src else None,
        "method": method,
        "trees_found": len(instances),
        "trees_reconstructed": len(instances) - len(failures),
        "scale": {"from": "camera height" if tree_height is None else "reference tree height",
                  "reference_tree": placement.reference + 1,
                  "reference_height_m": round(float(placement.heights[placement.reference]), 3)},
        "camera": {"fov_y_deg": float(fov_y), "width": int(cam.width), "height": int(cam.height),
                   "K": [[f, 0.0, cam.width / 2], [0.0, f, cam.height / 2], [0.0, 0.0, 1.0]],
                   "position_m": [round(float(x), 3) for x in cam.position],
                   "height_above_ground_m": round(placement.camera_height, 3),
                   "horizon_row": round(placement.horizon_row, 1)},
        "frame": "Y up, metres; the reference tree's foot at the origin; the camera on the +Z side looking along -Z",
        "trees": rows,
    }
