"""Single photo -> 3D tree by learned perception and bi-modal growth (seed 003 §5, Fig. 2).

segmentation M (network) -> species U (species CNN on M) -> RBV R (cascaded CNN on M) ->
bi-modal growth of U's parameters inside R, its scaffold on M's wood -> leaves -> the tree
carved to the cone of M, filled out to it and its cards textured with the photo's crown
(:func:`dress_from_photo`, beyond the paper) -> mesh -> front / side / top renders and the
reprojection error against M -> the usual tree outputs.

Each arrow is one call into a domain folder; the networks run on onnxruntime
(:mod:`treeform.learn.infer`), nothing here imports torch.
"""

from __future__ import annotations

from contextlib import nullcontext
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from treeform import __version__
from treeform._shared.timing import ProgressCallback, StageTimer
from treeform.io.outputs import check_out_dir, start_tree_outputs, write_json
from treeform.methods.learned.config import LearnedConfig

__all__ = ["STAGES", "LearnedReconstruction", "reconstruct", "dress_from_photo", "fill_silhouette"]

STAGES = ("load", "segment", "species", "rbv", "grow", "render", "export")
"""Stage names reported through ``progress(stage, event, seconds)``, in order (``metrics["timings"]``
also holds the leaves and mesh times, spent inside grow)."""


@dataclass
class LearnedReconstruction:
    """Everything :func:`reconstruct` made; ``files`` maps output names to paths (if written)."""

    photo: object
    segmentation: object
    species: str
    species_probabilities: dict
    rbv: object
    camera: object
    skeleton: object
    foliage: object
    mesh: object
    metrics: dict
    config: LearnedConfig
    renders: dict = field(default_factory=dict)
    preview: np.ndarray | None = None
    files: dict = field(default_factory=dict)


def fill_silhouette(skeleton, foliage, camera, mask, rbv, *, mpp: float, depth_samples: int = 24, seed=0):
    """``foliage`` plus cards where the photo shows the tree and no card projects.

    The grown crown fills its RBV, not the photo's outline: where the mask has pixels more
    than half a card from every card's centre, new cards are laid on a grid of a card's
    size, each at a random depth along its pixel's ray where the ray runs inside the RBV (where
    it misses it, within the mask's row revolved about the row's centre, as seed 004 §3.5
    revolves the crown), hung on the nearest twig.
    """
    import scipy.ndimage as ndi

    from treeform.growth.leaves import attach_leaves
    from treeform.structures import Foliage

    rng = np.random.default_rng([int(seed), 7])
    size = float(np.median(foliage.size))
    r = max(1.0, 0.5 * size / mpp)  # a card's half edge in pixels
    h, w = mask.shape
    uv = camera.project(foliage.positions)[:, :2]
    centres = np.zeros(mask.shape, bool)
    ok = (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)
    centres[uv[ok, 1].astype(np.int64), uv[ok, 0].astype(np.int64)] = True
    holes = mask & (ndi.distance_transform_edt(~centres) > r)
    step = max(1, int(round(r)))
    grid = np.zeros_like(holes)
    oy, ox = rng.integers(0, step, 2)
    grid[oy::step, ox::step] = True
    vs, us = np.nonzero(holes & grid)
    if len(us) == 0:
        return foliage
    # depth: points along each pixel's ray between the RBV's front and back
    us, vs = us + rng.uniform(0, 1, len(us)), vs + rng.uniform(0, 1, len(vs))
    reach = float(rbv.physical_radii.max())
    cam_z = float(camera.position[2])
    depths = cam_z - np.linspace(reach, -reach, depth_samples)  # along the view axis (the camera looks down -Z)
    pts = camera.unproject(np.repeat(us, depth_samples), np.repeat(vs, depth_samples),
                           np.tile(depths, len(us))).reshape(len(us), depth_samples, 3)
    inside = rbv.contains(pts.reshape(-1, 3)).reshape(len(us), depth_samples)
    has = inside.any(1)
    score = np.where(inside, rng.uniform(0, 1, inside.shape), -1.0)
    chosen = pts[np.arange(len(us)), np.argmax(score, axis=1)]
    if not has.all():  # rays past the RBV: within the silhouette's row revolved about its centre
        miss = np.flatnonzero(~has)
        rows = mask.any(1)
        left = np.where(rows, mask.argmax(1), 0)
        right = np.where(rows, w - 1 - mask[:, ::-1].argmax(1), 0)
        row = np.clip(vs[miss].astype(np.int64), 0, h - 1)
        half = 0.5 * (right[row] - left[row] + 1) * mpp
        dx = (us[miss] - 0.5 * (left[row] + right[row] + 1)) * mpp
        zmax = np.sqrt(np.maximum(half ** 2 - dx ** 2, (0.1 * half) ** 2))
        z = rng.uniform(-1.0, 1.0, len(miss)) * zmax
        chosen[miss] = camera.unproject(us[miss], vs[miss], cam_z - z)
    new = attach_leaves(skeleton, chosen, size=size, center=rbv.origin + [0, 0.6 * rbv.physical_height, 0],
                        scatter=1.4, seed=rng)
    if len(new) == 0:
        return foliage
    color = np.tile(np.median(foliage.color, axis=0), (len(new), 1))
    return Foliage(np.concatenate([foliage.positions, new.positions]), np.concatenate([foliage.normals, new.normals]),
                   np.concatenate([foliage.up, new.up]), np.concatenate([foliage.size, new.size]),
                   np.concatenate([foliage.color, color]), np.concatenate([foliage.node, new.node]))


