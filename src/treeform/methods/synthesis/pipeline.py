"""Single photo -> 3D tree by analysis by synthesis (seed 004: Guénard et al. 2013).

photo -> segmentation -> foliage silhouette B and trunk (:func:`treeform.crown.layout.tree_layout`)
-> for each candidate (§5): the recursive foliage skeleton of n branches (§3,
:func:`treeform.skeleton.foliage_skeleton`) lifted to 3D in the revolved hull (§3.5,
:func:`treeform.skeleton.lift_to_3d`) -> the species' L-system grows branchlets and Bézier
leaves on it (§4, :func:`treeform.growth.lsystem.dress_skeleton`) -> silhouette from the
photo's camera -> eq. (3) -> the model maximising eq. (4) is kept and built at full detail:
B-spline generalized cylinders, leaves coloured from the photo -> the usual tree outputs, plus
the error against the number of tested models (Fig. 13) in metrics.json and candidates.png.

Each arrow is one call into a domain folder.
"""

from __future__ import annotations

from contextlib import nullcontext
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from treeform._shared.defaults import DEFAULT_SEGMENTER
from treeform import __version__
from treeform._shared.timing import ProgressCallback, StageTimer
from treeform.io.outputs import check_out_dir, start_tree_outputs, write_json
from treeform.structures.foliage import Foliage
from treeform.methods.synthesis.config import SPECIES_PRIORS, SynthesisConfig

__all__ = ["STAGES", "SynthesisReconstruction", "reconstruct", "build_candidate", "foliage_reach", "row_half_widths", "skeleton2d"]

STAGES = ("load", "segment", "species", "skeleton", "search", "model", "render", "export")
"""Stage names reported through ``progress(stage, event, seconds)``, in order."""

BARE_BOLE = 0.12
"""Fraction of the tree's height at the foot of the trunk that carries no twigs."""

EDGE_FIT = 1.0
"""A card whose centre lies ``d`` pixels inside the outline keeps at most ``2·EDGE_FIT·d`` pixels
of edge: it reaches the outline without overhanging it (1.8, an overhang, scored 5.4 % against
5.2 % median on the isolated photos: dense crowns need no overhang to fill the outline)."""

MIN_EDGE_SCALE = 0.3
"""Smallest fraction of its size a card keeps at the outline."""

SEARCH_LEAF_TEXTURE = 64
"""Texture edge of the leaf cards in the candidates' silhouette renders."""


@dataclass
class SynthesisReconstruction:
    """Everything :func:`reconstruct` made; ``files`` maps output names to paths (if written).

    ``candidates`` lists each tested model's proposal, error and eq. (4) score in test order;
    ``skeleton2d`` is the chosen model's 2D skeleton, in pixels of the reduced photo or, where the
    photo's frame cuts the crown, of the canvas around it that holds the continued crown (the photo
    at ``metrics["canvas_offset"]`` = ``[top, left]`` on it).
    """

    photo: object
    segmentation: object
    species: str
    camera: object
    skeleton2d: object
    skeleton: object
    foliage: object
    mesh: object
    candidates: list
    metrics: dict
    config: SynthesisConfig
    renders: dict = field(default_factory=dict)
    preview: np.ndarray | None = None
    files: dict = field(default_factory=dict)


def _leaf_size(crown_mask: np.ndarray, mpp: float) -> float:
    """Leaf-card edge in metres for the crown's scale: 1/10 of the crown's mean radius,
    clamped to 5–60 cm (a leaf cluster, like the other single-photo routes' cards)."""
    r = np.sqrt(crown_mask.sum() / np.pi) * mpp
    return float(np.clip(r / 10.0, 0.05, 0.8))


