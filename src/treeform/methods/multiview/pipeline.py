"""Several photos -> 3D tree (seed 002: Tan et al., Image-based tree modeling, SIGGRAPH 2007).

Stages, each one call into a domain folder or a sibling module:

1. **photos + SfM** (§3): :func:`treeform.sfm.load_photos`, :func:`treeform.sfm.run_sfm` —
   pycolmap on the CPU with the EXIF focal prior; the largest model.
2. **frame** (§3): up = the cameras' mean up, the ground plane from the lowest points,
   metres from ``height`` or from the cameras' eye height, origin at the trunk's foot.
3. **matting** (§4.1): the project's segmenter on every registered view (the network seeing it
   at 1.25x the matte's size), plus the wood the network sees on full-size tiles of the photo
   (:func:`_tile_wood`: the limbs it loses when it sees the photo whole) and thin dark ridges
   against the sky near the tree as wood (:func:`treeform.segment.thin.thin_dark_lines`: the
   twigs a segmenter's stride loses), less the foliage coloured like the sky above the tree
   (:func:`treeform.segment.matting.sky_gaps`: the small gaps it fills in).
4. **points and partition** (§4.1–4.2): :func:`carve.carve_tree` — the tree's points as
   the visual hull of the mattes (the piece the cameras look at, :func:`carve.main_component`;
   at the fine cells its pieces in the trunk's column and near them, :func:`carve.tree_pieces`),
   each with the silhouette half-width seen from the views and wood votes, each view's wood
   pixel given to the tree's cells on its ray that explain it best (:func:`carve.explain_wood`),
   not to every cell the ray crosses in the crown; thin or wood-voted points are branch, the
   rest leaf.
5. **visible branch graph** (§4.3): :func:`branch_graph.branch_skeleton`.
6. **hidden branches** (§5.2): the visible skeleton's own subtrees as replication blocks,
   each turned and scaled onto an end branch it replaces, cut at the hull
   (:mod:`replication`), then constrained growth — the project's space colonization toward
   the leaf points with the paper's 90-degree influence cones; radii by the pipe model, the trunk at the width the photos
   show at their own resolution (:func:`trunk.trunk_diameter`; the mattes' width where they do not).
7. **leaves** (§6): most leaf clusters on the crown's surface as the views' silhouettes carve
   it, the rest on the grown twigs; each card wears the photo that sees it best, carved texel
   by texel against every view's matte (``leaf_texture='photo'``, the default), or is a drawn
   cluster coloured from the photos at the nearest leaf point, then calibrated by rendering
   so the model's leaves have the photos' colours (``'procedural'``).
8. mesh, previews from three input cameras, metrics, export (tree.glb ...,
   cameras.json, points.ply).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from treeform._shared.errors import InputError, NoTreeFoundError
from treeform._shared.timing import ProgressCallback, StageTimer
from treeform.methods.multiview.config import MATTE_ZOOM, MultiviewConfig

__all__ = ["MIN_GROUND_POINTS", "MIN_VIEW_IOU", "STAGES", "MultiviewResult", "consistency_warning",
           "reconstruct_multiview", "registration_warning", "scale_warning"]

WOOD_VOTE = 0.25
"""A carved cell is branch when more than this share of the views that see it label it wood (the
votes explained along the views' rays, :func:`~treeform.methods.multiview.carve.explain_wood`)."""

PIECE_GAP = 0.03
"""Pieces of the fine hull this share of the tree's height from the pieces in the trunk's column join
the tree (:func:`~treeform.methods.multiview.carve.tree_pieces`; the gap the branch graph bridges too)."""

REPLICATION_CONE = 45.0
"""Half-angle (degrees) of the influence cones of the constrained growth after the replication blocks
(seed 002 §5.2: "an angular extent of 90 degrees side to side")."""
REPLICATION_NODES = 4000
"""The replication blocks' growth stops at this many nodes."""

COVER = 0.65
"""Share of a leaf-cluster card its texture covers."""
PHOTO_COVER = 0.15
"""The same for a photo tile carved by the views (:data:`TEXEL_TOLERANCE`): the views' gaps cut it,
so its cards are larger (on the 24-view oak capture, with the cameras turned and the carving of
:data:`TEXEL_TOLERANCE` / :data:`TEXEL_SPARE`, novel-view IoU 0.735 at 0.29, 0.746 at 0.2, 0.748 at
0.15, 0.746 at 0.1; BENCHMARKS.md)."""
SYNTH_ROUNDS = 4
"""Rounds of the leaf synthesis (``leaf_placement="segments"``): each gives the sparsest third of the
branches the leaves of the densest, until the leaf budget is spent (on the 24-view oak capture one
round leaves 5,248 of 15,000 leaves unspent and scores novel-view IoU 0.534; two spend it: 0.777)."""

SHELL_SHARE = 0.9
"""Share of the leaf clusters placed on the crown's surface (the rest on the twigs inside)."""
LEAF_SUPPORT = 0.92
"""A surface cell carries leaves when at least this share of the views that see it hold it."""
TEXEL_TOLERANCE = 0.05
"""Share of the views holding a leaf texel that may see background there before it is cut
(:func:`~treeform.crown.photo_leaves.carve_texels`)."""
TEXEL_SPARE = 1
"""Views that may see background at a kept texel however few views hold it (with 10 views, 0.05
alone would tolerate none)."""
TEXEL_DILATE = 1
"""Pixels by which the views' tree masks grow before the texels are carved against them (the
cameras' registration is good to about a pixel at the mattes' size; 0: not grown)."""

MATTE_THREADS = max(1, min(4, os.cpu_count() or 1))
"""Views matted at once (threads) by the matting stage."""

TILE_WOOD_FROM = 2.0
"""The network's wood on full-size tiles (``tile_wood``) joins a photo's matte when the photo is at
least this many times the network's view (320 px): from a 1024-px photo the tiles see the limbs 3.2x
larger (the 1024-px oak capture's skeleton 5.36 -> 3.06 % of the height), from a 480-px one 1.5x,
which added as much false wood as true (six 480-px captures: 5.16 -> 5.35 %)."""
MIN_GROUND_POINTS = 20
"""SfM ground inliers under which the eye-height scale is called unreliable. Measured (BENCHMARKS.md,
multi-view): 4-13 inliers on captures whose height came out 0.23-2.4x the truth, 22 on one within 15 %."""


def scale_warning(frame: dict, height_given: bool) -> str | None:
    """One line for the user when the metric scale rests on a weak ground plane, else None.

    ``frame`` is :func:`~treeform.sfm.to_tree_frame`'s ``meta["frame"]``; with ``--height`` the
    ground does not set the scale and nothing is said, nor where the photos' plane sweep found
    the ground (``ground_source`` "sweep").

    Examples
    --------
    >>> scale_warning({"ground_inliers": 5}, False)[:33]
    'the metric scale rests on a groun'
    >>> scale_warning({"ground_inliers": 5}, True) is None, scale_warning({"ground_inliers": 40}, False) is None
    (True, True)
    >>> scale_warning({"ground_inliers": 5, "ground_source": "sweep"}, False) is None
    True
    """
    n = frame.get("ground_inliers")
    if height_given or frame.get("ground_source") == "sweep" or n is None or n >= MIN_GROUND_POINTS:
        return None
    return (f"the metric scale rests on a ground plane through {n} SfM points (under {MIN_GROUND_POINTS}): "
            "the tree's height may be off by a factor of two or more; give --height for a reliable scale")


def registration_warning(photos: int, unregistered) -> str | None:
    """One line for the user when some photos did not register, else None.

    The model then sees the tree only from the registered photos' directions (a 12-photo
    capture of our park scene registered 3: its hull is a wedge).

    Examples
    --------
    >>> registration_warning(24, []) is None
    True
    >>> registration_warning(12, [f"v{i:02d}.jpg" for i in range(9)])
    '9 of 12 photos did not register (v00.jpg, v01.jpg, v02.jpg, ...): the tree is seen from the other 3 alone; photos 15-20 degrees apart all around the tree register best'
    """
    miss = list(unregistered)
    if not miss:
        return None
    names = ", ".join(str(m) for m in miss[:3]) + (", ..." if len(miss) > 3 else "")
    return (f"{len(miss)} of {photos} photos did not register ({names}): the tree is seen from the other "
            f"{photos - len(miss)} alone; photos 15-20 degrees apart all around the tree register best")


MIN_VIEW_IOU = 0.25
"""A registered photo whose tree matte and the model seen from its camera overlap less than this
(silhouette IoU) disagrees with the model. Measured on 480-px captures (BENCHMARKS.md, multi-view):
the least of the 24 views of four right SfM models 0.55-0.66; wrong models (camera position errors
of 12-26 % of the ring, or one camera 22 % off) have views at 0.0-0.09; so has a right model whose
segmenter took a neighbouring tree for the tree in one photo (0.08)."""


def consistency_warning(names, iou, tree_share) -> str | None:
    """One line for the user when registered photos see the tree where the model is not, else None.

    Either the photo's camera is wrong (the structure from motion placed it wrongly; where more
    than a quarter of the photos disagree, the model itself is likely wrong) or its tree matte
    is (the segmenter took another object for the tree); the model cannot tell which. Photos
    whose matte holds no tree (``tree_share`` at most 0.2 % of the pixels) are not counted.

    Examples
    --------
    >>> consistency_warning(["a.jpg", "b.jpg", "c.jpg"], [0.7, 0.65, 0.72], [0.2, 0.2, 0.2]) is None
    True
    >>> consistency_warning([f"{i}.jpg" for i in range(8)], [0.7] * 7 + [0.05], [0.2] * 8)[:61]
    '1 of 8 registered photos disagree with the model (7.jpg: silh'
    >>> consistency_warning(["a.jpg", "b.jpg", "c.jpg"], [0.7, 0.05, 0.0], [0.2, 0.2, 0.2])[-82:]
    'the cameras of the whole model may be wrong; retake the photos 15-20 degrees apart'
    >>> consistency_warning(["a.jpg", "b.jpg"], [0.7, 0.0], [0.2, 0.0]) is None
    True
    """
    bad = [str(n) for n, v, t in zip(names, iou, tree_share) if t > 0.002 and v < MIN_VIEW_IOU]
    if not bad:
        return None
    shown = ", ".join(bad[:3]) + (", ..." if len(bad) > 3 else "")
    head = (f"{len(bad)} of {len(names)} registered photos disagree with the model ({shown}: silhouette IoU "
            f"under {MIN_VIEW_IOU}): ")
    if len(bad) > len(names) / 4:
        return head + ("the structure from motion placed their cameras wrongly, or the mattes missed the tree; "
                       "the cameras of the whole model may be wrong; retake the photos 15-20 degrees apart")
    return head + "their camera or their tree matte is wrong (another object taken for the tree); check those photos"


STAGES = ("photos", "sfm", "frame", "matting", "carve", "branches", "growth", "leaves", "mesh", "render", "export")


@dataclass
class MultiviewResult:
    skeleton: object
    foliage: object
    mesh: object
    sfm: object
    carved: object
    branch: np.ndarray
    preview: np.ndarray
    metrics: dict
    config: dict
    timings: dict = field(default_factory=dict)
    files: dict = field(default_factory=dict)


def _scaled_K(sfm, scales) -> np.ndarray:
    K = sfm.K.copy()
    K[:, :2, :] *= np.asarray(scales, np.float64)[:, None, None]
    return K


def _user_labels(masks, name: str, size: tuple) -> np.ndarray:
    """The user's matte of photo ``name`` (``masks/<stem>.png``) as labels at ``size`` (w, h).

    A label image (values 0 background, 1 foliage, 2 wood) is taken as it is; any other
    image is a tree mask (white = tree, labelled foliage).
    """
    from PIL import Image, ImageOps

    path = Path(masks) / (Path(name).stem + ".png")
    if not path.is_file():
        raise InputError(f"--masks: no mask for {name} (expected {path})")
    try:
        with Image.open(path) as im:
            arr = np.asarray(ImageOps.exif_transpose(im).convert("L").resize(size, Image.NEAREST))
    except OSError as exc:
        raise InputError(f"--masks: cannot read {path} ({exc})") from None
    if arr.max() <= 2:
        return arr.astype(np.uint8)
    return (arr > 127).astype(np.uint8)


def _segment_views(views, sfm, cfg, masks=None):
    """Labels (0/1/2) of every registered view at ``mask_size`` and the K scaled to them.

    The views are matted on :data:`MATTE_THREADS` threads side by side (the network, the edge
    band's closed-form matting and the image filters let go of the GIL); each view's matte is its
    own, so the result does not depend on the threads' order.
    """
    from concurrent.futures import ThreadPoolExecutor

    from PIL import Image

    from treeform.segment import segment
    from treeform.segment.classical import sky_mask
    from treeform.segment.matting import sky_gaps
    from treeform.segment.thin import thin_dark_lines
    from treeform.structures import Segmentation

    by_name = {v.name: v for v in views}
    seg_net = None
    if masks is None and cfg.tile_wood and cfg.segmenter == "learned":
        from treeform.learn.infer import Segmenter

        seg_net = Segmenter()

    def one(k: int):
        name = sfm.names[k]
        img = by_name[name].image
        s = min(1.0, cfg.mask_size / max(img.shape[:2]))
        small = img if s == 1.0 else np.asarray(Image.fromarray(img).resize(
            (max(1, round(img.shape[1] * s)), max(1, round(img.shape[0] * s))), Image.LANCZOS))
        if masks is not None:
            lab = _user_labels(masks, name, (small.shape[1], small.shape[0]))
        else:
            side = round(MATTE_ZOOM * max(small.shape[:2])) if cfg.matte_side is None else cfg.matte_side
            # (the route's own gap rule follows: the segmenter's would carve the hull twice)
            seg = segment(small, method=cfg.segmenter, seed=cfg.seed, side=side or None, gaps=False)
            lab = np.array(seg.labels, np.uint8)
            if seg_net is not None and max(img.shape[:2]) >= TILE_WOOD_FROM * seg_net.side:
                lab[_tile_wood(img, lab.shape, seg_net)] = 2
            if cfg.thin_wood:
                # the segmenter's stride loses the twigs against the sky: dark ridges against the
                # sky near the tree become wood; the carving keeps only those the views agree on
                # in 3D (a power line or a roof edge behind the tree agrees with nothing)
                lab[thin_dark_lines(small, lab > 0, against=sky_mask(small)) & (lab == 0)] = 2
            if cfg.sky_gaps:
                # the segmenter fills the small gaps through the crown: its foliage coloured like the
                # sky above the tree is sky (wood and the thin ridges stay; the carving needs two views
                # to agree before a gap cuts a leaf)
                lab[sky_gaps(small, Segmentation(lab), ratio=3.0) & (lab == 1)] = 0
        return lab, small, small.shape[1] / sfm.sizes[k, 0]

    with ThreadPoolExecutor(max_workers=max(1, min(MATTE_THREADS, len(sfm.names)))) as pool:
        labels, images, scales = zip(*pool.map(one, range(len(sfm.names))))
    return list(labels), list(images), np.asarray(scales)


def _tile_wood(img: np.ndarray, shape: tuple, seg_net) -> np.ndarray:
    """Where the network, run on tiles of the full-size photo, sees wood: a (h, w) = ``shape`` mask.

    The matte comes from the photo seen whole at the network's 320 px, where the limbs under a
    crown are a pixel or less wide and their wood is lost (wood recall 13-29 % on the 24-view
    oak capture); on tiles at the photo's own size the network sees them
    (:func:`~treeform.segment.learned.wood_at_full_size`). Each matte pixel takes the most wood of
    the full-size pixels it covers, so a branch a pixel wide at full size stays a pixel wide.
    """
    import cv2
    import scipy.ndimage as ndi

    from treeform.segment.learned import wood_at_full_size

    wood = wood_at_full_size(img, seg_net)
    f = int(np.ceil(img.shape[1] / shape[1]))
    if f > 1:  # each pixel the most of the f x f block from it on, the block a nearest resize samples
        wood = ndi.maximum_filter(wood, size=f, origin=-(f // 2))
    if wood.shape != tuple(shape):
        wood = cv2.resize(wood, (shape[1], shape[0]), interpolation=cv2.INTER_NEAREST)
    return wood > 0.5


def _hull_box(sfm, axis, ring) -> tuple[np.ndarray, np.ndarray]:
    """The region the tree can occupy: around where the cameras look (``axis``), within their distance
    (``ring``, see :func:`_ring`), from well under the ground up."""
    c = sfm.centers
    if not ring > 0:
        raise InputError("the cameras do not surround the tree (a camera stands on its axis)")
    # the ground plane of a sparse model may be off: carve from well under the cameras
    low = float(c[:, 1].min()) - ring
    top = float(c[:, 1].max()) + 3.0 * ring
    return np.array([axis[0] - ring, low, axis[2] - ring]), np.array([axis[0] + ring, top, axis[2] + ring])


def _ring(sfm) -> tuple[np.ndarray, float]:
    """Where the cameras look (on the ground) and their median distance from it.

    The point nearest, in least squares, to every camera's optical axis seen from above
    (for cameras on an arc as well as on a circle); the cameras' median position when the
    axes are parallel.
    """
    c = sfm.centers[:, [0, 2]]
    d = sfm.cam_to_world[:, :3, 2][:, [0, 2]]
    d = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
    P = np.eye(2)[None] - d[:, :, None] * d[:, None, :]
    A, b = P.sum(0), np.einsum("nij,nj->i", P, c)
    xz = np.linalg.solve(A, b) if np.linalg.cond(A) < 1e6 else np.median(c, axis=0)
    center = np.array([xz[0], 0.0, xz[1]])
    return center, float(np.median(np.hypot(c[:, 0] - xz[0], c[:, 1] - xz[1])))


def _replicate(visible, carved, rng):
    """The visible skeleton grown by its own subtrees inside the carved hull (seed 002 §5.2's
    unconstrained growth, :mod:`~treeform.methods.multiview.replication`): as many end branches
    replaced as the visible skeleton has tips, up to ``REPLICATION_NODES`` nodes."""
    from scipy.spatial import cKDTree

    from treeform.methods.multiview.replication import grow_by_replication, replication_blocks

    blocks = replication_blocks(visible.positions, visible.parent)
    hull = cKDTree(carved.points)

    def inside(p):
        d, i = hull.query(p)
        return d <= carved.size[i]

    par = np.asarray(visible.parent)
    tips = int(np.count_nonzero(np.bincount(par[par >= 0], minlength=len(par)) == 0))
    pos, parent, stats = grow_by_replication(visible.positions, par, blocks, inside, rng, rounds=tips,
                                             max_nodes=REPLICATION_NODES)
    stats["blocks"] = len(blocks)
    return pos, parent, stats


def _crown_attractors(carved, branch: np.ndarray, n: int, rng) -> np.ndarray:
    """``n`` points spread over the leaf cells in proportion to their volume."""
    leaf = ~branch
    if not leaf.any() or n <= 0:
        return np.zeros((0, 3))
    pts, size = carved.points[leaf], carved.size[leaf]
    vol = size ** 3
    pick = rng.choice(len(pts), size=n, p=vol / vol.sum())
    return pts[pick] + (rng.random((n, 3)) - 0.5) * size[pick, None]


def reconstruct_multiview(photos, *, out=None, masks=None, config: MultiviewConfig | None = None,
                          progress: ProgressCallback | None = None, **options) -> MultiviewResult:
    """Reconstruct one tree from photos taken around it (seed 002).

    Parameters
    ----------
    photos : str, Path or sequence of paths
        A folder of photos (10–60 taken around the tree) or the files.
    out : path, optional
        Output folder: tree.glb, tree.obj, skeleton.json/.ply, preview.png, metrics.json,
        config.json, cameras.json, points.ply (written all or nothing).
    masks : path, optional
        A folder with the tree matte of each photo, ``<photo stem>.png`` (labels 0/1/2, or
        white = tree), used instead of the segmenter (seed 002 asks its user for strokes).
    config : MultiviewConfig, optional
    progress : callable, optional
        ``progress(stage, event, seconds)`` for :data:`STAGES`.
    **options
        Fields of :class:`MultiviewConfig` (override ``config``).

    Returns
    -------
    MultiviewResult

    Raises
    ------
    InputError
        Too few or unreadable photos, bad options.
    NoTreeFoundError
        The photos show no tree the mattes agree on.
    SfmError
        The photos cannot be registered (see :mod:`treeform.sfm`).
    """
    import dataclasses
    import time

    from treeform._shared.checks import check_known_options
    from treeform._shared.rng import as_rng
    from treeform.geometry import LOD_PRESETS, tree_mesh
    from treeform.growth.radii import branch_orders, pipe_model_radii
    from treeform.growth.space_colonization import space_colonization
    from treeform.io.outputs import check_out_dir
    from treeform.methods.multiview.branch_graph import branch_skeleton
    from treeform.methods.multiview.carve import (carve_tree, explain_wood, main_component, silhouette_fields,
                                                  tree_pieces)
    from treeform.methods.multiview.coherence import refine_rotations
    from treeform.methods.multiview.trunk import trunk_axis, trunk_diameter
    from treeform.sfm import load_photos, run_sfm, to_tree_frame
    from treeform.structures import TreeSkeleton

    cfg = dataclasses.replace(config or MultiviewConfig(), **check_known_options(MultiviewConfig, options)).validate()
    if masks is not None and not Path(masks).is_dir():
        raise InputError(f"--masks: not a folder: {masks}")
    if out is not None:
        out = check_out_dir(out)
    timer = StageTimer(progress)
    rng = as_rng(cfg.seed)

    with timer.stage("photos"):
        views = load_photos(photos, max_size=cfg.max_size)
    with timer.stage("sfm"):
        sfm = run_sfm(views, seed=cfg.seed)
    with timer.stage("frame"):
        by_name = {v.name: v.image for v in views}
        sfm = to_tree_frame(sfm, eye_height=cfg.eye_height, seed=cfg.seed, images=[by_name[n] for n in sfm.names])
    with timer.stage("matting"):
        labels, images, scales = _segment_views(views, sfm, cfg, masks)
        K = _scaled_K(sfm, scales)
        seen_tree = np.array([(lab > 0).mean() for lab in labels])
        if np.count_nonzero(seen_tree > 0.002) < max(3, len(labels) // 2):
            raise NoTreeFoundError("no tree found in the photos (the segmentation finds none in most views)")
    with timer.stage("carve"):
        axis, ring = _ring(sfm)
        lo, hi = _hull_box(sfm, axis, ring)

        fields = silhouette_fields(labels)  # the masks' distance maps, for all three carvings

        def coarse_hull():
            hull = carve_tree(K, sfm.cam_to_world, labels, box=(lo, hi), voxel=float((hi - lo).max()) / 96.0,
                              tolerance=cfg.tolerance, fields=fields)
            # the tree is the piece of the hull the cameras look at (a neighbouring tree or a hedge at the
            # ring's edge, seen only by the cameras across the ring, can survive the carving too)
            return hull.subset(main_component(hull, axis, 0.35 * ring))

        coarse = coarse_hull()
        if cfg.refine_poses and len(coarse) and sfm.n_cameras >= 4:
            # the SfM's cameras agree with the far scene its points lie on, not quite about the tree:
            # turn each so that the other views' hull fills its matte, then carve again
            t0 = time.perf_counter()
            pad = float(coarse.size.max())
            ref = refine_rotations(K, sfm.cam_to_world, [lab > 0 for lab in labels],
                                   (coarse.points.min(0) - pad, coarse.points.max(0) + pad))
            shift = np.linalg.norm(ref.shifts, axis=1) / np.array([max(lab.shape) for lab in labels])
            pose_refinement = {
                "rounds": ref.iterations,
                "shift_median_pct": round(100 * float(np.median(shift)), 4),
                "shift_max_pct": round(100 * float(np.max(shift)), 4),
                "outline_cost_before_px2": round(float(np.nanmedian(ref.cost_before)), 4),
                "outline_cost_after_px2": round(float(np.nanmedian(ref.cost_after)), 4),
                "seconds": round(time.perf_counter() - t0, 3)}
            sfm = dataclasses.replace(sfm, cam_to_world=ref.cam_to_world,
                                      meta={**sfm.meta, "pose_refinement": pose_refinement})
            if np.any(ref.shifts):  # none turned (too few views matched): the hull stands as carved
                coarse = coarse_hull()
        if len(coarse) == 0:
            raise NoTreeFoundError("no tree found: the views' tree masks do not agree on any volume")
        foot, height = _tree_extent(coarse)
        if foot[1] > 0:
            # a matte that missed the trunk's foot (shade, a hedge, the segmenter) leaves the hull
            # hanging above the SfM ground (y = 0 of the frame): the trunk goes down to it
            height += foot[1]
            foot[1] = 0.0
        # the trunk's foot stands on the ground: metres from the given height, else from the cameras'
        # eye height above the foot (the SfM ground plane of a sparse model is a weaker cue)
        above = float(np.median(sfm.centers[:, 1])) - foot[1]
        if cfg.height is not None:
            s = cfg.height / height
        elif above > 0:
            s = cfg.eye_height / above
        else:
            raise NoTreeFoundError("no tree found: the carved volume lies above the cameras")
        # origin at the trunk's foot
        sfm = sfm.transformed(s, np.eye(3), -s * foot)
        coarse_pts, coarse_size = s * (coarse.points - foot), s * coarse.size
        height *= s
        lo = np.array([-0.75 * height, -0.02 * height, -0.75 * height])
        hi = np.array([0.75 * height, 1.1 * height, 0.75 * height])
        ring = float(np.min(np.hypot(sfm.centers[:, 0], sfm.centers[:, 2])))
        lo[[0, 2]] = np.maximum(lo[[0, 2]], -0.95 * ring)
        hi[[0, 2]] = np.minimum(hi[[0, 2]], 0.95 * ring)
        voxel = height / cfg.cells
        carved = carve_tree(K, sfm.cam_to_world, labels, box=(lo, hi), voxel=voxel, tolerance=cfg.tolerance,
                            surface_voxel=max(voxel, height / cfg.surface_cells), images=images, fields=fields)
        # only what lies in the coarse hull's tree piece
        if len(carved):
            from scipy.spatial import cKDTree

            d, k = cKDTree(coarse_pts).query(carved.points, p=np.inf)
            carved = carved.subset(d <= 0.5 * coarse_size[k] + voxel)
            # the coarse piece can hold a neighbour's crown its coarse cells touched; at the fine cells
            # it stands apart, out of the trunk's column (on the 24-view willow capture 4 % of the hull,
            # 3 m beyond the crown, where the hidden branches grew a limb out to it)
            carved = carved.subset(tree_pieces(carved, np.zeros(3), 0.35 * ring, PIECE_GAP * height))
        if len(carved) == 0:
            raise NoTreeFoundError("no tree found: the views' tree masks do not agree on any volume")
        # the coarse cells placed the foot within half a coarse cell; the fine hull's foot is sharper.
        # Under the SfM ground, it wins (a sparse ground, fit to far hedges and facades, can sit
        # high); above it, the mattes missed the trunk's foot and the trunk goes down to the ground
        ground = -s * foot[1]
        fine_foot = min(float(_tree_extent(carved)[0][1]), ground)
        if abs(fine_foot) > 0.5 * voxel:
            top = height - fine_foot
            s2 = cfg.height / top if cfg.height is not None else \
                cfg.eye_height / (float(np.median(sfm.centers[:, 1])) - fine_foot)
            shift = np.array([0.0, -s2 * fine_foot, 0.0])
            sfm = sfm.transformed(s2, np.eye(3), shift)
            carved = carved.transformed(s2, shift)
            height, voxel = top * s2, voxel * s2
    with timer.stage("branches"):
        # branch points: where the views' mattes say wood, or where the hull is a thin tube (a bare
        # branch against the sky). Thinness alone is no test in a leafy crown: a porous crown's hull is
        # full of thin fragments (measured on a 24-view capture with the true mattes: the visible
        # skeleton strays 17 % of the height from the true branches with thinness, 0.9-4.9 % with votes)
        # a view's wood pixel is one limb at one depth, not every cell its ray crosses in the crown: the
        # votes go to the tree's cells that explain it best (on the 24-view oak capture the branch cells
        # went 79,000 -> 23,000 and the skeleton 3.3 -> 1.2 % of the height; BENCHMARKS.md)
        votes = explain_wood(carved.points, carved.wood, K, sfm.cam_to_world, labels, size=carved.size)
        branch = (votes > WOOD_VOTE) | (carved.thickness < max(2.0 * voxel, 0.006 * height))
        visible = branch_skeleton(carved.points[branch], carved.thickness[branch], link=2.5 * voxel,
                                  gap=PIECE_GAP * height, bin_width=max(3.0 * voxel, 0.008 * height),
                                  root=np.zeros(3)) if branch.sum() >= 2 else None
        if visible is None or visible.n_nodes < 2:
            # nothing thin seen: a trunk from the foot to the crown's bottom
            bottom = float(np.percentile(carved.points[:, 1], 2))
            ys = np.linspace(0.0, max(bottom, 0.1 * height), 6)
            visible = TreeSkeleton(np.column_stack([np.zeros(6), ys, np.zeros(6)]), np.arange(-1, 5),
                                   np.full(6, 0.02 * height))
        visible = _down_to_ground(visible)
        # the mattes' blur widens thin wood 2.5-3x (and a segmenter may take the trunk's shadow or a
        # bush behind it into the trunk): the trunk is measured in the photos at their own resolution
        # where they show it, else in the hull; a radius no more than 1 % of the height (open-grown
        # trees measure 0.4-1 %; the 24-view oak capture 0.6 %)
        diameter = None
        if masks is None and cfg.segmenter == "learned":
            diameter = trunk_diameter(sfm, [by_name[n] for n in sfm.names], trunk_axis(visible), height)
        trunk_from = "photos" if diameter is not None else "hull"
        trunk_r = 0.5 * diameter if diameter is not None else \
            float(np.median(visible.radius[: max(3, visible.n_nodes // 20)]))
        trunk_r = min(trunk_r, 0.01 * height)
    with timer.stage("growth"):
        att = _crown_attractors(carved, branch, 4000, rng)
        start_pos, start_par = visible.positions, visible.parent
        growth_stats = None
        if cfg.hidden_growth == "replication":
            start_pos, start_par, growth_stats = _replicate(visible, carved, rng)
        if len(att):
            res = space_colonization(att, start_pos, start_par, influence_radius=0.2 * height,
                                     kill_distance=0.035 * height, segment_length=0.015 * height,
                                     max_iterations=400, direction_weight=cfg.direction_weight,
                                     perception_angle=REPLICATION_CONE if cfg.hidden_growth == "replication"
                                     else None)
            pos, par = res.positions, res.parent
        else:
            pos, par = start_pos, start_par
        radius = pipe_model_radii(par, tip_radius=1.0)
        radius *= trunk_r / radius[0]
        radius = np.maximum(radius, 0.002)
        skeleton = TreeSkeleton(pos, par, radius, branch_orders(par, radius))
        skeleton.meta.update({"method": "multiview", "visible_nodes": int(visible.n_nodes)})
    with timer.stage("leaves"):
        leaf_stats = None
        if cfg.leaf_placement == "segments":
            from treeform.methods.multiview.leaf_segments import segmented_leaves

            leaf = ~branch
            foliage, leaf_stats = segmented_leaves(
                carved.points[leaf], skeleton, K, sfm.cam_to_world, labels, images,
                size=_leaf_size(carved.points[leaf], max(1, round(SHELL_SHARE * cfg.leaves)), height),
                leaves=cfg.leaves, rng=rng, seed=cfg.seed,
                card_scale=np.sqrt(COVER / PHOTO_COVER) if cfg.leaf_texture == "photo" else 1.0,
                threads=MATTE_THREADS, rounds=SYNTH_ROUNDS)
        else:
            foliage = _leaves(carved, branch, skeleton, height, cfg, rng)
        leaf_tex = None
        if cfg.leaf_texture == "photo" and len(foliage):
            foliage, leaf_tex = _photo_leaves(foliage, sfm, images, labels, rng, cfg.seed)
    with timer.stage("mesh"):
        mesh = tree_mesh(skeleton, foliage, max_triangles=LOD_PRESETS[cfg.lod], leaf_texture=leaf_tex, seed=cfg.seed)
        if cfg.height is not None:
            # --height is the tree's: the scale above made the carved hull that tall, and its top is a
            # tent over the crown (eye-level views cannot carve it), so the model came out shorter.
            # Everything is scaled about the foot (the origin, on the ground) until the model's top is
            # the given height.
            k = cfg.height / float(mesh.bounds()[1][1])
            if abs(k - 1.0) > 1e-3:
                skeleton = dataclasses.replace(skeleton, positions=skeleton.positions * k,
                                               radius=None if skeleton.radius is None else skeleton.radius * k)
                foliage = dataclasses.replace(foliage, positions=foliage.positions * k, size=foliage.size * k)
                sfm = sfm.transformed(k, np.eye(3), np.zeros(3))
                visible = dataclasses.replace(visible, positions=visible.positions * k,
                                              radius=None if visible.radius is None else visible.radius * k)
                carved = carved.transformed(k, np.zeros(3))
                trunk_r, height = trunk_r * k, height * k
                mesh = tree_mesh(skeleton, foliage, max_triangles=LOD_PRESETS[cfg.lod], leaf_texture=leaf_tex,
                                 seed=cfg.seed)
    with timer.stage("render"):
        # the leaves' colours are the photos', which already hold the day's light: lit again, they
        # render darker than the photos. Scale them (the tiles, or the cards' tints) until the model,
        # seen from the photos' cameras, has the photos' leaf colours (twice: the display encoding is
        # not linear).
        for _ in range(2):
            gain = _leaf_gain(mesh, sfm, images, labels)
            if gain is None or np.all(np.abs(gain - 1.0) < 0.03):
                break
            if leaf_tex is not None:
                leaf_tex = leaf_tex.copy()
                leaf_tex[..., :3] = np.clip(leaf_tex[..., :3] * gain, 0, 255).astype(np.uint8)
            else:
                foliage = foliage.with_colors(np.clip(foliage.color * gain, 0.0, 1.0))
            mesh = tree_mesh(skeleton, foliage, max_triangles=LOD_PRESETS[cfg.lod], leaf_texture=leaf_tex,
                             seed=cfg.seed)
        preview, iou = _preview(mesh, sfm, images, labels)
    metrics = {
        "photos": len(views), "registered": sfm.n_cameras, "unregistered": list(sfm.unregistered),
        "sfm_points": len(sfm.points), "carved_cells": len(carved),
        "branch_cells": int(branch.sum()), "visible_nodes": int(visible.n_nodes), "nodes": skeleton.n_nodes,
        "leaves": len(foliage), "triangles": mesh.n_triangles, "leaf_regions": leaf_stats,
        "replication": growth_stats,
        # the model's own top above the ground (y = 0): the carved hull's (hull_height_m) stands higher,
        # a tent over the crown that eye-level views cannot carve away
        "tree_height_m": round(float(mesh.bounds()[1][1]), 4), "hull_height_m": round(float(height), 4),
        "trunk_radius_m": round(trunk_r, 4), "trunk_radius_from": trunk_from,
        "scale_from": "height" if cfg.height is not None else "eye_height",
        "scale_warning": scale_warning(sfm.meta.get("frame", {}), cfg.height is not None),
        "registration_warning": registration_warning(len(views), sfm.unregistered),
        "consistency_warning": consistency_warning(sfm.names, iou, seen_tree) if len(iou) else None,
        "silhouette_iou_views": {str(n): round(float(v), 4) for n, v in zip(sfm.names, iou)},
        "silhouette_iou_median": round(float(np.median(iou)), 4) if len(iou) else None,
        "silhouette_iou_min": round(float(np.min(iou)), 4) if len(iou) else None,
        "sfm": sfm.meta,
    }
    metrics["seconds"] = {k: round(v, 3) for k, v in timer.timings.items()}
    result = MultiviewResult(skeleton, foliage, mesh, sfm, carved, branch, preview, metrics, cfg.to_dict(),
                             timer.timings)
    if out is not None:
        with timer.stage("export"):
            result.files = _export(out, result)
    metrics["seconds"] = {k: round(v, 3) for k, v in timer.timings.items()}
    metrics["total_seconds"] = round(sum(timer.timings.values()), 3)
    return result


def _leaf_size(points: np.ndarray, n: int, height: float, cover: float = COVER) -> float:
    """The card edge with which ``n`` clusters cover the crown's surface about once.

    The surface is about four times the crown's side view (a sphere's is), the side view is
    the mean area of the leaf cells seen along x and along z, and a cluster texture covers
    ``cover`` of its card; clipped to 0.8-8 % of the tree's height.
    """
    if len(points) == 0:
        return 0.02 * height
    g = height / 100.0
    cells = np.floor(points / g).astype(np.int64)
    side = 0.5 * (len(np.unique(cells[:, [0, 1]], axis=0)) + len(np.unique(cells[:, [2, 1]], axis=0))) * g * g
    return float(np.clip(np.sqrt(4.0 * side / (cover * n)), 0.008 * height, 0.08 * height))


def _leaves(carved, branch, skeleton, height, cfg, rng):
    """Leaf clusters where the photos see leaves: on the hull's surface, and a share on the twigs inside.

    The crown's surface is where the views' silhouettes are (cells within half a card of a
    silhouette's edge in some view, held by nearly every view's mask); clusters spread over
    it in proportion to the cells' area follow its bays and gaps, so the model's outline
    matches the photos' from every side (seed 002 §6 places its leaves from the photos too).
    The rest hang on the grown twigs, seen through the gaps. Each cluster takes the colour
    of the photos at its nearest leaf cell.
    """
    from scipy.spatial import cKDTree

    from treeform.growth.leaves import attach_leaves, twig_foliage
    from treeform.structures import Foliage

    leaf = ~branch
    size = _leaf_size(carved.points[leaf], max(1, round(SHELL_SHARE * cfg.leaves)), height,
                      PHOTO_COVER if cfg.leaf_texture == "photo" else COVER)
    crown_rgb = carved.colors[leaf] if leaf.any() else carved.colors
    base = np.median(crown_rgb, axis=0) / 255.0 if len(crown_rgb) else np.array([0.3, 0.45, 0.2])
    shell = np.flatnonzero(leaf & (carved.edge <= 0.5 * size) & (carved.support >= LEAF_SUPPORT))
    n_shell = round(SHELL_SHARE * cfg.leaves) if len(shell) else 0
    parts = []
    if n_shell:
        area = carved.size[shell] ** 2
        pick = shell[rng.choice(len(shell), size=n_shell, p=area / area.sum())]
        pos = carved.points[pick] + (rng.random((n_shell, 3)) - 0.5) * carved.size[pick, None]
        center = np.median(carved.points[leaf], axis=0)
        parts.append(attach_leaves(skeleton, pos, size=size, center=center, scatter=1.5, seed=rng))
    parts.append(twig_foliage(skeleton, leaf_color=base, size=size, leaves=cfg.leaves - n_shell, seed=rng))
    parts = [f for f in parts if len(f)]
    if not parts:
        return Foliage.empty()
    foliage = Foliage(*(np.concatenate([getattr(f, k) for f in parts]) for k in
                        ("positions", "normals", "up", "size", "color", "node")))
    if leaf.any():
        k = cKDTree(carved.points[leaf]).query(foliage.positions)[1]
        col = crown_rgb[k] / 255.0 * rng.normal(1.0, 0.06, (len(foliage), 1))
        foliage = foliage.with_colors(np.clip(col, 0, 1))
    return foliage


def _photo_leaves(foliage, sfm, images, labels, rng, seed):
    """The leaf cards textured with the photos' own crown: each card's tile cut from the view that sees it best.

    Seed 002 §6 takes its leaves from the photos. Every card is assigned the registered view
    that sees it (not hidden behind other cards) and that it faces most
    (:func:`~treeform.crown.photo_leaves.choose_views`); the cards a view sees turn to face it,
    and the tile is the photo under the card with the view's foliage matte as alpha
    (:func:`~treeform.crown.photo_leaves.views_leaf_atlas`), so the leaves carry the photos'
    texture. Then every texel is carved against all the views' masks
    (:func:`~treeform.crown.photo_leaves.carve_texels`): the visual hull at the texels'
    resolution, so what some photos see through the crown is a gap from every side (on the
    24-view oak capture the model's area beyond the true silhouette in novel views falls from
    29 % to 22 %). Returns the cards (white tints, uv set) and the atlas.
    """
    import scipy.ndimage as ndi

    from treeform.crown.photo_leaves import choose_views, face_camera, views_leaf_atlas

    cams = [sfm.render_camera(k, scale=labels[k].shape[1] / sfm.sizes[k, 0]) for k in range(len(labels))]
    masks = [lab > 0 for lab in labels]
    view, visible, shade = choose_views(foliage, cams, masks, images)
    for k in np.unique(view[visible]):
        foliage = face_camera(foliage, cams[k], visible & (view == k), rng)
    alphas = [ndi.gaussian_filter((lab == 1).astype(np.float32), 0.6) for lab in labels]
    white = foliage.with_colors(np.ones((len(foliage), 3)))
    atlas, foliage = views_leaf_atlas(white, cams, images, alphas, view, visible=visible, shade=shade, seed=seed,
                                      masks=[ndi.binary_dilation(mk, iterations=TEXEL_DILATE) if TEXEL_DILATE
                                             else mk for mk in masks],
                                      tolerance=TEXEL_TOLERANCE, spare=TEXEL_SPARE)
    return foliage, atlas


def _down_to_ground(skeleton):
    """The skeleton with its root on the ground (y = 0): where the mattes lost the trunk's foot (a
    hedge or a bench in front of it, a segmenter that misses it), the graph's root hangs above the
    ground, and the trunk goes straight down from it."""
    from treeform.structures import TreeSkeleton

    root = skeleton.positions[0]
    if root[1] <= 1e-6:
        return skeleton
    parent = np.concatenate([[-1], np.where(skeleton.parent < 0, 0, skeleton.parent + 1)])
    return TreeSkeleton(np.vstack([[root[0], 0.0, root[2]], skeleton.positions]), parent,
                        np.concatenate([skeleton.radius[:1], skeleton.radius]),
                        np.concatenate([skeleton.order[:1], skeleton.order]))


def _tree_extent(carved) -> tuple[np.ndarray, float]:
    """The trunk's foot (lowest cells' centre, on the ground) and the tree's height above it."""
    y = carved.points[:, 1]
    low = y <= np.percentile(y, 1) + 1e-9
    foot = carved.points[low].mean(0)
    foot[1] = float(y.min() - 0.5 * carved.size[np.argmin(y)])
    height = float(y.max() + 0.5 * carved.size[np.argmax(y)]) - foot[1]
    if not height > 0:
        raise NoTreeFoundError("no tree found: the carved volume lies under the ground")
    return foot, height


def _leaf_gain(mesh, sfm, images, labels, views: int = 4, width: int = 256):
    """Per-channel factor (3,) that brings the model's rendered leaves to the photos' leaf colours.

    Over a few registered views rendered small: the median photo colour over the pixels
    where the photo shows foliage and the model shows leaves, over the median rendered
    colour there; clipped to [0.5, 4]. None when they share too few pixels.
    """
    from PIL import Image

    from treeform.render import Renderer

    names = [p.name for p in mesh.parts]
    if "leaves" not in names:
        return None
    leaf_part = names.index("leaves")
    n = sfm.n_cameras
    photo_px, model_px = [], []
    renderer = None
    try:
        for k in sorted({(i * n) // views for i in range(views)}):
            h, w = labels[k].shape
            scale = width / sfm.sizes[k, 0]
            cam = sfm.render_camera(k, near=0.1, far=1000.0, scale=scale)
            if renderer is None:
                renderer = Renderer(cam, samples=1)
            renderer.camera = cam
            res = renderer.render(mesh)
            rh, rw = res.mask.shape
            lab = np.asarray(Image.fromarray(labels[k]).resize((rw, rh), Image.NEAREST))
            img = np.asarray(Image.fromarray(images[k]).resize((rw, rh), Image.BILINEAR))
            both = (res.part == leaf_part) & (lab == 1)
            photo_px.append(img[both])
            model_px.append(res.color[..., :3][both])
    finally:
        if renderer is not None:
            renderer.release()
    photo_px, model_px = np.concatenate(photo_px), np.concatenate(model_px)
    if len(photo_px) < 200:
        return None
    gain = np.median(photo_px, axis=0) / np.maximum(np.median(model_px, axis=0), 1.0)
    return np.clip(gain, 0.5, 4.0)


def _preview(mesh, sfm, images, labels):
    """Three input photos beside the model rendered from their cameras, and every view's silhouette IoU."""
    from treeform.render import Renderer
    from treeform.report.preview import compose_strip

    n = sfm.n_cameras
    iou = []
    tiles, names = [], []
    show = sorted({0, n // 3, (2 * n) // 3})
    renderers = {}  # the three shown views antialiased, the others' silhouettes at one sample (4x cheaper)
    try:
        for k in range(n):
            h, w = labels[k].shape
            cam = sfm.render_camera(k, near=0.1, far=1000.0, scale=w / sfm.sizes[k, 0])
            samples = 4 if k in show else 1
            if samples not in renderers:
                renderers[samples] = Renderer(cam, samples=samples)
            renderer = renderers[samples]
            renderer.camera = cam
            res = renderer.render(mesh)
            m = res.mask[:h, :w] > 0
            t = labels[k] > 0
            iou.append(float((m & t).sum() / max((m | t).sum(), 1)))
            if k in show:
                tiles += [images[k], res.rgb((255, 255, 255))]
                names += [f"photo {sfm.names[k]}", "model, same camera"]
    finally:
        for r in renderers.values():
            r.release()
    rows = [compose_strip(tiles[i:i + 2], labels=names[i:i + 2], height=300) for i in range(0, len(tiles), 2)]
    width = max(r.shape[1] for r in rows)
    rows = [np.pad(r, ((0, 6), (0, width - r.shape[1]), (0, 0)), constant_values=255) for r in rows]
    return np.concatenate(rows, axis=0), np.array(iou)


def _export(out, result) -> dict:
    from treeform.io.outputs import write_json, write_tree_outputs
    from treeform.io.ply import write_points_ply

    sfm, carved = result.sfm, result.carved
    lab = np.where(result.branch, 1, 2).astype(np.uint8)  # 1 branch, 2 leaf, 0 background (SfM points)
    pts = np.concatenate([carved.points, sfm.points])
    cols = np.concatenate([carved.colors, sfm.colors])
    labels = np.concatenate([lab, np.zeros(len(sfm.points), np.uint8)])
    return write_tree_outputs(
        out, mesh=result.mesh, skeleton=result.skeleton, preview=result.preview, config=result.config,
        metrics=result.metrics,
        extra=[lambda d: write_json(d / "cameras.json", sfm.cameras_json()),
               lambda d: write_points_ply(d / "points.ply", pts, cols, labels)])
