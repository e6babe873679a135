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

__all__ = ["STAGES", "LearnedReconstruction", "reconstruct", "dress_from_photo"]

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


def dress_from_photo(skeleton, foliage, bark_texture, leaf_texture, *, cfg: LearnedConfig, camera, image, seg,
                     layout, mpp: float, rbv=None, crown=None):
    """The grown tree's leaves and bark made to agree with the photo (``grow_tree``'s ``dress``).

    - Branches that project outside the tree mask's outline, and cards whose square does not lie
      mostly on the mask, go: the real tree lies inside the cone of its silhouette
      (:func:`treeform.crown.sampling.carve_to_silhouette`, ``cfg.carve``; the trunk stays). Past the
      photo's frame the outline is ``crown`` (``(canvas, offset)`` of
      :func:`~treeform.methods._single_photo.continued_crown`), where given.
    - Where the mask shows leaves (not the trunk below the crown) and no card projects, cards
      are added inside the RBV (:func:`treeform.crown.sampling.fill_silhouette`, ``cfg.fill``; needs
      ``rbv``).
    - With ``cfg.leaf_texture == "photo"``, the cards the camera sees turn to face it and every
      card shows its patch of the photo's crown (:func:`treeform.crown.photo_leaf_atlas`, as
      the envelope and abs routes do); the bark takes the photo's wood colour.
    """
    import scipy.ndimage as ndi

    from treeform.crown.layout import trunk_pixels
    from treeform.crown.sampling import carve_to_silhouette, fill_silhouette

    tree = seg.tree_mask
    leafy = tree & ~trunk_pixels(seg, layout)  # the trunk below the crown carries no leaves
    if cfg.carve:
        from treeform.methods._single_photo import on_canvas

        outline, offset = (on_canvas(tree, *crown), crown[1]) if crown is not None else (tree, (0, 0))
        skeleton, foliage = carve_to_silhouette(skeleton, foliage, camera, outline, offset=offset)
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
    from treeform.methods._single_photo import (continued_crown, load_and_segment, model_metrics, photo_camera,
                                                render_previews)

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

        # a crown the frame cuts goes on past it (rounded): the tree's height counts the continued top and
        # the carving keeps what grows there. The network sees the photo's own labels (shown the continued
        # crown, it drew volumes that fit the photo worse: front SSIM 0.50 -> 0.33 on Platanus occidentalis 1),
        # and its volume, drawn for a whole tree, is fitted to the part of it the photo shows
        crown, offset, whole = continued_crown(layout, enabled=cfg.beyond_frame)
        cut = crown.shape != seg.tree_mask.shape  # (a crown cut on the right alone has offset (0, 0))
        levels = predict_rbv(seg.labels)
        tree_h = float(cfg.tree_height or load_reference_height(species))
        norm = np.maximum(levels[cfg.rbv_level - 1], 1e-3)
        rbv = RadialBoundingVolume(norm * tree_h, tree_h)
        cam, mpp = photo_camera(width_px, height_px, whole, tree_h, cfg.fov_y)
        if cfg.fit_silhouette or cut:  # the photo fixes each layer's left and right extent; the network the rest
            from treeform.crown.rbv_fit import fit_rbv_to_silhouette

            rbv = fit_rbv_to_silhouette(rbv, cam, seg.tree_mask)
    with timer.stage("grow"):
        from treeform.methods.learned.grow import grow_tree

        wood = seg.wood_mask
        branch_mask = wood if wood.sum() >= 2 else None
        grown = grow_tree(species, seed=cfg.seed, rbv_volume=rbv, branch_mask=branch_mask, mask_scale=mpp,
                          mask_base=layout.base if branch_mask is not None else None,
                          trunk_path=layout.trunk_path, previews=False,
                          leaves=cfg.leaves, lod=cfg.lod, foliage=cfg.foliage, texture_size=cfg.texture_size,
                          bole=cfg.bole, dress=lambda *a: dress_from_photo(*a, cfg=cfg, camera=cam, image=image, seg=seg,
                                                            layout=layout, mpp=mpp, rbv=rbv,
                                                            crown=(crown, offset) if cut else None))
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