def foliage_reach(sk2d, crown_mask: np.ndarray) -> list:
    """Per skeleton point, how far its foliage reaches (pixels): the farthest crown pixel whose
    nearest skeleton point it is (a Voronoi partition of the crown among all branch points),
    smoothed along each branch. Twigs grown to this length fill the silhouette out to its edge,
    where the branches' own widths (the partition's half-width across a branch) stop short of
    the crown's outline beyond a branch tip or on the far side of an off-centre branch."""
    from scipy.spatial import cKDTree

    pts = np.concatenate([np.asarray(b, float) for b in sk2d.branches])
    ys, xs = np.nonzero(crown_mask[::2, ::2])
    reach = np.zeros(len(pts))
    if len(xs):
        d, k = cKDTree(pts).query(np.column_stack([xs * 2.0 + 0.5, ys * 2.0 + 0.5]))
        np.maximum.at(reach, k, d)
    rows = np.flatnonzero(crown_mask.any(1))
    trunk = np.asarray(sk2d.branches[0], float)
    y_base = float(trunk[:, 1].max()) if len(trunk) else 0.0
    y_bare = y_base - BARE_BOLE * (y_base - (rows.min() if len(rows) else y_base))
    out, i = [], 0
    for j, b in enumerate(sk2d.branches):
        r = reach[i:i + len(b)]
        i += len(b)
        if j == 0:  # a bare bole at the foot (no twigs reaching for the lawn)
            r = np.where(np.asarray(b, float)[:, 1] > y_bare, 0.0, r)
        if len(r) >= 3:  # running max then mean over neighbours: no single-point spikes or gaps
            r = np.maximum(np.maximum(r, np.r_[r[1:], r[-1]]), np.r_[r[0], r[:-1]])
            r = np.convolve(np.pad(r, 1, mode="edge"), np.ones(3) / 3.0, mode="valid")
        out.append(r)
    return out


def row_half_widths(mask: np.ndarray) -> np.ndarray:
    """(H,) half of each row's extent in ``mask`` (pixels), the max over a window of 2 % of the
    mask's height (0 for empty rows): the depth the revolved crown may have at that row."""
    import scipy.ndimage as ndi

    from treeform.crown.layout import row_extents

    rows, left, right = row_extents(mask)
    hw = np.where(rows, 0.5 * (right - left + 1), 0.0)
    ys = np.flatnonzero(rows)
    win = max(1, int(0.02 * (np.ptp(ys) + 1))) if len(ys) else 1
    return ndi.maximum_filter1d(hw, 2 * win + 1)


def _fits(points: np.ndarray, camera, edge_distance: np.ndarray, base, mpp: float, depth_bound,
          offset: tuple = (0, 0)) -> np.ndarray:
    """(P,) pixels between each point's projection and the silhouette's outside (0: outside the
    photo's silhouette or, with ``depth_bound``, outside the crown revolved about its rows' centres, §3.5).
    ``edge_distance``, ``depth_bound`` and ``base`` may lie on a canvas around the photo (``offset``
    = ``(top, left)`` of the photo on it)."""
    uvz = camera.project(points)
    h, w = edge_distance.shape
    u = np.floor(uvz[:, 0]).astype(np.int64) + int(offset[1])
    v = np.floor(uvz[:, 1]).astype(np.int64) + int(offset[0])
    ok = (u >= 0) & (u < w) & (v >= 0) & (v < h) & (uvz[:, 2] > 0)
    d = np.zeros(len(points))
    d[ok] = edge_distance[v[ok], u[ok]]
    if depth_bound is not None:
        row = np.clip(np.round(base[1] - points[:, 1] / mpp).astype(np.int64), 0, len(depth_bound) - 1)
        d[np.abs(points[:, 2]) > depth_bound[row] * mpp] = 0.0
    return d


