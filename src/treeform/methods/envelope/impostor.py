"""``treeform impostor``: the image-based representation of a tree for rendering at distance (seed 001 §3.3, §3.5).

From the output folder of any reconstruct / grow / multiview run (its ``tree.glb``): the tree
is rendered from the front (unlit albedo, the front of the photo for photo-textured trees), the
colour cubemap is synthesized from that view (:func:`treeform.crown.color_cubemap.color_cubemap`),
and the radial distance map of the whole tree is rasterized around the crown's centre
(:func:`treeform.render.render_radial_cubemap`). The relief-mapped renderer and the forest use
these files.

Outputs (``impostor/`` beside the tree, all or nothing): ``rdm.npz``
(:class:`~treeform.structures.RadialDistanceMap`), ``opacity.npz`` (:class:`~treeform.structures.OpacityGrid`:
the leaves' and wood's extinction per voxel, so the relief impostor sees through the crown's gaps),
``color_px.png`` … ``color_nz.png`` (the six
faces, OpenGL order), ``color_cross.png`` (the faces unfolded, to look at), ``front.png`` (the
view the colours came from), ``leaflets/`` (a leaflet billboard and its channels, seed 001 §4.2:
what the clipped billboard clouds draw near the camera), ``cloud.npz`` (the billboard centres
on the tree's branch points, every prefix spread, and the billboard edge), ``wood.glb`` (trunk
and main limbs under a small triangle budget, drawn under the cloud) and ``impostor.json``
(the manifest). :func:`read_impostor` reads the folder back.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from treeform import __version__
from treeform._shared.checks import check_int
from treeform._shared.errors import InputError
from treeform._shared.timing import ProgressCallback, StageTimer

__all__ = ["IMPOSTOR_STAGES", "IMPOSTOR_COLORS", "FACE_NAMES", "OPACITY_RESOLUTION", "Impostor", "make_impostor",
           "read_impostor"]

IMPOSTOR_STAGES = ("load", "render", "rdm", "color", "leaflets", "cloud", "export")
CLOUD_COVER = 3.0
"""Layers of billboards over the crown's silhouette with all of them drawn (sets their size)."""
WOOD_TRIANGLES = 2000
"""Triangle budget of ``wood.glb``, the trunk and limbs under the near trees' billboard clouds."""
WOOD_TEXTURE = 256
"""Largest edge of ``wood.glb``'s bark textures (the near trees are seen from metres away, not centimetres)."""
FACE_NAMES = ("px", "nx", "py", "ny", "pz", "nz")
"""File suffixes of the six faces, OpenGL order (+X, -X, +Y, -Y, +Z, -Z)."""
OPACITY_RESOLUTION = 96
"""Voxels along the opacity grid's edge (bench_impostor.py: oak / pine silhouette IoU at 64 px 0.93 with 96,
0.91 with 64, 0.81 / 0.84 with none)."""
_LEAFLET_ATTRACTORS = 800


@dataclass
class Impostor:
    """What :func:`make_impostor` made: the colour faces, the RDM, the front view, the files."""

    color: np.ndarray  # (6, F, F, 3) uint8
    rdm: object  # RadialDistanceMap
    front: np.ndarray  # (H, W, 4) uint8
    leaflets: object  # LeafletBillboard
    manifest: dict
    files: dict = field(default_factory=dict)
    cloud_points: np.ndarray | None = None  # (P, 3) float32, billboard centres
    cloud_size: float = 0.0  # billboard edge (m) with all P drawn
    wood: object = None  # Mesh: trunk and limbs under the cloud
    opacity: object = None  # OpacityGrid: the tree's extinction per voxel (None: the relief hits the RDM's surface)

    def planar(self) -> dict:
        """The front view as :func:`~treeform.render.impostor.render_rdm_impostor`'s ``planar`` colour."""
        f = self.manifest["front"]
        return {"image": self.front, "center_px": f["center_px"], "pixels_per_metre": f["pixels_per_metre"]}


IMPOSTOR_COLORS = ("synthesis", "baked")
"""How the colour cubemap is made: synthesized from the front view (seed 001 §3.3: a single photo's
tree, whose other sides nobody saw) or baked from views of the mesh all round (a 3D tree)."""


