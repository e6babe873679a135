"""Single photo -> 3D tree by crown envelope + radial distance map + space colonization (seed 001 §3).

Each stage is one call into a domain folder; this module only composes them, moves
between pixel and world coordinates (metres, Y up, camera on +Z looking at -Z) and
writes the outputs atomically.
"""

from __future__ import annotations

import math
from contextlib import nullcontext
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

import numpy as np

from treeform import __version__
from treeform._shared.rng import as_rng
from treeform._shared.timing import ProgressCallback, StageTimer
from treeform.io.outputs import check_out_dir, start_tree_outputs, write_json
from treeform.methods._single_photo import load_photo, photo_camera, render_previews, segment_or_mask
from treeform.methods.envelope.config import EnvelopeConfig, leader_direction_weight
from treeform.structures import Camera, Foliage, Mesh, Photo, RadialDistanceMap, Segmentation, TreeSkeleton

OUTPUT_FILES = ("tree.glb", "tree.obj", "tree.mtl", "skeleton.json", "skeleton.ply", "preview.png",
                "metrics.json", "config.json")

CLUMP_LEAF_WIDTH = 0.2
"""Width (sigma) of a foliage clump's leaf density, as a fraction of the clumps' spacing."""
CLUMP_BRANCH_WIDTH = 0.25
"""Width of a clump's attractor density (wider: the twigs reach every leaf of the clump)."""
CLUMP_BRANCH_FLOOR = 0.1
"""Attractor density between the clumps (limbs cross the gaps to reach them; also bounds the
sampling's rejections in a crown far longer than wide)."""

STAGES = ("load", "segment", "envelope", "relief", "rdm", "attractors", "colonize", "leaves", "mesh",
          "render", "export")


@dataclass
class Reconstruction:
    """Everything :func:`reconstruct` made; ``files`` maps output names to paths (if written)."""

    photo: Photo
    segmentation: Segmentation
    camera: Camera
    envelope_vertices: np.ndarray
    envelope_faces: np.ndarray
    rdm: RadialDistanceMap
    skeleton: TreeSkeleton
    foliage: Foliage
    mesh: Mesh
    metrics: dict
    config: EnvelopeConfig
    renders: dict = field(default_factory=dict)
    preview: np.ndarray | None = None
    files: dict = field(default_factory=dict)


def _pixels_to_world(cam: Camera, m: float, uvz: np.ndarray) -> np.ndarray:
    """(column, row, height-in-pixels) -> world, by unprojecting at depth D - z·m."""
    dist = float(np.linalg.norm(np.subtract(cam.position, cam.target)))
    return cam.unproject(uvz[:, 0], uvz[:, 1], dist - uvz[:, 2] * m)


def _trunk_nodes(cam: Camera, mpp: float, path_px: np.ndarray, seg_len: float) -> np.ndarray:
    """World nodes every ``seg_len`` metres along the traced trunk (base at the origin)."""
    pts = _pixels_to_world(cam, mpp, np.column_stack([path_px, np.zeros(len(path_px))]))
    pts[0] = 0.0
    return _trunk_nodes_along(pts, seg_len)


def _trunk_nodes_along(pts: np.ndarray, seg_len: float) -> np.ndarray:
    """Nodes every ``seg_len`` metres along a polyline (K, 3)."""
    from treeform.contour.resample import resample_polyline

    length = float(np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))[-1]) if len(pts) > 1 else 0.0
    if length <= 0:
        return np.stack([np.zeros(3), np.array([0.0, seg_len, 0.0])])
    return resample_polyline(pts, max(2, int(length / seg_len) + 1), endpoint=True)


def tree_form(tree_mask: np.ndarray) -> str:
    """Growth form, 'broadleaf' or 'conifer', of the tree in a photo's (H, W) tree mask.

    The silhouette rule of :func:`treeform.contour.form.classify_form` (chosen on
    the billboard library's cut-outs: a narrow cone or column reaching down to near the ground
    is a conifer); a palm is grown as a broadleaf.
    """
    from treeform.contour.form import classify_form

    rgba = np.zeros(tree_mask.shape + (4,), np.uint8)
    rgba[np.asarray(tree_mask, bool), 3] = 255
    form = classify_form(rgba)
    return form if form == "conifer" else "broadleaf"