def build_candidate(sk2d, proposal, *, species: str, base, mpp: float, camera, edge_distance: np.ndarray | None,
                    leaf_size: float, leaves: int | None = None, reach: list | None = None,
                    depth_bound: np.ndarray | None = None, trunk_radius: float | None = None,
                    offset: tuple = (0, 0), bole: float = 0.0):
    """One model of the generative model (§4) from a 2D skeleton and a proposal.

    Parameters
    ----------
    sk2d : Skeleton2D
    proposal : Proposal
    species : str
        The L-system preset; the proposal's density multiplies the preset's.
    base : (x, y)
        Trunk base pixel; ``mpp`` metres per pixel; ``camera`` the photo's camera.
    edge_distance : ndarray (H, W) or None
        Distance in pixels from each photo pixel to the outside of the tree mask (0 outside):
        leaves projecting outside are dropped and cards nearer the outline than half their
        edge shrink to fit (down to :data:`MIN_EDGE_SCALE`); None keeps every leaf as grown.
    leaf_size : float
        Card edge in metres.
    leaves : int, optional
        Cap on the number of cards.
    reach : list of (K_i,) arrays, optional
        Pixels per skeleton point (:func:`foliage_reach`), replacing the branches' widths.
    depth_bound : ndarray (H,), optional
        Per photo row, how deep (pixels) leaves may lie (:func:`row_half_widths`).
    trunk_radius : float, optional
        The photo's trunk radius in metres (:func:`~treeform.growth.lsystem.dress_skeleton`).
    offset : (int, int)
        ``(top, left)``: ``sk2d``, ``base``, ``edge_distance`` and ``depth_bound`` lie on a canvas
        around the photo, whose pixel (u, v) is the canvas's (u + left, v + top) (a crown continued
        past the frame, :func:`~treeform.methods._single_photo.continued_crown`).
    bole : float
        Share of the tree's height (its skeleton's, above the root) below which grown twigs go, with
        what grows past them (the given main branches stay); their leaves stay where they are, hung
        on the wood left above them.

    Returns
    -------
    (TreeSkeleton, Foliage)
    """
    from treeform.growth.lsystem import dress_skeleton, load_preset

    from treeform.skeleton import lift_to_3d

    polylines, radius = lift_to_3d(sk2d, base=base, metres_per_pixel=mpp, seed=proposal.cut_seed)
    if reach is not None:
        radius = [r * mpp for r in reach]
    density = load_preset(species).defines["density"] * proposal.density
    grown = dress_skeleton(polylines, radius, parent=sk2d.parent, preset=species, seed=proposal.leaf_seed,
                           trunk_radius=trunk_radius,
                           defines={"density": density, "spread": proposal.spread, "leaf_size": leaf_size})
    skeleton, foliage = grown.skeleton, grown.foliage
    # grown wood below the ground or the bole (twigs of a low crown hanging round the trunk's foot) goes,
    # with its subtree, and so does wood leaving the silhouette or the revolved crown
    ground = float(skeleton.positions[0, 1])
    floor = ground + bole * (float(skeleton.positions[:, 1].max()) - ground)
    fit = skeleton.positions[:, 1] >= ground
    if edge_distance is not None:
        fit &= _fits(skeleton.positions, camera, edge_distance, base, mpp, depth_bound, offset) > 0
    inside = fit & (skeleton.positions[:, 1] >= floor)
    if not inside.all():
        old = skeleton
        skeleton, new = skeleton.prune(grown.given | inside)
        if len(foliage):
            # a leaf whose twig went for the bole alone stays where it is, on the wood left above it
            node = np.where(new[foliage.node] >= 0, foliage.node, -1)
            low = (node < 0) & fit[foliage.node]
            node[low] = old.nearest_kept(new >= 0)[foliage.node[low]]
            foliage = foliage.subset(np.flatnonzero(node >= 0))
            foliage.node = new[node[node >= 0]]
    if len(foliage) and (foliage.positions[:, 1] < ground).any():
        foliage = foliage.subset(np.flatnonzero(foliage.positions[:, 1] >= ground))
    if edge_distance is not None and len(foliage):
        d = _fits(foliage.positions, camera, edge_distance, base, mpp, depth_bound, offset)
        keep = d > 0
        half = 0.5 * foliage.size / mpp
        scale = np.clip(EDGE_FIT * d / half, MIN_EDGE_SCALE, 1.0)
        idx = np.flatnonzero(keep)
        f = foliage
        foliage = Foliage(f.positions[idx], f.normals[idx], f.up[idx], f.size[idx] * scale[idx], f.color[idx],
                          f.node[idx], None if f.uv is None else f.uv[idx])
    if leaves is not None and len(foliage) > leaves:
        pick = np.random.default_rng([proposal.leaf_seed, 7]).choice(len(foliage), leaves, replace=False)
        foliage = foliage.subset(np.sort(pick))
    return skeleton, foliage