def make_impostor(tree_dir, *, out=None, face: int = 256, rdm_resolution: int = 128, view_size: int = 512,
                  leaflet_size: int = 256, seed: int = 0, colors: str = "synthesis", engine=None,
                  opacity_resolution: int = OPACITY_RESOLUTION, progress: ProgressCallback | None = None) -> Impostor:
    """Colour cubemap and radial distance map of a tree from its output folder.

    Parameters
    ----------
    tree_dir : path
        An output folder holding ``tree.glb`` (or the GLB itself).
    out : path, optional
        Where the files go (default ``tree_dir/impostor``); nothing is written with
        ``out=False``.
    face : int
        Edge of a colour face in texels (the canvas of the synthesis is 4F × 3F).
    rdm_resolution : int
        Edge of an RDM face in texels.
    view_size : int
        Height in pixels of the front view the colours come from.
    leaflet_size : int
        Edge of the leaflet billboard's textures (:func:`~treeform.methods.envelope.leaflets.leaflet_billboard`).
    seed : int
    colors : {'synthesis', 'baked'}
        The colour cubemap: texture synthesis from the front view
        (:func:`~treeform.crown.color_cubemap.color_cubemap`), or the mesh's own colours seen
        from outside on the RDM's surface (:func:`~treeform.render.bake_color_cubemap`).
    engine : (float, float), optional
        Also write ``engine/``: the tree as a chain of GLB levels for game engines (full mesh,
        billboard cloud, impostor cards; :mod:`~treeform.methods.envelope.engine`) switching at
        these two distances in metres, and ``engine/lods.json``.
    opacity_resolution : int
        Voxels along the edge of the opacity grid (:func:`~treeform.geometry.opacity_grid`,
        ``opacity.npz``): the relief impostor sees through the crown's gaps as the mesh does
        from afar. 0 writes none (the relief then hits the RDM's surface, seed 001 §4.1 as
        published).
    progress : callable, optional
        ``progress(stage, event, seconds)`` for :data:`IMPOSTOR_STAGES`.

    Returns
    -------
    Impostor
    """
    from treeform._shared.rng import as_rng
    from treeform.io.outputs import check_out_dir

    face = check_int(face, "face", 32, 2048)
    rdm_resolution = check_int(rdm_resolution, "rdm_resolution", 8, 2048)
    view_size = check_int(view_size, "view_size", 64, 4096)
    leaflet_size = check_int(leaflet_size, "leaflet_size", 64, 4096)
    opacity_resolution = check_int(opacity_resolution, "opacity_resolution", 0, 512)
    if 0 < opacity_resolution < 8:
        raise InputError(f"opacity_resolution: expected 0 (none) or at least 8 voxels, got {opacity_resolution}")
    as_rng(seed)
    from treeform._shared.checks import check_choice

    check_choice(colors, "colors", IMPOSTOR_COLORS)
    if engine is not None:
        try:
            near, far = (float(x) for x in engine)
        except (TypeError, ValueError):
            raise InputError(f"engine: expected two switch distances in metres, got {engine!r}") from None
        if not (0 < near < far < float("inf")):
            raise InputError(f"engine: expected 0 < near < far metres, got {near:g}, {far:g}")
    src = Path(tree_dir)
    glb = src / "tree.glb" if src.is_dir() else src
    if not glb.is_file():
        raise InputError(f"{src}: no tree.glb here (expected the output folder of a treeform run)")
    out_dir = None
    if out is not False:
        out_dir = check_out_dir((src if src.is_dir() else src.parent) / "impostor" if out is None else out)
    timer = StageTimer(progress)
    with timer.stage("load"):
        from treeform.io.gltf import read_glb_mesh

        mesh = read_glb_mesh(glb)
        pts = np.concatenate([p.positions for p in mesh.parts if p.n_vertices]).astype(np.float64)
    with timer.stage("render"):
        from treeform.render import Lighting, Renderer
        from treeform.report import preview_cameras

        cam = preview_cameras(pts, size=view_size)["front"]
        unlit = Lighting(key=(0.0, 0.0, 0.0), sky=(1.0, 1.0, 1.0), ground=(1.0, 1.0, 1.0))
        renderer = Renderer(cam, samples=1, background=(0.0, 0.0, 0.0, 0.0), lighting=unlit)
        try:
            res = renderer.render(mesh)
        finally:
            renderer.release()
        front = np.dstack([res.color[..., :3], np.where(res.mask, 255, 0).astype(np.uint8)])
        front_cam = cam
    with timer.stage("rdm"):
        from treeform.render import render_radial_cubemap
        from treeform.structures import RadialDistanceMap

        leafy = [p for p in mesh.parts if p.material.alpha_mode != "OPAQUE" and p.n_vertices] or mesh.parts
        lp = np.concatenate([p.positions for p in leafy]).astype(np.float64)
        center = 0.5 * (lp.min(0) + lp.max(0))  # the crown's box centre
        from treeform.geometry import opaque_cards

        verts, tris, off = [], [], 0
        for p in mesh.parts:
            # leaf cards as far as their leaves go: the radial map ignores alpha, and the cards'
            # transparent margins stood out of the mesh's silhouette all round
            trimmed = opaque_cards(p) if p.material.alpha_mode != "OPAQUE" else None
            verts.append(trimmed if trimmed is not None else p.positions.astype(np.float64))
            tris.append(p.indices.astype(np.int64) + off)
            off += p.n_vertices
        verts = np.concatenate(verts)
        radii = render_radial_cubemap(verts, np.concatenate(tris), center, resolution=rdm_resolution)
        # thin parts (twigs, a trunk far below the centre, small cards) can fall between texel
        # centres: every vertex also raises its own texel, so the map holds the whole tree
        import cv2

        from treeform.structures.rdm import direction_to_texel

        d = verts - center
        f, r, c = direction_to_texel(d, rdm_resolution)
        np.maximum.at(radii, (f, r, c), np.linalg.norm(d, axis=1).astype(np.float32))
        # a 3x3 median per face drops the single-texel spikes those splats (and pits the rasterizer's
        # gaps) leave in the crown: a spiky rim and streaky relief otherwise (bench_impostor.py:
        # silhouette IoU at 32 px 0.81 -> 0.86 for a grown oak); the bare trunk below the crown is
        # thin too, so its vertices raise their texels again
        radii = np.stack([cv2.medianBlur(np.ascontiguousarray(x), 3) for x in radii])
        below = verts[:, 1] < lp[:, 1].min()
        np.maximum.at(radii, (f[below], r[below], c[below]), np.linalg.norm(d[below], axis=1).astype(np.float32))
        rdm = RadialDistanceMap(center, radii)
        opacity = None
        if opacity_resolution:
            from treeform.geometry.opacity import opacity_grid

            # (the trunk and thickest limbs as capsules beside the grid, from the skeleton written with the tree)
            opacity = opacity_grid(mesh, resolution=opacity_resolution, skeleton=_skeleton_beside(glb))
    with timer.stage("color"):
        from treeform.crown.color_cubemap import color_cubemap, cross_from_faces

        if colors == "baked":
            from treeform.render import bake_color_cubemap

            color = bake_color_cubemap(mesh, rdm, face=face, view_size=view_size)
        else:
            color = color_cubemap(front, face=face, seed=seed)
    uvz = front_cam.project(np.asarray(center)[None])[0]
    with timer.stage("leaflets"):
        from treeform.methods.envelope.leaflets import leaflet_billboard, leaflet_writers

        leaflets = leaflet_billboard("sphere", size=leaflet_size, attractors=_LEAFLET_ATTRACTORS, seed=seed)
    with timer.stage("cloud"):
        from treeform.crown.sampling import billboard_centres
        from treeform.render.cloud import MAX_BILLBOARDS

        skeleton = _skeleton_beside(glb)
        cloud_points = billboard_centres(rdm, None if skeleton is None else skeleton.positions, MAX_BILLBOARDS,
                                         box=(lp.min(0), lp.max(0)), seed=seed)
        fill = max(float((leaflets.rgba[..., 3] >= 128).mean()), 0.05)
        lo, hi = rdm.bounds()
        cloud_size = float(np.mean(hi - lo) / 2 * np.sqrt(CLOUD_COVER * np.pi / (fill * len(cloud_points))))
        wood = _wood_mesh(mesh, skeleton, seed)
    manifest = {
        "treeform": __version__, "source": str(glb), "seed": int(seed),
        "cloud": {"file": "cloud.npz", "billboards": int(len(cloud_points)), "size": round(cloud_size, 6),
                  "from": "skeleton" if skeleton is not None else "rdm shell",
                  "wood": "wood.glb", "wood_triangles": int(wood.n_triangles)},
        "leaflets": {"folder": "leaflets", "size": leaflet_size, "shape": "sphere", "leaves": leaflets.leaves},
        "color": {"faces": [f"color_{n}.png" for n in FACE_NAMES], "face_size": face, "order": "+X -X +Y -Y +Z -Z",
                  "made_by": colors,
                  "cross": "color_cross.png", "front": "front.png"},
        "rdm": {"file": "rdm.npz", "resolution": rdm_resolution, "center": [round(float(c), 6) for c in center],
                "mean_radius": round(rdm.mean_radius(), 6)},
        **({"opacity": {"file": "opacity.npz", "resolution": opacity_resolution,
                        "origin": [round(float(c), 6) for c in opacity.origin], "voxel": round(opacity.voxel, 6),
                        "wood_capsules": int(len(opacity.wood)),
                        "model": "extinction 1/m per voxel; the tree is hit at optical depth ln 2, or on a "
                                 "capsule of wood in front of that"}}
           if opacity is not None else {}),
        # the front view as the relief impostor's planar colour (seed 001 §4.1, for distant trees):
        # the crown centre's pixel and the view's scale there
        "front": {"file": "front.png", "center_px": [round(float(x), 3) for x in uvz[:2]],
                  "pixels_per_metre": round(float(front_cam.focal / uvz[2]), 6)},
    }
    result = Impostor(color, rdm, front, leaflets, manifest, cloud_points=cloud_points, cloud_size=cloud_size,
                      wood=wood, opacity=opacity)
    if out_dir is not None:
        with timer.stage("export"):
            from treeform.io.gltf import write_glb
            from treeform.io.images import write_png
            from treeform.io.outputs import StagedOutputs, write_json

            manifest["timings"] = {k: round(v, 4) for k, v in timer.timings.items()}
            with StagedOutputs(out_dir) as staged:
                staged.submit(*[lambda d, n=n, i=i: write_png(color[i], d / f"color_{n}.png")
                                for i, n in enumerate(FACE_NAMES)],
                              lambda d: write_png(cross_from_faces(color), d / "color_cross.png"),
                              lambda d: write_png(front, d / "front.png"),
                              lambda d: rdm.save(d / "rdm.npz"),
                              *((lambda d: opacity.save(d / "opacity.npz"),) if opacity is not None else ()),
                              lambda d: _save_npz(d / "cloud.npz", points=cloud_points,
                                                  size=np.float32(cloud_size)),
                              lambda d: write_glb(wood, d / "wood.glb"),
                              *leaflet_writers(leaflets, seed=seed, attractors=_LEAFLET_ATTRACTORS, folder="leaflets"),
                              *(_engine(result, glb, engine, seed) if engine is not None else ()),
                              lambda d: write_json(d / "impostor.json", manifest))
                result.files = staged.commit()
    manifest["timings"] = {k: round(v, 4) for k, v in timer.timings.items()}
    return result