def conifer_leader(trunk: np.ndarray, attractors: np.ndarray, seg_len: float) -> np.ndarray:
    """The trunk (K, 3) continued as a conifer's leader: straight on to just under the crown's top.

    The leader ends at the 97th percentile of the attractors' heights (its tip grows on into the
    topmost ones), under the median column of the topmost 3 % (the apex) and at the crown's median
    depth (the photo cannot show the apex's depth); nodes every ``seg_len``.
    """
    if len(attractors) < 10:
        return trunk
    y = attractors[:, 1]
    y_top = float(np.percentile(y, 97))
    if y_top <= trunk[-1, 1] + 2 * seg_len:
        return trunk
    apex = attractors[y >= y_top]
    top = np.array([np.median(apex[:, 0]), y_top, np.median(attractors[:, 2])])
    return _trunk_nodes_along(np.concatenate([trunk, top[None]]), seg_len)


_KERNELS = {  # the compiled kernels this route calls from Python (their callees compile into them)
    "growth/_kernels.py": {"pipe_accumulate", "main_child_orders"},
    "growth/_leaf_kernels.py": {"nearest_points", "orient_cards", "subtree_tip_counts"},
    "geometry/_kernels.py": {"chain_layout", "card_corners", "prefix_rotations"},
    "crown/_kernels.py": {"finish_tiles"},
    "growth/_point_kernels.py": {"close_pair_drops", "nearest_new_node"},
    "_shared/rdm_kernels.py": {"lookup", "contains", "bounds"},
    "io/_text_kernels.py": {"float_rows", "face_rows"},
}


def _announce_compile():
    """Say so when this run will compile the route's numba kernels (once per installation, ~6 s)."""
    import logging

    import treeform
    from treeform._shared.jit import announce_compile

    root = Path(treeform.__file__).parent
    announce_compile(logging.getLogger(__name__), "the meshing and foliage kernels", 9,
                     *(str(root / f) for f in _KERNELS), names=set().union(*_KERNELS.values()))


