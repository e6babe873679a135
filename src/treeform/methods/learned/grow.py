"""Species preset -> leafy 3D tree by phenomenological growth (seed 003 §4.3, Appendix Tables 2–3).

Each stage is one call into a domain folder: :func:`treeform.growth.phenomenological.grow`
(skeleton), :func:`treeform.growth.leaves.twig_foliage` (leaf clusters on the twigs),
:func:`treeform.geometry.tree_mesh` (bark tubes + leaf cards under a triangle budget),
:class:`treeform.render.Renderer` (previews) and :mod:`treeform.io` (files, written
atomically: a staging folder, then renames). Under a triangle budget (``lod`` other than
``"full"``) only the leaf clusters the budget keeps are generated, enlarged as the LOD would
enlarge a thinned crown (:func:`treeform.geometry.foliage_budget`), so ``leaves`` in the
metrics counts those.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from treeform import __version__
from treeform._shared.errors import InputError
from treeform._shared.rng import as_rng
from treeform._shared.timing import ProgressCallback, StageTimer
from treeform.io.outputs import check_out_dir, write_json, write_staged
from treeform.methods.learned.config import GrowConfig
from treeform.structures import Foliage, Mesh, TreeSkeleton

if TYPE_CHECKING:  # pragma: no cover
    from treeform.growth.phenomenological import GrowthParameters

__all__ = ["GrowResult", "OUTPUT_FILES", "STAGES", "grow_tree", "shape_metrics", "preview_lighting", "write_staged"]

STAGES = ("grow", "leaves", "mesh", "render", "metrics", "export")
"""Stage names reported through ``progress(stage, event, seconds)``, in order."""

OUTPUT_FILES = ("tree.glb", "tree.obj", "tree.mtl", "skeleton.json", "skeleton.ply", "preview.png",
                "metrics.json", "config.json")


@dataclass
class GrowResult:
    """Everything :func:`grow_tree` made; ``files`` maps output names to paths (if written).

    ``parameters`` are the growth parameters used (the species' with the overrides applied);
    ``renders`` holds the front / side / top :class:`~treeform.render.RenderResult`;
    ``preview`` is the (H, W, 3) uint8 strip of the three renders.
    """

    skeleton: TreeSkeleton
    foliage: Foliage
    mesh: Mesh
    parameters: "GrowthParameters"
    config: GrowConfig
    metrics: dict
    renders: dict = field(default_factory=dict)
    preview: np.ndarray | None = None
    files: dict = field(default_factory=dict)


# ------------------------------------------------------------------------------------ helpers
def shape_metrics(skeleton: TreeSkeleton) -> dict:
    """Tree-form numbers of a skeleton (metres; Y up).

    Height and crown extents are :mod:`treeform.metrics`' own (the same numbers
    ``treeform metrics`` reports for the tree's skeleton.json or GLB); the shape ratios use a
    spread that a lone long branch does not move.

    Returns
    -------
    dict
        ``height`` (:func:`~treeform.metrics.tree_height`: highest node above the base),
        ``crown_extent_x``, ``crown_extent_z`` and ``crown_width`` (their mean), from
        :func:`~treeform.metrics.treeform_metrics.crown_extents` of the nodes;
        ``crown_spread`` (mean of the 2–98 % percentile spreads of the nodes along X and Z,
        robust to outliers), ``crown_base`` (5th percentile of the tips' heights),
        ``crown_height`` (``height - crown_base``), ``crown_flatness`` (crown height / crown
        spread), ``slenderness`` (height / crown spread) and ``tip_direction_y`` (mean Y of the
        unit directions of the terminal segments: < 0 means twigs point below horizontal).

    Examples
    --------
    >>> sk = TreeSkeleton(np.array([[0, 0, 0], [0, 2, 0], [1, 2, 0.], [-1, 2, 0]]), np.array([-1, 0, 1, 1]))
    >>> m = shape_metrics(sk)
    >>> m["height"], m["crown_width"], m["tip_direction_y"]
    (2.0, 1.0, 0.0)
    """
    from treeform.metrics.treeform_metrics import crown_extents, tree_height

    p = skeleton.positions
    tips = skeleton.tips()
    height = tree_height(skeleton)
    crown = crown_extents(skeleton)
    ext = [np.percentile(p[:, k], 98) - np.percentile(p[:, k], 2) for k in (0, 2)]
    spread = float(max(np.mean(ext), 1e-6))
    tip_y = p[tips, 1]
    base = float(np.percentile(tip_y, 5)) if len(tips) else 0.0
    d = p[tips] - p[skeleton.parent[tips].clip(0)]
    d = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
    return {
        "height": round(height, 4),
        "crown_extent_x": round(crown["crown_extent_x_m"], 4),
        "crown_extent_z": round(crown["crown_extent_z_m"], 4),
        "crown_width": round(crown["crown_width_m"], 4),
        "crown_spread": round(spread, 4),
        "crown_base": round(base, 4),
        "crown_height": round(height - base, 4),
        "crown_flatness": round((height - base) / spread, 4),
        "slenderness": round(height / spread, 4),
        "tip_direction_y": round(float(d[:, 1].mean()) if len(tips) else 0.0, 4),
    }


def preview_lighting():
    """The soft, camera-relative :class:`~treeform.render.Lighting` of the previews."""
    from treeform.render import Lighting

    # soft, camera-relative light: every view is lit alike and the leaves keep their colour
    return Lighting(direction=(-0.4, 0.6, 0.7), key=(0.5, 0.5, 0.46), sky=(0.75, 0.77, 0.8),
                    ground=(0.5, 0.49, 0.45), camera_relative=True)


# ------------------------------------------------------------------------------------ pipeline
def _read_branch_mask(path) -> np.ndarray:
    """A branch mask file (white = branch) at its own size, as (H, W) bool."""
    from PIL import Image

    from treeform.io import read_mask

    try:
        with Image.open(path) as im:
            size = im.size
    except FileNotFoundError:
        raise InputError(f"--mask {path}: no such file") from None
    except Exception as exc:
        raise InputError(f"--mask {path}: not an image ({type(exc).__name__})") from None
    mask = read_mask(path, (size[1], size[0]))
    if mask.sum() < 2:
        raise InputError(f"--mask {path}: no branch pixels (white = branch)")
    return mask


def grow_tree(species: str = "oak", *, seed: int = 0, out=None, progress: ProgressCallback | None = None,
              config: GrowConfig | None = None, rbv_volume=None, branch_mask: np.ndarray | None = None,
              mask_scale: float | None = None, mask_base=None, trunk_path=None, previews: bool = True, dress=None,
              **overrides) -> GrowResult:
    """Grow a leafy, textured 3D tree of a species (seed 003 §4.3, Appendix Tables 2–3).

    Parameters
    ----------
    species : str or path-like
        A preset (acacia, apple, willow, maple, birch, oak, pine) or a species JSON file.
    seed : int
        Same species + options + seed -> byte-identical ``skeleton.json``.
    out : path, optional
        Directory to write tree.glb, tree.obj (+ .mtl, textures), skeleton.json,
        skeleton.ply, preview.png, metrics.json and config.json; files appear only when
        every stage succeeded.
    progress : callable, optional
        ``progress(stage, event, seconds)`` for the stages in :data:`STAGES`.
    config : GrowConfig, optional
        Base configuration (``species``, ``seed`` and ``out`` given here win).
    rbv_volume : RadialBoundingVolume, optional
        In-memory RBV for bi-modal growth (instead of the ``rbv`` file of the config).
    branch_mask : ndarray, shape (H, W), bool, optional
        In-memory branch mask (instead of the ``mask`` file), with its ``mask_scale``
        (metres per pixel) and ``mask_base`` ((column, row) of the tree base); see
        :func:`~treeform.growth.bimodal.bimodal_grow`; ``trunk_path`` ((K, 2) pixels, base first) is
        the photo's trunk the scaffold's one stem follows.
    previews : bool
        Render the front / side / top preview strip (callers that render their own views
        turn it off).
    dress : callable, optional
        ``dress(skeleton, foliage, bark_texture, leaf_texture) -> (skeleton, foliage,
        bark_texture, leaf_texture)``, applied before the mesh is built: a photo route cuts
        the branches and cards outside the photo's silhouette and textures the rest with the photo.
    **overrides
        :class:`GrowConfig` fields (``leaves=5000, lod="low", leaves_per_twig=2, ...``) or
        growth parameters (``age=12, growth_rate=2.5, ...``; see
        :class:`~treeform.growth.phenomenological.GrowthParameters`).

    Returns
    -------
    GrowResult

    Raises
    ------
    InputError
        Unknown species (the message lists the known ones), option or parameter.
    OutputError
        ``out`` cannot be written.
    """
    from treeform.growth.phenomenological import GrowthParameters
    from treeform.growth.species import (load_marker_density, load_perception_angle, load_species,
                                         load_species_appearance)

    base = config.to_dict() if config is not None else {}
    cfg_names = {f.name for f in fields(GrowConfig)}
    par_names = {f.name for f in fields(GrowthParameters)}
    cfg_over = {k: v for k, v in overrides.items() if k in cfg_names}
    par_over = {k: v for k, v in overrides.items() if k in par_names and k not in cfg_names}
    unknown = sorted(set(overrides) - cfg_names - par_names)
    if unknown:
        raise InputError(f"unknown option(s) {', '.join(unknown)}; options: {', '.join(sorted(cfg_names))}; "
                         f"growth parameters: {', '.join(sorted(par_names))}")
    params_over = {**base.get("params", {}), **par_over}
    cfg = GrowConfig.from_dict({**base, **cfg_over, "species": str(species), "seed": seed, "params": params_over,
                                "out": None if out is None else str(out)})
    out_dir = check_out_dir(cfg.out) if cfg.out is not None else None
    params = GrowthParameters.from_dict(cfg.params, base=load_species(cfg.species))
    look = load_species_appearance(cfg.species)
    timer = StageTimer(progress)
    rng = as_rng(cfg.seed)

    with timer.stage("grow"):
        if cfg.rbv is None and rbv_volume is None:
            from treeform.growth.phenomenological import grow

            skeleton = grow(params, seed=cfg.seed)
        else:
            from treeform.growth.bimodal import bimodal_grow
            from treeform.structures import RadialBoundingVolume

            rbv = rbv_volume if rbv_volume is not None else RadialBoundingVolume.load(cfg.rbv)
            mask = branch_mask if branch_mask is not None else (
                _read_branch_mask(cfg.mask) if cfg.mask is not None else None)
            skeleton = bimodal_grow(params, rbv, mask=mask, mask_scale=mask_scale, mask_base=mask_base,
                                    trunk_path=trunk_path,
                                    seed=cfg.seed, perception_angle=load_perception_angle(cfg.species),
                                    marker_density=load_marker_density(cfg.species), bole=cfg.bole)
        skeleton.meta["species"] = Path(cfg.species).stem
    with timer.stage("leaves"):
        from treeform.geometry import LOD_PRESETS, foliage_budget
        from treeform.growth.leaves import twig_foliage, twig_nodes

        n_leaves, leaf_size, factor = cfg.leaves, cfg.leaf_size or look.leaf_size, 1.0
        if LOD_PRESETS[cfg.lod] is not None:  # generate only the clusters the budget keeps, enlarged as the LOD would
            if n_leaves is None:
                n_leaves = int(round(cfg.leaves_per_twig * len(twig_nodes(skeleton, cfg.twig_tips))))
            n_leaves, factor = foliage_budget(skeleton, n_leaves, max_triangles=LOD_PRESETS[cfg.lod],
                                              radial_segments=cfg.radial_segments)
            leaf_size *= factor
        foliage = twig_foliage(skeleton, leaf_color=look.leaf_color, size=leaf_size, leaves=n_leaves,
                               leaves_per_twig=cfg.leaves_per_twig, twig_tips=cfg.twig_tips, seed=rng)
        skeleton.meta["n_leaves"] = len(foliage)  # so `treeform metrics` on the files reports the count
    with timer.stage("mesh"):
        from treeform.geometry import LOD_PRESETS, tree_mesh, tree_textures
        from treeform.geometry.textures import bark_normals

        kind = look.leaf_type if cfg.foliage == "auto" else cfg.foliage
        # the leaf texture is sized for the species' cards, not the budget's enlarged ones (as before the budget step)
        sized = foliage if factor == 1.0 else replace(foliage, size=foliage.size / factor)
        bark_tex, leaf_tex = tree_textures(skeleton, sized, foliage_kind=kind, texture_size=cfg.texture_size,
                                           seed=cfg.seed)
        bark_normal = bark_normals(bark_tex, seed=cfg.seed)
        if dress is not None:
            skeleton, foliage, bark_tex, leaf_tex = dress(skeleton, foliage, bark_tex, leaf_tex)
            skeleton.meta["n_leaves"] = len(foliage)
        mesh = tree_mesh(skeleton, foliage, max_triangles=LOD_PRESETS[cfg.lod], radial_segments=cfg.radial_segments,
                         leaf_texture=leaf_tex, bark_texture=bark_tex, bark_normal=bark_normal, seed=cfg.seed)
    renders, preview = {}, None
    if previews:
        with timer.stage("render"):
            from treeform.methods._single_photo import render_previews
            from treeform.report import preview_strip

            # every view framed on the whole tree (render_size pixels high); side at the front's scale
            renders = render_previews(mesh, lighting=preview_lighting(), fov_y=cfg.fov_y, size=cfg.render_size)
            preview = preview_strip(renders)
    metrics = {
        "species": skeleton.meta["species"],
        "seed": cfg.seed,
        "nodes": skeleton.n_nodes,
        "branches": skeleton.n_nodes,
        "tips": int(len(skeleton.tips())),
        "leaves": len(foliage),
        "vertices": mesh.n_vertices,
        "triangles": mesh.n_triangles,
        **shape_metrics(skeleton),
    }
    result = GrowResult(skeleton, foliage, mesh, params, cfg, metrics, renders, preview)
    if out_dir is not None:
        with timer.stage("metrics"):  # seed 003 §6 tree-form metrics (LAI and MRT: ~0.4 s for an oak)
            from treeform.metrics import tree_metrics

            metrics["tree_form"] = tree_metrics(skeleton, foliage)
        with timer.stage("export"):
            result.files = _write_outputs(result, out_dir)
    metrics["timings"] = {k: round(v, 4) for k, v in timer.timings.items()}
    metrics["total_seconds"] = round(sum(timer.timings.values()), 4)
    if out_dir is not None:
        write_json(out_dir / "metrics.json", metrics)
    return result


def _write_outputs(res: GrowResult, out_dir: Path) -> dict:
    """Write every output of a grow run into ``out_dir`` all-or-nothing (:func:`treeform.io.write_tree_outputs`)."""
    from treeform.io import write_tree_outputs

    config = {"treeform": __version__, "method": "learned.grow", "config": res.config.to_dict(),
              "parameters": res.parameters.to_dict()}
    return write_tree_outputs(out_dir, mesh=res.mesh, skeleton=res.skeleton, preview=res.preview, config=config,
                              metrics=res.metrics)