def _engine(imp: Impostor, glb: Path, engine, seed: int) -> list:
    from treeform.methods.envelope.engine import engine_writers

    near, far = (float(x) for x in engine)
    imp.manifest["engine"] = {"folder": "engine", "manifest": "lods.json", "switch_m": [near, far]}
    return engine_writers(imp, glb, near=near, far=far, seed=seed)


def _save_npz(path, **arrays):
    with open(path, "wb") as fh:
        np.savez(fh, **arrays)


def _skeleton_beside(glb: Path):
    """The treeform skeleton written beside ``glb`` (``skeleton.json``), or None."""
    from treeform.io.trees import read_tree

    if not (glb.parent / "skeleton.json").is_file():
        return None
    return read_tree(glb.parent / "skeleton.json")


def _wood_mesh(mesh, skeleton, seed: int):
    """Trunk and main limbs under :data:`WOOD_TRIANGLES`, with the tree's own bark texture.

    From the skeleton when there is one (the thinnest chains dropped first,
    :func:`~treeform.geometry.lod.tree_mesh`); otherwise the GLB's opaque parts as they are.
    """
    from treeform.structures.mesh import Mesh

    bark = [p for p in mesh.parts if p.material.alpha_mode == "OPAQUE" and p.n_triangles]
    if skeleton is None:
        return Mesh(bark)
    from treeform.geometry.lod import tree_mesh

    tex = _fit(bark[0].material.texture) if bark else None
    normal = _fit(bark[0].material.normal_texture) if bark else None
    if tex is not None and tex.shape[2] == 3:
        tex = np.dstack([tex, np.full(tex.shape[:2], 255, np.uint8)])
    return tree_mesh(skeleton, None, max_triangles=WOOD_TRIANGLES, radial_segments=6, bark_texture=tex,
                     bark_normal=normal if tex is not None else None, seed=seed)