def dress_from_photo(skeleton, foliage, bark_texture, leaf_texture, *, cfg: LearnedConfig, camera, image, seg,
                     layout, mpp: float, rbv=None):
    """The grown tree's leaves and bark made to agree with the photo (``grow_tree``'s ``dress``).

    - Branches and cards whose centre projects outside the tree mask (grown by half a card) go:
      the real tree lies inside the cone of its silhouette (``cfg.carve``; the trunk stays).
    - Where the mask shows leaves (not the trunk below the crown) and no card projects, cards
      are added inside the RBV (:func:`fill_silhouette`, ``cfg.fill``; needs ``rbv``).
    - With ``cfg.leaf_texture == "photo"``, the cards the camera sees turn to face it and every
      card shows its patch of the photo's crown (:func:`treeform.crown.photo_leaf_atlas`, as
      the envelope and abs routes do); the bark takes the photo's wood colour.
    """
    import scipy.ndimage as ndi

    from treeform.crown.layout import trunk_pixels
    from treeform.crown.sampling import visual_hull_contains

    tree = seg.tree_mask
    leafy = tree & ~trunk_pixels(seg, layout)  # the trunk below the crown carries no leaves
    if cfg.carve:
        from dataclasses import replace

        half = max(1, int(round(0.5 * float(np.median(foliage.size)) / mpp))) if len(foliage) else 1
        # the silhouette's outline, not its gaps: a card is larger than most of them
        disk = np.hypot(*np.mgrid[-half:half + 1, -half:half + 1]) <= half
        grown = ndi.binary_fill_holes(ndi.binary_dilation(ndi.binary_closing(tree, disk, border_value=0), disk))
        # a branch ends where it leaves the silhouette for good: a node stays while it or a node
        # above it on its branches is inside (a limb crossing a gap of the mask is kept whole);
        # the trunk stays, as the mask may miss part of it
        inside = visual_hull_contains(camera, grown, skeleton.positions)
        for i in range(skeleton.n_nodes - 1, 0, -1):  # children come after their parents
            if inside[i]:
                inside[skeleton.parent[i]] = True
        skeleton, new = skeleton.prune(inside | (skeleton.order == 0))
        if len(foliage):
            old = foliage.node
            node = np.where(old >= 0, new[np.maximum(old, 0)], -1)
            kept = ((old < 0) | (node >= 0)) & visual_hull_contains(camera, grown, foliage.positions)
            foliage = replace(foliage.subset(kept), node=node[kept])
    if cfg.fill and len(foliage) and rbv is not None:
        foliage = fill_silhouette(skeleton, foliage, camera, leafy, rbv, mpp=mpp, seed=cfg.seed)
    if seg.wood_mask.sum() > 20:
        from treeform.geometry.textures import tint_texture

        bark_texture = tint_texture(bark_texture, np.median(image[seg.wood_mask], axis=0))
    if cfg.leaf_texture == "photo" and len(foliage):
        from treeform.crown.photo_leaves import camera_sees, face_camera, photo_leaf_atlas
        from treeform.geometry.textures import foliage_texture_kind
        from treeform.growth.species import load_species_appearance
        from treeform.segment.matting import sky_gaps

        visible, shade = camera_sees(foliage, camera, tree)
        foliage = face_camera(foliage, camera, visible, cfg.seed).with_colors(np.ones((len(foliage), 3)))
        alpha = ndi.gaussian_filter((leafy & ~sky_gaps(image, seg, ratio=3.0)) * seg.alpha, 0.6)
        look = load_species_appearance(skeleton.meta.get("species", "oak"))
        kind = look.leaf_type if cfg.foliage == "auto" else cfg.foliage
        leaf_texture, foliage = photo_leaf_atlas(foliage, camera, image, alpha, visible=visible, shade=shade,
                                                 seed=cfg.seed, kind=foliage_texture_kind(kind))
    return skeleton, foliage, bark_texture, leaf_texture