def reconstruct(photo, *, mask=None, out=None, config: EnvelopeConfig | None = None,
                progress: ProgressCallback | None = None, **options) -> Reconstruction:
    """Reconstruct a leafy, textured 3D tree from one photo (seed 001 §3).

    Parameters
    ----------
    photo : path, ndarray (H, W, 3) uint8, or Photo
    mask : path or ndarray (H, W), optional
        User tree mask (white = tree) replacing the automatic segmentation.
    out : path, optional
        Directory to write tree.glb, tree.obj (+ .mtl, textures), skeleton.json,
        skeleton.ply, preview.png, metrics.json and config.json; files appear only
        when every stage succeeded.
    config : EnvelopeConfig, optional
    progress : callable, optional
        ``progress(stage, event, seconds)``.
    **options
        Overrides of config fields, e.g. ``seed=3, crown="conical", leaves=5000, lod="low"``.

    Returns
    -------
    Reconstruction
    """
    cfg = EnvelopeConfig.from_dict({**(config.to_dict() if config else {}), **options})
    out_dir = check_out_dir(out) if out is not None else None
    timer = StageTimer(progress)
    rng = as_rng(cfg.seed)
    _announce_compile()

    with timer.stage("load"):
        ph, user_mask = load_photo(photo, mask, max_size=cfg.max_size)
        image = ph.image
    with timer.stage("segment"):
        from treeform.crown.layout import tree_layout

        seg = segment_or_mask(image, user_mask, segmenter=cfg.segmenter, seed=cfg.seed)
        layout = tree_layout(seg)
        height, width = ph.shape
        # a crown the frame cuts goes on past it (rounded): the tree's height counts its continued top
        from treeform.methods._single_photo import continued_crown, on_canvas

        crown_full, (ptop, pleft), whole = continued_crown(layout, enabled=cfg.beyond_frame)
        cam, mpp = photo_camera(width, height, whole, cfg.tree_height, cfg.fov_y)

        form = cfg.form if cfg.form != "auto" else tree_form(seg.tree_mask)

        def canvas(frame_mask):
            """A mask of the photo on the continued crown's canvas, the continued crown around it."""
            return on_canvas(frame_mask, crown_full, (ptop, pleft))
    with timer.stage("envelope"):
        from treeform.crown.envelope import inflate_envelope

        env = inflate_envelope(crown_full, crown=cfg.crown_for(form), k=cfg.tangent_k, a=cfg.conical_a,
                               grid_size=cfg.envelope_grid, depth_ratio=cfg.depth_ratio,
                               profile=cfg.profile)
        env_uvz = env.vertices - np.array([pleft, ptop, 0.0])  # the photo's pixels (past its edges too)
        front_z = env.front_z[ptop:ptop + height, pleft:pleft + width]
        world_verts = _pixels_to_world(cam, mpp, env_uvz)
    with timer.stage("relief"):
        from treeform.crown.relief import relief_map

        relief = relief_map(image, layout.crown_mask, levels=cfg.relief_levels)
        vu = np.clip(env_uvz[:, 0].astype(np.int64), 0, width - 1)
        vv = np.clip(env_uvz[:, 1].astype(np.int64), 0, height - 1)
        h_vert = relief[vv, vu]
    with timer.stage("rdm"):
        import scipy.ndimage as ndi

        from treeform.crown.rdm import rdm_from_texels
        from treeform.render.cubemap import render_radial_cubemap

        edt = ndi.distance_transform_edt(crown_full)
        cv_, cu_ = np.unravel_index(np.argmax(edt), edt.shape)
        center = _pixels_to_world(cam, mpp, np.array([[cu_ - pleft + 0.5, cv_ - ptop + 0.5, 0.0]]))[0]
        radii = render_radial_cubemap(world_verts, env.faces, center, values=h_vert, rho=cfg.relief_weight,
                                      resolution=cfg.rdm_resolution, rotations_deg=tuple(cfg.rdm_rotations))
        rdm = rdm_from_texels(center, radii)
        r_mean = rdm.mean_radius()
    from treeform.crown.sampling import visual_hull_contains

    hull_mask = canvas(ndi.binary_dilation(seg.tree_mask, iterations=1))  # and the crown past the frame

    def inside(p):
        ok = rdm.contains(p)
        ok[ok] = visual_hull_contains(cam, hull_mask, p[ok], offset=(ptop, pleft))
        return ok

    with timer.stage("attractors"):
        from treeform.crown.sampling import clump_density, foliage_clumps, thinned
        from treeform.growth.sampling import blue_noise_points

        lo, hi = rdm.bounds()
        leaf_density, grow_into = None, inside
        if cfg.clumps > 0:  # leaves and the branches that carry them gather in clumps
            spacing = cfg.clumps * r_mean
            centres = foliage_clumps(inside, (lo, hi), spacing, seed=rng)
            leaf_density = partial(clump_density, centres=centres, sigma=CLUMP_LEAF_WIDTH * spacing)
            if form != "conifer":  # a conifer's laterals leave its leader evenly, whorl after whorl
                grow_into = thinned(inside, lambda p: CLUMP_BRANCH_FLOOR + (1 - CLUMP_BRANCH_FLOOR) *
                                    clump_density(p, centres, CLUMP_BRANCH_WIDTH * spacing), seed=rng)
        # as many attractors in the photo's crown as without the crown past the frame (their density
        # sets the branches' and the photo's view of them)
        n_att = int(round(cfg.attractors * min(crown_full.sum() / max(layout.crown_mask.sum(), 1), 2.0)))
        attractors = blue_noise_points(grow_into, (lo, hi), n_att, seed=rng)
    with timer.stage("colonize"):
        from treeform.growth.radii import branch_orders, pipe_model_radii
        from treeform.growth.space_colonization import space_colonization

        seg_len = cfg.segment_length * r_mean
        trunk = _trunk_nodes(cam, mpp, layout.trunk_path, seg_len)
        tree_h = cfg.tree_height  # the photo's tree spans this many metres (photo_camera)
        if trunk[-1, 1] < 0.1 * tree_h:  # no visible trunk (hidden by shrubs): a straight one to the crown
            top = max(0.15 * tree_h, float(np.percentile(attractors[:, 1], 5)) if len(attractors) else 0.0)
            trunk = _trunk_nodes_along(np.array([[0.0, 0.0, 0.0], [0.0, top, 0.0]]), seg_len)
        # one stem at the ground: no branch wood in the lowest tenth (leaves may hang there);
        # the trunk sprouts from its top fifth and wherever the crown reaches down beside it,
        # so low crown parts get short limbs off the trunk instead of strands growing down along it
        attractors = attractors[attractors[:, 1] >= 0.1 * tree_h]
        if form == "conifer":  # one leader through the crown, laterals off it all the way up
            trunk = conifer_leader(trunk, attractors, seg_len)
        n_trunk = len(trunk)
        crown_low = float(attractors[:, 1].min()) if len(attractors) else float(trunk[-1, 1])
        growable = (np.linspace(0, 1, n_trunk) >= 0.8) | (trunk[:, 1] >= max(crown_low - seg_len, 0.1 * tree_h))
        sc = space_colonization(attractors, trunk, influence_radius=cfg.influence * r_mean,
                                kill_distance=cfg.kill_factor * seg_len, segment_length=seg_len, growable=growable,
                                direction_weight=cfg.direction_weight,
                                start_direction_weight=leader_direction_weight(form))
        # the photo's trunk width, within what trees grow: a radius of 0.2-6 % of the height
        # (wood around the base -- a fence, a bush labelled wood -- reads far too wide)
        trunk_radius = float(np.clip(layout.trunk_width * mpp / 2, max(0.002 * tree_h, 0.02), 0.06 * tree_h))
        n_tips = max(1, int((np.bincount(sc.parent[1:], minlength=len(sc.parent)) == 0).sum()))
        tip_r = max(trunk_radius / n_tips ** (1 / cfg.pipe_exponent), 0.002)
        radius = pipe_model_radii(sc.parent, tip_radius=tip_r, exponent=cfg.pipe_exponent)
        radius *= trunk_radius / radius[0]
        skeleton = TreeSkeleton(sc.positions, sc.parent, radius, branch_orders(sc.parent, radius),
                                sc.iteration.astype(np.float64),
                                meta={"method": "envelope", "seed": cfg.seed, "source": Path(ph.source).name,
                                      "form": form})
    with timer.stage("leaves"):
        from treeform.crown.layout import trunk_pixels
        from treeform.crown.sampling import rdm_front_height, sample_crown_columns, sample_rdm_shell
        from treeform.growth.leaves import attach_leaves, color_leaves

        leaf_mask = seg.tree_mask & layout.crown_mask & ~trunk_pixels(seg, layout)
        dist = float(np.linalg.norm(np.subtract(cam.position, cam.target)))
        area = leaf_mask.sum() * mpp * mpp
        n_shell = int(round(cfg.shell_leaves * cfg.leaves))
        # card size so the column-sampled leaves alone cover each crown pixel leaf_coverage times
        # on average (a card's texture covers ~0.65 of it, at a mean tilt of ~0.5 toward the camera;
        # needle and scale textures cover less, so their cards are larger)
        from treeform.geometry import CLUSTER_COVERAGE, foliage_coverage

        texture_cover = 0.33 * foliage_coverage(cfg.foliage_kind(form), seed=cfg.seed) / CLUSTER_COVERAGE
        size = math.sqrt(cfg.leaf_coverage * area / max(cfg.leaves - n_shell, 1) / texture_cover) if cfg.leaves else 0.1
        # procedural card centres stay a third of a card inside the silhouette so cards do not
        # overhang it (photo-textured cards are cut by the photo's own alpha: no inset needed)
        inset = int(round(size / mpp / 3)) if cfg.leaf_texture == "procedural" else 0
        core = ndi.binary_erosion(leaf_mask, iterations=inset, border_value=1) if inset > 0 else leaf_mask
        # the crown's depth at each pixel comes from the RDM (relief, rotated copies): march rays
        crown_z = rdm_front_height(rdm, cam, dist, mpp, leaf_mask.shape)
        crown_z = np.where(crown_z > 0, crown_z, front_z)
        weight = None if leaf_density is None else (lambda c: leaf_density(_pixels_to_world(cam, mpp, c)))
        uvz = sample_crown_columns(core if core.sum() > 0.5 * leaf_mask.sum() else leaf_mask, crown_z,
                                   cfg.leaves - n_shell, weight=weight, seed=rng)
        # the shell's leaves also dress the crown past the frame (the photo shows none of them: the
        # leaves it sees keep their number, within the same triangle budget)
        hull_core = canvas(core)
        def in_hull(p):
            return visual_hull_contains(cam, hull_core, p, offset=(ptop, pleft))
        shell_pts = sample_rdm_shell(rdm, n_shell, keep=in_hull if leaf_density is None else
                                     thinned(in_hull, leaf_density, seed=rng), seed=rng, max_rounds=60)
        pts = np.concatenate([_pixels_to_world(cam, mpp, uvz), shell_pts])
        suv = cam.project(shell_pts)
        uvz = np.concatenate([uvz, np.column_stack([suv[:, :2], (dist - suv[:, 2]) / mpp])])
        # photo-textured cards turn more freely: their lighting then varies around the photo's own
        # (measured: front SSIM +0.01-0.03, silhouette error -0.3 % on real photos)
        foliage = attach_leaves(skeleton, pts, size=size, center=center, seed=rng,
                                scatter=1.4 if cfg.leaf_texture == "photo" else 0.9)
        skeleton.meta["n_leaves"] = len(foliage)  # so `treeform metrics` on the files reports the count
        if len(foliage):
            fu = np.clip(uvz[:, 0].astype(np.int64), 0, width - 1)
            fv = np.clip(uvz[:, 1].astype(np.int64), 0, height - 1)
            zf = crown_z[fv, fu]
            in_frame = (uvz[:, 0] >= 0) & (uvz[:, 0] < width) & (uvz[:, 1] >= 0) & (uvz[:, 1] < height)
            # seen: near the envelope's front, or the nearest card in some pixel (a depth buffer of
            # the cards: the cards in front of the envelope and those behind its gaps)
            from treeform.crown.photo_leaves import camera_sees

            visible = (uvz[:, 2] >= zf - np.maximum(2 * size / mpp, 0.3 * zf)) & in_frame
            visible |= camera_sees(foliage, cam, np.ones((height, width), bool))[0]
            d = foliage.positions - center
            shade = 0.55 + 0.45 * np.clip(np.linalg.norm(d, axis=1) / np.maximum(rdm.lookup(d), 1e-6), 0, 1)
            if cfg.leaf_texture == "procedural":  # the photo is the texture otherwise (mesh stage)
                foliage = color_leaves(foliage, uvz[:, :2], visible, image, leaf_mask, shade=shade, seed=rng)
            else:  # photo tiles: the cards the camera sees face it, so each shows its patch unstretched
                from treeform.crown.photo_leaves import face_camera

                foliage = face_camera(foliage, cam, visible, rng)
                # the alpha of its photo tile cuts a card the camera sees to the outline; a card behind
                # them shows a tile of the crown wherever it stands, so one overhanging the mask goes
                # (past the frame, the continued crown is the mask: the photo does not show it cut there)
                from treeform.crown.sampling import CARD_COVER, card_cover

                keep = visible | (card_cover(cam, canvas(leaf_mask), foliage, offset=(ptop, pleft)) >= CARD_COVER)
                foliage, visible, shade = foliage.subset(keep), visible[keep], shade[keep]
                skeleton.meta["n_leaves"] = len(foliage)
    with timer.stage("mesh"):
        from treeform.geometry import LOD_PRESETS, tree_mesh, tree_textures
        from treeform.geometry.textures import bark_normals, tint_texture

        bark_tex, leaf_tex = tree_textures(skeleton, foliage, foliage_kind=cfg.foliage_kind(form),
                                           texture_size=cfg.texture_size, seed=cfg.seed)
        bark_normal = bark_normals(bark_tex, seed=cfg.seed)
        if seg.wood_mask.sum() > 20:  # the bark takes the colour of the photo's wood (brighter too)
            bark_tex = tint_texture(bark_tex, np.median(image[seg.wood_mask], axis=0))
        if cfg.leaf_texture == "photo" and len(foliage):
            from treeform.crown.photo_leaves import photo_leaf_atlas
            from treeform.geometry.textures import foliage_texture_kind
            from treeform.segment.matting import sky_gaps

            # foliage alpha from the photo (sky seen through the crown left out), softened by a
            # pixel so tile edges are antialiased; the cards need no tint (shading is in the tiles)
            alpha = ndi.gaussian_filter((leaf_mask & ~sky_gaps(image, seg, ratio=3.0)) * seg.alpha, 0.6)
            white = foliage.with_colors(np.ones((len(foliage), 3)))
            leaf_tex, foliage = photo_leaf_atlas(white, cam, image, alpha, visible=visible,
                                                 shade=np.where(visible, 1.0, shade), seed=cfg.seed,
                                                 kind=foliage_texture_kind(cfg.foliage_kind(form)))
        mesh = tree_mesh(skeleton, foliage, max_triangles=LOD_PRESETS[cfg.lod],
                         radial_segments=cfg.radial_segments, leaf_texture=leaf_tex, bark_texture=bark_tex,
                         bark_normal=bark_normal, seed=cfg.seed)
    # the mesh files are written (threads) while the preview renders; all or nothing
    staged = start_tree_outputs(out_dir, mesh=mesh, skeleton=skeleton) if out_dir is not None else None
    with staged if staged is not None else nullcontext():
        with timer.stage("render"):
            from treeform.methods._single_photo import model_metrics, photo_metrics
            from treeform.render import Lighting
            from treeform.report import photo_window, preview_strip

            # soft, camera-relative light so the front view shows the albedo the photo gave the leaves
            light = Lighting(direction=(-0.4, 0.6, 0.7), key=(0.45, 0.45, 0.42), sky=(0.8, 0.8, 0.82),
                             ground=(0.55, 0.54, 0.5), camera_relative=True)
            # the front view is the photo's camera, widened to show the whole tree; side shares its scale
            renders = render_previews(mesh, front=cam, lighting=light)
            window = photo_window(renders["front"].camera, cam)  # the photo's frame in the widened front view
            metrics = {
                **photo_metrics(renders, cam, image, seg.tree_mask),
                "form": form,
                "attractors": int(len(attractors)),
                "attractors_left": sc.attractors_left,
                **model_metrics(skeleton, foliage, mesh, photo_size=(width, height), metres_per_pixel=mpp),
            }
            preview = preview_strip(renders, photo=image, segmentation=seg, keep=window)
        result = Reconstruction(ph, seg, cam, world_verts, env.faces, rdm, skeleton, foliage, mesh, metrics, cfg,
                                renders, preview)
        if out_dir is not None:
            with timer.stage("export"):
                result.files = _write_outputs(result, out_dir, staged)
    metrics["timings"] = {k: round(v, 4) for k, v in timer.timings.items()}
    metrics["total_seconds"] = round(sum(timer.timings.values()), 4)
    if out_dir is not None:
        write_json(out_dir / "metrics.json", metrics)
    return result


def _write_outputs(res: Reconstruction, out_dir: Path, staged=None) -> dict:
    """Write every output into ``out_dir`` all-or-nothing (:func:`treeform.io.write_tree_outputs`)."""
    from treeform.io import write_tree_outputs

    config = {"treeform": __version__, "method": "envelope", "photo": res.photo.source,
              "config": res.config.to_dict()}
    return write_tree_outputs(out_dir, mesh=res.mesh, skeleton=res.skeleton, preview=res.preview, config=config,
                              metrics=res.metrics, staged=staged)