def reconstruct(photo, *, mask=None, out=None, config: SynthesisConfig | None = None,
                progress: ProgressCallback | None = None, **options) -> SynthesisReconstruction:
    """Reconstruct a 3D tree from one photo by analysis by synthesis (seed 004 §3–§5).

    Parameters
    ----------
    photo : path, ndarray (H, W, 3) uint8, or Photo
    mask : path or ndarray (H, W), optional
        User tree mask (white = tree) replacing the segmentation.
    out : path, optional
        Directory for tree.glb, tree.obj (+ .mtl, textures), skeleton.json, skeleton.ply,
        preview.png, metrics.json, config.json, skeleton2d.png / skeleton2d.json (the chosen
        2D skeleton over the photo) and candidates.png (Fig. 13) — all or nothing.
    config : SynthesisConfig, optional
    progress : callable, optional
        ``progress(stage, event, seconds)`` over :data:`STAGES`.
    **options
        Overrides of config fields, e.g. ``candidates=40, species="pine", seed=3``.

    Returns
    -------
    SynthesisReconstruction

    Raises
    ------
    InputError, NoTreeFoundError, ModelError, OutputError
    """
    from treeform.methods._single_photo import (continued_crown, load_and_segment, model_metrics, on_canvas,
                                                photo_camera, render_previews)

    cfg = SynthesisConfig.from_dict({**(config.to_dict() if config else {}), **options})
    out_dir = check_out_dir(out) if out is not None else None
    timer = StageTimer(progress)

    ph, seg, layout = load_and_segment(photo, mask, max_size=cfg.max_size, segmenter=cfg.segmenter, seed=cfg.seed,
                                       timer=timer)
    image, tree_mask = ph.image, seg.tree_mask
    height_px, width_px = ph.shape
    with timer.stage("species"):
        if cfg.species is not None:
            species, probs = cfg.species, {}
        else:
            from treeform.learn.infer import predict_species

            probs = predict_species(seg.labels)
            species = next(iter(probs))
    # a crown the frame cuts goes on past it (rounded): the 2D analysis and the fitting work on a canvas
    # around the photo that holds the continued crown, the tree's height counts its continued top, and
    # the search scores the photo's own view
    crown_c, offset, whole = continued_crown(layout, enabled=cfg.beyond_frame)
    top, left = offset
    tree_c = on_canvas(tree_mask, crown_c, offset)
    wood_c = on_canvas(seg.wood_mask, np.zeros_like(crown_c), offset)
    base_c = (layout.base[0] + left, layout.base[1] + top)
    cam, mpp = photo_camera(width_px, height_px, whole, cfg.tree_height, cfg.fov_y)
    from treeform.methods.synthesis.search import SilhouetteScorer, best_so_far, choose, prior, propose, score

    from treeform.skeleton import wood_visible

    shows_wood = wood_visible(tree_mask, seg.wood_mask)
    proposals = propose(cfg.candidates, species, n_branches=cfg.n_branches, seed=cfg.seed, wood=shows_wood)
    sk_cache: dict = {}
    with timer.stage("skeleton"):
        from treeform.skeleton import foliage_skeleton, wood_skeleton

        trunk = np.asarray(layout.trunk_path, np.float64) + np.array([left, top], np.float64)
        tol = SPECIES_PRIORS[species][2]

        def skeleton_for(p):
            key = ("wood",) if p.skeleton == "wood" else (p.n_branches, p.cut_seed)
            if key not in sk_cache:
                if p.skeleton == "wood":  # the whole tree: crown parts apart from the main one too
                    sk = wood_skeleton(tree_c, wood_c, trunk=trunk, levels=cfg.levels)
                    sk_cache[key] = (sk, foliage_reach(sk, tree_c))
                else:
                    sk = foliage_skeleton(crown_c, n_branches=p.n_branches, mode="tree",
                                          trunk=trunk, levels=cfg.levels, angle_tolerance=tol,
                                          seed=cfg.seed * 1009 + p.cut_seed)
                    sk_cache[key] = (sk, foliage_reach(sk, crown_c))
            return sk_cache[key]

        skeleton_for(proposals[0])
    with timer.stage("search"):
        import scipy.ndimage as ndi

        from treeform.geometry import leaf_texture, tree_mesh

        leaf_size = _leaf_size(crown_c, mpp)  # the whole crown's scale (continued past the frame)
        edge = ndi.distance_transform_edt(tree_c) if cfg.prune else None
        depth_bound = row_half_widths(tree_c) if cfg.prune else None
        trunk_radius = max(0.5 * layout.trunk_width * mpp, 0.01)  # the photo's trunk, not the pipe model's
        tex = leaf_texture(SEARCH_LEAF_TEXTURE, seed=cfg.seed, outline="bezier")
        scorer = SilhouetteScorer(cam, tree_mask, height=cfg.search_size)
        candidates = []
        try:
            for i, p in enumerate(proposals):
                sk2d, reach_px = skeleton_for(p)
                skel, fol = build_candidate(sk2d, p, species=species, base=base_c, mpp=mpp, camera=cam,
                                            edge_distance=edge, leaf_size=leaf_size, reach=reach_px,
                                            depth_bound=depth_bound, trunk_radius=trunk_radius, offset=offset,
                                            bole=cfg.bole)
                err, _ = scorer.error(tree_mesh(skel, fol, radial_segments=4, leaf_texture=tex, seed=cfg.seed))
                observed = p.skeleton == "wood"
                pm = 1.0 if observed else prior(p.n_branches, species)
                candidates.append({"index": i, **p.to_dict(), "n_first_order": int(sk2d.meta["n_first_order"]),
                                   "error": round(err, 6), "prior": round(pm, 6),
                                   "score": round(score(err, p.n_branches, species, observed=observed), 6),
                                   "leaves": len(fol)})
        finally:
            scorer.release()
        best = choose(candidates)
        chosen = proposals[best["index"]]
    with timer.stage("model"):
        from treeform.geometry import LOD_PRESETS, bspline_skeleton, tree_textures
        from treeform.geometry.textures import bark_normals, tint_texture
        from treeform.growth.leaves import color_leaves

        sk2d, reach_px = skeleton_for(chosen)
        skeleton, foliage = build_candidate(sk2d, chosen, species=species, base=base_c, mpp=mpp, camera=cam,
                                            edge_distance=edge, leaf_size=leaf_size, leaves=cfg.leaves,
                                            reach=reach_px, depth_bound=depth_bound,
                                            trunk_radius=trunk_radius, offset=offset, bole=cfg.bole)
        skeleton.meta.update({"method": "abs", "seed": cfg.seed, "species": species,
                              "source": Path(ph.source).name if ph.source else None, "n_leaves": len(foliage)})
        photo_leaves = cfg.leaf_texture == "photo" and len(foliage) > 0
        if len(foliage):
            from treeform.crown.photo_leaves import camera_sees, face_camera
            from treeform.crown.sampling import visual_hull_contains

            uvz = cam.project(foliage.positions)
            inside = visual_hull_contains(cam, tree_mask, foliage.positions)
            # the cards nearest the camera in some pixel (a depth buffer of the cards) are what the
            # photo shows: they face it and wear its patches; the others are shaded by depth
            visible, shade = camera_sees(foliage, cam, tree_mask)
            if photo_leaves:  # the cards the camera sees face it: each shows its patch of the photo unstretched
                foliage = face_camera(foliage, cam, visible, cfg.seed).with_colors(np.ones((len(foliage), 3)))
            else:  # leaf colours from the photo where a card projects onto the crown
                foliage = color_leaves(foliage, uvz[:, :2], inside, image,
                                       seg.foliage_mask if seg.foliage_mask.any() else tree_mask, seed=cfg.seed)
        smooth = bspline_skeleton(skeleton, samples_per_segment=2)
        bark_tex, _ = tree_textures(smooth, foliage, texture_size=cfg.texture_size, seed=cfg.seed)
        bark_normal = bark_normals(bark_tex, seed=cfg.seed)
        if seg.wood_mask.sum() > 20:
            bark_tex = tint_texture(bark_tex, np.median(image[seg.wood_mask], axis=0))
        if photo_leaves:
            import scipy.ndimage as ndi

            from treeform.crown.photo_leaves import photo_leaf_atlas
            from treeform.segment.matting import sky_gaps

            from treeform.crown.layout import trunk_pixels

            # the tree but its trunk (branches seen among the leaves belong to the crown's look), less
            # the sky seen through the crown, softened by a pixel
            leafy = tree_mask & ~trunk_pixels(seg, layout)
            alpha = ndi.gaussian_filter((leafy & ~sky_gaps(image, seg, ratio=3.0)) * seg.alpha, 0.6)
            leaf_tex, foliage = photo_leaf_atlas(foliage, cam, image, alpha, visible=visible, shade=shade,
                                                 seed=cfg.seed)
        else:
            leaf_tex = leaf_texture(256, seed=cfg.seed, outline="bezier")
        mesh = tree_mesh(smooth, foliage, max_triangles=LOD_PRESETS[cfg.lod], leaf_texture=leaf_tex,
                         bark_texture=bark_tex, bark_normal=bark_normal, seed=cfg.seed)
    # the mesh files are written (threads) while the preview renders; all or nothing
    staged = start_tree_outputs(out_dir, mesh=mesh, skeleton=skeleton) if out_dir is not None else None
    with staged if staged is not None else nullcontext():
        with timer.stage("render"):
            from treeform.methods._single_photo import photo_metrics
            from treeform.methods.learned.grow import preview_lighting
            from treeform.report import photo_window, preview_strip

            renders = render_previews(mesh, front=cam, lighting=preview_lighting())
            window = photo_window(renders["front"].camera, cam)
            errors = [c["error"] for c in candidates]
            metrics = {
                **photo_metrics(renders, cam, image, tree_mask),
                "species": species,
                **({"species_predicted": next(iter(probs)),
                    "species_probabilities": {k: round(v, 4) for k, v in probs.items()}} if probs else {}),
                "n_branches": chosen.n_branches,
                "n_first_order": int(sk2d.meta["n_first_order"]),
                "canvas_offset": [int(top), int(left)],
                "skeleton_source": chosen.skeleton,
                "wood_visible": bool(shows_wood),
                "candidates": candidates,
                "candidate_curve": [round(e, 6) for e in best_so_far(errors)],
                "search_error_first": errors[0],
                "search_error_best": best["error"],
                **model_metrics(skeleton, foliage, mesh, photo_size=(width_px, height_px), metres_per_pixel=mpp),
            }
            preview = preview_strip(renders, photo=image, segmentation=seg, keep=window)
        result = SynthesisReconstruction(ph, seg, species, cam, sk2d, skeleton, foliage, mesh, candidates, metrics, cfg,
                                         renders, preview)
        if out_dir is not None:
            with timer.stage("export"):
                result.files = _write_outputs(result, out_dir, image, staged)
    metrics["timings"] = {k: round(v, 4) for k, v in timer.timings.items()}
    metrics["total_seconds"] = round(sum(timer.timings.values()), 4)
    if out_dir is not None:
        write_json(out_dir / "metrics.json", metrics)
    return result