def reconstruct(photo, *, mask=None, out=None, config: LearnedConfig | None = None,
                progress: ProgressCallback | None = None, **options) -> LearnedReconstruction:
    """Reconstruct a 3D tree from one photo with the learned networks (seed 003 §5).

    Parameters
    ----------
    photo : path, ndarray (H, W, 3) uint8, or Photo
    mask : path or ndarray (H, W), optional
        User tree mask (white = tree) replacing the segmentation network.
    out : path, optional
        Directory for tree.glb, tree.obj (+ .mtl, textures), skeleton.json, skeleton.ply,
        preview.png, metrics.json, config.json and rbv.npz (the predicted radial bounding
        volume, in metres, what ``grow --rbv`` reads) — all or nothing.
    config : LearnedConfig, optional
    progress : callable, optional
        ``progress(stage, event, seconds)`` over :data:`STAGES`.
    **options
        Overrides of config fields, e.g. ``species="pine", seed=3, lod="low"``.

    Returns
    -------
    LearnedReconstruction

    Raises
    ------
    InputError, NoTreeFoundError, ModelError, OutputError
    """
    from treeform.methods._single_photo import load_and_segment, model_metrics, photo_camera, render_previews

    cfg = LearnedConfig.from_dict({**(config.to_dict() if config else {}), **options})
    out_dir = check_out_dir(out) if out is not None else None
    timer = StageTimer(progress)

    ph, seg, layout = load_and_segment(photo, mask, max_size=cfg.max_size, segmenter=cfg.segmenter, seed=cfg.seed,
                                       timer=timer)
    image = ph.image
    height_px, width_px = ph.shape
    with timer.stage("species"):
        from treeform.learn.infer import predict_species

        probs = predict_species(seg.labels)
        species = cfg.species or next(iter(probs))
    with timer.stage("rbv"):
        from treeform.growth.species import load_reference_height
        from treeform.learn.infer import predict_rbv
        from treeform.structures import RadialBoundingVolume

        levels = predict_rbv(seg.labels)
        tree_h = float(cfg.tree_height or load_reference_height(species))
        norm = np.maximum(levels[cfg.rbv_level - 1], 1e-3)
        rbv = RadialBoundingVolume(norm * tree_h, tree_h)
        cam, mpp = photo_camera(width_px, height_px, layout, tree_h, cfg.fov_y)
        if cfg.fit_silhouette:  # the photo fixes each layer's left and right extent; the network the rest
            from treeform.crown.rbv_fit import fit_rbv_to_silhouette

            rbv = fit_rbv_to_silhouette(rbv, cam, seg.tree_mask)
    with timer.stage("grow"):
        from treeform.methods.learned.grow import grow_tree

        wood = seg.wood_mask
        branch_mask = wood if wood.sum() >= 2 else None
        grown = grow_tree(species, seed=cfg.seed, rbv_volume=rbv, branch_mask=branch_mask, mask_scale=mpp,
                          mask_base=layout.base if branch_mask is not None else None, previews=False,
                          leaves=cfg.leaves, lod=cfg.lod, foliage=cfg.foliage, texture_size=cfg.texture_size,
                          dress=lambda *a: dress_from_photo(*a, cfg=cfg, camera=cam, image=image, seg=seg,
                                                            layout=layout, mpp=mpp, rbv=rbv))
        skeleton, foliage, mesh = grown.skeleton, grown.foliage, grown.mesh
        skeleton.meta.update({"method": "learned", "source": Path(ph.source).name if ph.source else None})
    for k in ("leaves", "mesh"):  # grow_tree timed these inside the grow stage
        timer.timings[k] = grown.metrics["timings"].get(k, 0.0)
    # the mesh files are written (threads) while the preview renders; all or nothing
    staged = start_tree_outputs(out_dir, mesh=mesh, skeleton=skeleton) if out_dir is not None else None
    with staged if staged is not None else nullcontext():
        with timer.stage("render"):
            from treeform.methods._single_photo import photo_metrics
            from treeform.methods.learned.grow import preview_lighting
            from treeform.report import photo_window, preview_strip

            # the front view is the photo's camera, widened to show the whole tree; side shares its scale
            renders = render_previews(mesh, front=cam, lighting=preview_lighting())
            window = photo_window(renders["front"].camera, cam)  # the photo's frame in the widened front view
            metrics = {
                **photo_metrics(renders, cam, image, seg.tree_mask),
                "species": species,
                "species_predicted": next(iter(probs)),
                "species_probabilities": {k: round(v, 4) for k, v in probs.items()},
                "tree_height": round(tree_h, 4),
                "rbv_level": cfg.rbv_level,
                **model_metrics(skeleton, foliage, mesh, photo_size=(width_px, height_px), metres_per_pixel=mpp),
            }
            preview = preview_strip(renders, photo=image, segmentation=seg, keep=window)
        result = LearnedReconstruction(ph, seg, species, probs, rbv, cam, skeleton, foliage, mesh, metrics, cfg, renders,
                                       preview)
        if out_dir is not None:
            with timer.stage("export"):
                from treeform.io import write_tree_outputs

                config_out = {"treeform": __version__, "method": "learned", "photo": ph.source, "config": cfg.to_dict()}
                result.files = write_tree_outputs(out_dir, mesh=mesh, skeleton=skeleton, preview=preview,
                                                  config=config_out, metrics=metrics,
                                                  extra=[lambda d: rbv.save(d / "rbv.npz")], staged=staged)
    metrics["timings"] = {k: round(v, 4) for k, v in timer.timings.items()}
    metrics["total_seconds"] = round(sum(v for k, v in timer.timings.items() if k not in ("leaves", "mesh")), 4)
    if out_dir is not None:
        write_json(out_dir / "metrics.json", metrics)
    return result
