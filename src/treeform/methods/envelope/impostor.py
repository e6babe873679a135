"""``treeform impostor``: the image-based representation of a tree for rendering at distance (seed 001 §3.3, §3.5).

From the output folder of any reconstruct / grow / multiview run (its ``tree.glb``): the tree
is rendered from the front (unlit albedo, the front of the photo for photo-textured trees), the
colour cubemap is synthesized from that view (:func:`treeform.crown.color_cubemap.color_cubemap`),
and the radial distance map of the whole tree is rasterized around the crown's centre
(:func:`treeform.render.render_radial_cubemap`). The relief-mapped renderer and the forest use
these files.

Outputs (``impostor/`` beside the tree, all or nothing): ``rdm.npz``
(:class:`~treeform.structures.RadialDistanceMap`), ``color_px.png`` … ``color_nz.png`` (the six
faces, OpenGL order), ``color_cross.png`` (the faces unfolded, to look at), ``front.png`` (the
view the colours came from), ``leaflets/`` (a leaflet billboard and its channels, seed 001 §4.2:
what the clipped billboard clouds draw near the camera) and ``impostor.json`` (the manifest).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from treeform import __version__
from treeform._shared.checks import check_int
from treeform._shared.errors import InputError
from treeform._shared.timing import ProgressCallback, StageTimer

__all__ = ["IMPOSTOR_STAGES", "IMPOSTOR_COLORS", "FACE_NAMES", "Impostor", "make_impostor"]

IMPOSTOR_STAGES = ("load", "render", "rdm", "color", "leaflets", "export")
FACE_NAMES = ("px", "nx", "py", "ny", "pz", "nz")
_LEAFLET_ATTRACTORS = 800
"""File suffixes of the six faces, OpenGL order (+X, -X, +Y, -Y, +Z, -Z)."""


@dataclass
class Impostor:
    """What :func:`make_impostor` made: the colour faces, the RDM, the front view, the files."""

    color: np.ndarray  # (6, F, F, 3) uint8
    rdm: object  # RadialDistanceMap
    front: np.ndarray  # (H, W, 4) uint8
    leaflets: object  # LeafletBillboard
    manifest: dict
    files: dict = field(default_factory=dict)

    def planar(self) -> dict:
        """The front view as :func:`~treeform.render.impostor.render_rdm_impostor`'s ``planar`` colour."""
        f = self.manifest["front"]
        return {"image": self.front, "center_px": f["center_px"], "pixels_per_metre": f["pixels_per_metre"]}


IMPOSTOR_COLORS = ("synthesis", "baked")
"""How the colour cubemap is made: synthesized from the front view (seed 001 §3.3: a single photo's
tree, whose other sides nobody saw) or baked from views of the mesh all round (a 3D tree)."""


def make_impostor(tree_dir, *, out=None, face: int = 256, rdm_resolution: int = 128, view_size: int = 512,
                  leaflet_size: int = 256, seed: int = 0, colors: str = "synthesis",
                  progress: ProgressCallback | None = None) -> Impostor:
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
    as_rng(seed)
    from treeform._shared.checks import check_choice

    check_choice(colors, "colors", IMPOSTOR_COLORS)
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
        verts, tris, off = [], [], 0
        for p in mesh.parts:
            verts.append(p.positions.astype(np.float64))
            tris.append(p.indices.astype(np.int64) + off)
            off += p.n_vertices
        verts = np.concatenate(verts)
        radii = render_radial_cubemap(verts, np.concatenate(tris), center, resolution=rdm_resolution)
        # thin parts (twigs, a trunk far below the centre, small cards) can fall between texel
        # centres: every vertex also raises its own texel, so the map holds the whole tree
        from treeform.structures.rdm import direction_to_texel

        d = verts - center
        f, r, c = direction_to_texel(d, rdm_resolution)
        np.maximum.at(radii, (f, r, c), np.linalg.norm(d, axis=1).astype(np.float32))
        rdm = RadialDistanceMap(center, radii)
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
    manifest = {
        "treeform": __version__, "source": str(glb), "seed": int(seed),
        "leaflets": {"folder": "leaflets", "size": leaflet_size, "shape": "sphere", "leaves": leaflets.leaves},
        "color": {"faces": [f"color_{n}.png" for n in FACE_NAMES], "face_size": face, "order": "+X -X +Y -Y +Z -Z",
                  "made_by": colors,
                  "cross": "color_cross.png", "front": "front.png"},
        "rdm": {"file": "rdm.npz", "resolution": rdm_resolution, "center": [round(float(c), 6) for c in center],
                "mean_radius": round(rdm.mean_radius(), 6)},
        # the front view as the relief impostor's planar colour (seed 001 §4.1, for distant trees):
        # the crown centre's pixel and the view's scale there
        "front": {"file": "front.png", "center_px": [round(float(x), 3) for x in uvz[:2]],
                  "pixels_per_metre": round(float(front_cam.focal / uvz[2]), 6)},
    }
    result = Impostor(color, rdm, front, leaflets, manifest)
    if out_dir is not None:
        with timer.stage("export"):
            from treeform.io.images import write_png
            from treeform.io.outputs import StagedOutputs, write_json

            manifest["timings"] = {k: round(v, 4) for k, v in timer.timings.items()}
            with StagedOutputs(out_dir) as staged:
                staged.submit(*[lambda d, n=n, i=i: write_png(color[i], d / f"color_{n}.png")
                                for i, n in enumerate(FACE_NAMES)],
                              lambda d: write_png(cross_from_faces(color), d / "color_cross.png"),
                              lambda d: write_png(front, d / "front.png"),
                              lambda d: rdm.save(d / "rdm.npz"),
                              *leaflet_writers(leaflets, seed=seed, attractors=_LEAFLET_ATTRACTORS, folder="leaflets"),
                              lambda d: write_json(d / "impostor.json", manifest))
                result.files = staged.commit()
    manifest["timings"] = {k: round(v, 4) for k, v in timer.timings.items()}
    return result