def _write_outputs(res: SynthesisReconstruction, out_dir: Path, image: np.ndarray, staged=None) -> dict:
    """Every output into ``out_dir``, all or nothing (:func:`treeform.io.write_tree_outputs`)."""
    import json

    from treeform.io import write_tree_outputs
    from treeform.io.images import write_png
    from treeform.report.plots import line_plot
    from treeform.skeleton import draw_skeleton

    errors = [c["error"] for c in res.candidates]
    curve = line_plot({"best so far": res.metrics["candidate_curve"], "each model": errors},
                      title="reprojection error (eq. 3) vs tested models", xlabel="number of tested models",
                      ylabel="error")
    top, left = res.metrics.get("canvas_offset", (0, 0))
    if tuple(res.skeleton2d.shape[:2]) != image.shape[:2]:  # the photo on its continued crown's canvas (grey past it)
        canvas = np.full((*res.skeleton2d.shape[:2], 3), 128, np.uint8)
        canvas[top:top + image.shape[0], left:left + image.shape[1]] = image
        image = canvas
    overlay = draw_skeleton(image, res.skeleton2d)
    sk_json = json.dumps(res.skeleton2d.to_dict())

    def extra(d: Path):
        write_png(curve, d / "candidates.png")
        write_png(overlay, d / "skeleton2d.png")
        (d / "skeleton2d.json").write_text(sk_json)

    config = {"treeform": __version__, "method": "abs", "photo": res.photo.source, "config": res.config.to_dict()}
    return write_tree_outputs(out_dir, mesh=res.mesh, skeleton=res.skeleton, preview=res.preview, config=config,
                              metrics=res.metrics, extra=[extra], staged=staged)