def _fit(texture, edge: int = WOOD_TEXTURE):
    """``texture`` reduced to at most ``edge`` texels a side (area-averaged), or None."""
    if texture is None or max(texture.shape[:2]) <= edge:
        return texture
    import cv2

    s = edge / max(texture.shape[:2])
    size = (max(1, round(texture.shape[1] * s)), max(1, round(texture.shape[0] * s)))
    return np.ascontiguousarray(cv2.resize(texture, size, interpolation=cv2.INTER_AREA))


def read_impostor(folder) -> Impostor:
    """An impostor folder written by :func:`make_impostor` (``treeform impostor``), read back.

    Parameters
    ----------
    folder : path
        The ``impostor/`` folder, or a tree's output folder holding one.

    Returns
    -------
    Impostor
        With :attr:`~Impostor.files` empty.

    Raises
    ------
    InputError
        A missing folder or file, or a folder written before billboard clouds existed
        (rerun ``treeform impostor``).
    """
    import json

    import cv2

    from treeform.io.gltf import read_glb_mesh
    from treeform.methods.envelope.leaflets import read_leaflet_billboard
    from treeform.structures import OpacityGrid, RadialDistanceMap

    d = Path(folder)
    if not (d / "impostor.json").is_file() and (d / "impostor" / "impostor.json").is_file():
        d = d / "impostor"
    if not (d / "impostor.json").is_file():
        raise InputError(f"{folder}: no impostor.json here (run `treeform impostor` on the tree first)")
    try:
        manifest = json.loads((d / "impostor.json").read_text())
    except (OSError, ValueError) as exc:
        raise InputError(f"{d / 'impostor.json'}: unreadable ({exc})") from None
    if "cloud" not in manifest:
        raise InputError(f"{d}: made by an older treeform without billboard clouds; rerun `treeform impostor`")

    def image(name: str, flags=cv2.IMREAD_COLOR) -> np.ndarray:
        img = cv2.imread(str(d / name), flags)
        if img is None:
            raise InputError(f"{d / name}: missing or unreadable")
        return img

    color = np.stack([image(f)[..., ::-1] for f in manifest["color"]["faces"]])
    front = image(manifest["front"]["file"], cv2.IMREAD_UNCHANGED)
    front = np.dstack([front[..., 2::-1], front[..., 3]]) if front.ndim == 3 and front.shape[2] == 4 else front
    try:
        rdm = RadialDistanceMap.load(d / manifest["rdm"]["file"])
        opacity = OpacityGrid.load(d / manifest["opacity"]["file"]) if "opacity" in manifest else None
        with np.load(d / manifest["cloud"]["file"]) as z:
            points, size = z["points"].astype(np.float32), float(z["size"])
    except (OSError, KeyError, ValueError) as exc:
        raise InputError(f"{d}: unreadable impostor data ({exc})") from None
    leaflets = read_leaflet_billboard(d / manifest["leaflets"]["folder"])
    wood = read_glb_mesh(d / manifest["cloud"]["wood"])
    return Impostor(color, rdm, front, leaflets, manifest, cloud_points=points, cloud_size=size, wood=wood,
                    opacity=opacity)