SKELETON2D_STAGES = ("load", "segment", "skeleton", "export")
"""Stage names of :func:`skeleton2d`."""


def skeleton2d(photo, *, out, mask=None, n_branches: int = 5, levels: int = 2, segmenter: str = DEFAULT_SEGMENTER,
               max_size: int = 640, seed: int = 0, source: str = "auto", progress: ProgressCallback | None = None):
    """The 2D analysis of seed 004 alone: the photo's branch skeleton drawn over it (§3).

    Parameters
    ----------
    photo : path, ndarray (H, W, 3) uint8, or Photo
    out : path
        The overlay PNG (partition, cuts, branches by order over the photo); the polylines go
        beside it as JSON (same name, ``.json``): pixel coordinates of the reduced photo.
    mask : path or ndarray (H, W), optional
        User tree mask (white = tree) replacing the segmentation.
    n_branches, levels : int
        First-order branches (foliage skeleton only) and branch orders.
    segmenter : {"classical", "learned"}
    max_size : int
        Long side the photo is reduced to.
    seed : int
    source : {"auto", "foliage", "wood"}
        "foliage": :func:`treeform.skeleton.foliage_skeleton` on the crown (§3, branches
        inferred from the outline); "wood": :func:`treeform.skeleton.wood_skeleton` (the
        visible wood's shortest paths to the base); "auto": wood when at least
        :data:`~treeform.skeleton.WOOD_VISIBLE` of the tree's pixels are wood (leafless and
        sparse crowns), else foliage.

    Returns
    -------
    (Skeleton2D, dict)
        The skeleton and ``{"png": path, "json": path}``.
    """
    import json

    from treeform._shared.checks import check_choice, check_int
    from treeform.crown.layout import tree_layout
    from treeform.io._atomic import atomic_paths
    from treeform.io.images import write_png
    from treeform.io.outputs import check_out_file
    from treeform.methods._single_photo import load_photo, segment_or_mask
    from treeform.skeleton import draw_skeleton, foliage_skeleton, wood_skeleton, wood_visible

    check_int(n_branches, "n_branches", 1, 32)
    check_int(levels, "levels", 1, 3)
    check_choice(segmenter, "segmenter", ("classical", "learned"))
    check_choice(source, "source", ("auto", "foliage", "wood"))
    png = check_out_file(out, "-o", suffix=".png")
    timer = StageTimer(progress)
    with timer.stage("load"):
        ph, user_mask = load_photo(photo, mask, max_size=max_size)
    with timer.stage("segment"):
        seg = segment_or_mask(ph.image, user_mask, segmenter=segmenter, seed=seed)
        layout = tree_layout(seg)
    with timer.stage("skeleton"):
        trunk = np.asarray(layout.trunk_path, np.float64)
        if source == "auto":
            source = "wood" if wood_visible(seg.tree_mask, seg.wood_mask) else "foliage"
        if source == "wood":
            sk = wood_skeleton(seg.tree_mask, seg.wood_mask, trunk=trunk, levels=levels)
        else:
            sk = foliage_skeleton(layout.crown_mask, n_branches=n_branches, mode="tree", trunk=trunk, levels=levels,
                                  seed=seed)
    with timer.stage("export"):
        overlay = draw_skeleton(ph.image, sk)
        doc = {"photo": ph.source, "photo_size": [ph.shape[1], ph.shape[0]], **sk.to_dict()}
        js = png.with_suffix(".json")
        with atomic_paths([js, png]) as (tj, tp):
            tj.write_text(json.dumps(doc))
            write_png(overlay, tp)
    return sk, {"png": png, "json": js}
