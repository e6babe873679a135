"""Leaflet billboards: RGBA textures of leaf clusters with the extra channels of seed 001 Fig. 13.

Seed 001 §3.6: groups of leaves and small branches are drawn as billboards "created by
instantiating multiple copies of a leaflet (a photograph of leaves or small branches ...).
The distribution and arrangement of leaflets inside each billboard is also based on the
Space Colonization algorithm with an arbitrary input volume ... spheres or cones". §4.2 /
Fig. 13 store, besides RGBA, normals, leaf centroids, texture coordinates, ambient
occlusion, depth and a type bit (leaves vs branches).

:func:`leaflet_billboard`:

1. blue-noise attractors in a unit **sphere** (root at its centre: the cluster can be
   turned any way) or a **cone** (root at the centre of its base, apex up: a branchlet that
   joins the branching structure at its base, §3.6);
2. the one space colonization grows the twigs; pipe-model radii;
3. one leaflet card hangs at every twig node (petiole at the node, blade along the twig,
   random roll, facing the viewer more than away), textured with the leaflet image;
4. one front render (near-orthographic, unlit albedo) through :class:`~treeform.render.Renderer`
   with its per-pixel part / triangle / normal / uv buffers gives every channel; ambient
   occlusion comes from 64 depth renders around the cluster (a point is lit from a
   direction when no geometry lies in front of it there), cosine-weighted.

Channel encodings (PNG, row 0 at the top):

=============  ==============================================================================
``rgba``       colour (straight alpha; the leaflet's colours, unlit)
``normal``     (n + 1) / 2 in the billboard's frame (x right, y up, z toward the viewer)
``centroid``   R, G = the pixel coordinates (x / W, y / H) of the centre of the leaf the
               pixel belongs to (branches: the pixel itself), B = 0
``uv``         R, G = the leaflet texture coordinates that instantiated the pixel (glTF:
               v down), B = 0
``ao``         ambient occlusion, 1 = open sky
``depth``      16-bit: 0 nearest ... 65535 farthest over the cluster's bounding sphere
``type``       255 leaf, 128 branch, 0 empty
=============  ==============================================================================
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from treeform._shared.checks import check_int
from treeform._shared.errors import InputError
from treeform._shared.rng import as_rng
from treeform._shared.timing import ProgressCallback, StageTimer

__all__ = ["CHANNELS", "LEAFLET_STAGES", "LeafletBillboard", "leaflet_billboard", "leaflet_volume", "read_leaflet_billboard"]

CHANNELS = ("rgba", "normal", "centroid", "uv", "ao", "depth", "type")
LEAFLET_STAGES = ("grow", "render", "occlusion", "export")
_SHAPES = ("sphere", "cone")
_TYPE_LEAF, _TYPE_BRANCH = 255, 128


@dataclass
class LeafletBillboard:
    """The channels of one leaflet billboard, (S, S, ...) arrays with row 0 at the top."""

    shape: str
    rgba: np.ndarray
    normal: np.ndarray
    centroid: np.ndarray
    uv: np.ndarray
    ao: np.ndarray
    depth: np.ndarray
    type: np.ndarray
    leaves: int
    nodes: int
    sheet: np.ndarray | None = None
    files: dict = field(default_factory=dict)
    timings: dict = field(default_factory=dict)


def leaflet_volume(shape: str):
    """``(contains, (lo, hi), root, direction)`` of the unit sphere or the cone (base radius 0.8, height 2)."""
    if shape == "sphere":
        return (lambda p: np.einsum("ij,ij->i", p, p) <= 1.0), (np.full(3, -1.0), np.full(3, 1.0)), \
            np.zeros(3), (0.0, 1.0, 0.0)
    if shape == "cone":
        def contains(p):
            y = p[:, 1]
            return (y >= 0) & (y <= 2.0) & (np.hypot(p[:, 0], p[:, 2]) <= 0.8 * (1.0 - y / 2.0))

        return contains, (np.array([-0.8, 0.0, -0.8]), np.array([0.8, 2.0, 0.8])), np.zeros(3), (0.0, 1.0, 0.0)
    raise InputError(f"shape: expected one of {', '.join(_SHAPES)}, got {shape!r}")


def _read_leaflet(leaflet) -> tuple[np.ndarray, bool]:
    """The leaflet texture (H, W, 4) uint8 and whether it is the default (tinted green by vertex colour)."""
    from treeform.geometry import leaf_texture

    if leaflet is None:
        return leaf_texture(128, seed=0, kind="leaf"), True
    if isinstance(leaflet, np.ndarray):
        t = leaflet
    else:
        from treeform.io import read_rgba

        t = read_rgba(leaflet)
    if t.ndim != 3 or t.shape[2] != 4 or t.dtype != np.uint8:
        raise InputError(f"leaflet: expected an (H, W, 4) uint8 RGBA image, got {t.shape} {t.dtype}")
    opaque = t[..., 3] >= 128
    if opaque.mean() < 0.02:
        raise InputError("leaflet: the image is (almost) fully transparent")
    t = t.copy()  # transparent texels take the mean leaf colour: filtering leaves no dark fringe
    t[~opaque, :3] = np.rint(t[opaque, :3].mean(axis=0)).astype(np.uint8)
    return t, False


def _grow(shape: str, attractors: int, rng):
    from treeform.growth.radii import branch_orders, pipe_model_radii
    from treeform.growth.sampling import blue_noise_points
    from treeform.growth.space_colonization import space_colonization
    from treeform.structures import TreeSkeleton

    contains, bounds, root, direction = leaflet_volume(shape)
    pts = blue_noise_points(contains, bounds, attractors, seed=rng)
    spacing = (np.prod(bounds[1] - bounds[0]) / max(len(pts), 1)) ** (1 / 3)
    sc = space_colonization(pts, root[None], influence_radius=4.0 * spacing, kill_distance=1.2 * spacing,
                            segment_length=0.5 * spacing, initial_direction=direction)
    radius = pipe_model_radii(sc.parent, tip_radius=0.004)
    return TreeSkeleton(sc.positions, sc.parent, radius, branch_orders(sc.parent, radius)), spacing


def _leaves(skeleton, size: float, rng):
    """One card per twig node (a node with at most 2 tips above it): petiole at the node."""
    from treeform.growth.leaves import twig_nodes
    from treeform.structures import Foliage

    nodes = twig_nodes(skeleton, 2)
    if len(nodes) == 0:
        nodes = np.arange(1, skeleton.n_nodes)
    d = skeleton.positions[nodes] - skeleton.positions[skeleton.parent[nodes]]
    d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
    up = d + rng.normal(0.0, 0.45, d.shape)  # the blade follows the twig, loosely
    up /= np.maximum(np.linalg.norm(up, axis=1, keepdims=True), 1e-12)
    n = rng.normal(0.0, 1.0, d.shape) + [0.0, 0.0, 1.2]  # blades face the viewer more than away
    n -= np.sum(n * up, axis=1, keepdims=True) * up
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    s = size * rng.uniform(0.8, 1.2, len(nodes))
    centre = skeleton.positions[nodes] + up * (0.5 * s)[:, None]
    tint = np.clip(np.array([0.42, 0.62, 0.26]) * rng.uniform(0.85, 1.15, (len(nodes), 1)), 0, 1)
    return Foliage(centre, n, up, s, tint, nodes)


def _fibonacci_directions(k: int) -> np.ndarray:
    i = np.arange(k) + 0.5
    phi = np.arccos(1.0 - 2.0 * i / k)
    theta = math.pi * (1.0 + 5.0**0.5) * i
    return np.c_[np.cos(theta) * np.sin(phi), np.cos(phi), np.sin(theta) * np.sin(phi)]


def _ambient_occlusion(mesh, points, normals, center, radius, *, directions: int = 64, resolution: int = 256):
    """Cosine-weighted share of ``directions`` in which nothing of ``mesh`` lies in front of each point."""
    from treeform.render import Renderer
    from treeform.structures import Camera

    fov = 10.0
    dist = radius / math.sin(math.radians(fov / 2)) * 1.02
    lit = np.zeros(len(points))
    weight = np.zeros(len(points))
    renderer = None
    try:
        for d in _fibonacci_directions(directions):
            up = (0.0, 1.0, 0.0) if abs(d[1]) < 0.95 else (0.0, 0.0, 1.0)
            cam = Camera(resolution, resolution, fov, tuple(center + d * dist), tuple(center), up,
                         near=dist - 1.5 * radius, far=dist + 1.5 * radius)
            if renderer is None:
                renderer = Renderer(cam, samples=1)
            renderer.camera = cam
            depth = renderer.render(mesh).depth
            cos = normals @ d
            front = cos > 0
            if not front.any():
                continue
            uvz = cam.project(points[front])
            u = np.clip(uvz[:, 0].astype(int), 0, resolution - 1)
            v = np.clip(uvz[:, 1].astype(int), 0, resolution - 1)
            seen = depth[v, u] >= uvz[:, 2] - 0.03 * radius  # nothing nearer to the light than the point
            lit[front] += cos[front] * seen
            weight[front] += cos[front]
    finally:
        if renderer is not None:
            renderer.release()
    return np.where(weight > 0, lit / np.maximum(weight, 1e-12), 1.0)


def leaflet_billboard(shape: str = "sphere", *, leaflet=None, size: int = 512, attractors: int = 800,
                      leaf_size: float | None = None, seed: int = 0, out=None,
                      progress: ProgressCallback | None = None) -> LeafletBillboard:
    """Make a leaflet billboard and its Fig. 13 channels (seed 001 §3.6, §4.2).

    Parameters
    ----------
    shape : {"sphere", "cone"}
        Volume of the space colonization.
    leaflet : path or ndarray (H, W, 4) uint8, optional
        RGBA picture of a leaf or leaflet (petiole at the bottom, tip at the top); default
        treeform's procedural leaf, tinted green.
    size : int
        Edge of the square textures in pixels (64–4096).
    attractors : int
        Blue-noise attraction points (more: denser twigs and more leaves).
    leaf_size : float, optional
        Card edge in units of the volume (sphere radius 1); default 2.5 attractor spacings.
    seed : int
        Same inputs + seed -> identical images.
    out : path, optional
        Directory for ``rgba.png``, ``normal.png``, ``centroid.png``, ``uv.png``, ``ao.png``,
        ``depth.png`` (16-bit), ``type.png``, ``channels.png`` (all channels, as Fig. 13) and
        ``leaflets.json``; written all-or-nothing.
    progress : callable, optional
        ``progress(stage, event, seconds)`` for :data:`LEAFLET_STAGES`.

    Returns
    -------
    LeafletBillboard

    Raises
    ------
    InputError
        Unknown shape, bad size, unreadable or empty leaflet.
    """
    from treeform.geometry import branch_mesh, leaf_cards
    from treeform.render import Lighting, Renderer
    from treeform.structures import Camera, Mesh

    if shape not in _SHAPES:
        raise InputError(f"shape: expected one of {', '.join(_SHAPES)}, got {shape!r}")
    size = check_int(size, "size", 64, 4096)
    attractors = check_int(attractors, "attractors", 20, 20000)
    if out is not None:
        from treeform.io.outputs import check_out_dir

        out = check_out_dir(out)
    texture, default_leaf = _read_leaflet(leaflet)
    rng = as_rng(seed)
    timer = StageTimer(progress)

    with timer.stage("grow"):
        skeleton, spacing = _grow(shape, attractors, rng)
        foliage = _leaves(skeleton, leaf_size or 2.5 * spacing, rng)
        if not default_leaf:
            foliage.color[:] = 1.0  # a photographed leaflet keeps its own colours
        bark = branch_mesh(skeleton, radial_segments=6)
        bark.material.texture = None
        bark.material.base_color = (0.36, 0.27, 0.18, 1.0)
        mesh = Mesh([bark, leaf_cards(foliage, texture=texture)])
    with timer.stage("render"):
        lo, hi = mesh.bounds()
        center = 0.5 * (lo + hi)
        radius = float(np.linalg.norm(hi - lo)) / 2
        fov = 8.0  # near-orthographic, framing the cluster's front extent tightly
        half = 0.52 * float(max(hi[0] - lo[0], hi[1] - lo[1]))
        dist = half / math.tan(math.radians(fov / 2)) + 0.5 * float(hi[2] - lo[2])
        cam = Camera(size, size, fov, tuple(center + [0.0, 0.0, dist]), tuple(center), near=dist - 1.5 * radius,
                     far=dist + 1.5 * radius)
        unlit = Lighting(key=(0.0, 0.0, 0.0), sky=(1.0, 1.0, 1.0), ground=(1.0, 1.0, 1.0))
        renderer = Renderer(cam, samples=1, aux=True, lighting=unlit)
        try:
            res = renderer.render(mesh)
        finally:
            renderer.release()
        covered = res.mask
        is_leaf = res.part == 1
        typ = np.where(is_leaf, _TYPE_LEAF, np.where(covered, _TYPE_BRANCH, 0)).astype(np.uint8)
        normal = np.zeros((size, size, 3), np.uint8)
        normal[covered] = np.clip(np.rint((res.normal[covered] + 1.0) * 127.5), 0, 255).astype(np.uint8)
        uv = np.zeros((size, size, 3), np.uint8)
        uv[is_leaf, :2] = np.clip(np.rint(res.uv[is_leaf] * 255.0), 0, 255).astype(np.uint8)
        rows, cols = np.mgrid[0:size, 0:size]
        cx, cy = (cols + 0.5) / size, (rows + 0.5) / size
        leaf_px = cam.project(foliage.positions)[:, :2]
        card = np.where(is_leaf, res.triangle // 2, 0)
        cx = np.where(is_leaf, leaf_px[card, 0] / size, cx)
        cy = np.where(is_leaf, leaf_px[card, 1] / size, cy)
        centroid = np.zeros((size, size, 3), np.uint8)
        centroid[..., 0] = np.where(covered, np.clip(np.rint(cx * 255), 0, 255), 0).astype(np.uint8)
        centroid[..., 1] = np.where(covered, np.clip(np.rint(cy * 255), 0, 255), 0).astype(np.uint8)
        near, far = dist - radius, dist + radius
        depth = np.zeros((size, size), np.uint16)
        depth[covered] = np.clip(np.rint((res.depth[covered] - near) / (far - near) * 65535), 0, 65535).astype(np.uint16)
    with timer.stage("occlusion"):
        v, u = np.nonzero(covered)
        pts = cam.unproject(u + 0.5, v + 0.5, res.depth[covered])
        occl = _ambient_occlusion(mesh, pts, res.normal[covered].astype(np.float64), center, radius)
        ao = np.zeros((size, size), np.uint8)
        ao[covered] = np.clip(np.rint(occl * 255), 0, 255).astype(np.uint8)
    result = LeafletBillboard(shape, res.color, normal, centroid, uv, ao, depth, typ, leaves=len(foliage),
                              nodes=skeleton.n_nodes)
    result.sheet = channel_sheet(result)
    if out is not None:
        with timer.stage("export"):
            result.files = _write(result, out, seed=seed, attractors=attractors)
    result.timings = dict(timer.timings)
    return result


def channel_sheet(b: LeafletBillboard, *, gap: int = 4) -> np.ndarray:
    """All channels side by side (as seed 001 Fig. 13): RGBA over a checkerboard, then the six others."""
    from treeform.report import over_checkerboard

    s = b.rgba.shape[0]
    grey = lambda a: np.repeat(a[..., None], 3, axis=2)  # noqa: E731
    tiles = [over_checkerboard(b.rgba), b.normal, b.centroid, b.uv, grey(b.ao),
             grey((b.depth >> 8).astype(np.uint8)), grey(b.type)]
    cols = 4
    rows = -(-len(tiles) // cols)
    sheet = np.full((rows * s + (rows + 1) * gap, cols * s + (cols + 1) * gap, 3), 32, np.uint8)
    for k, t in enumerate(tiles):
        r, c = divmod(k, cols)
        sheet[gap + r * (s + gap):gap + r * (s + gap) + s, gap + c * (s + gap):gap + c * (s + gap) + s] = t[..., :3]
    return sheet


def leaflet_writers(b: LeafletBillboard, *, seed: int, attractors: int, folder: str = "") -> list:
    """The writers (``writer(staging_dir)``, :class:`treeform.io.outputs.StagedOutputs`) of a
    leaflet billboard's files: every channel as a PNG, the channel sheet and ``leaflets.json``,
    in ``staging_dir / folder``."""
    from treeform import __version__
    from treeform.io import write_png
    from treeform.io.outputs import write_json

    def into(d: Path) -> Path:
        target = d / folder if folder else d
        target.mkdir(exist_ok=True)
        return target

    arrays = {"rgba": b.rgba, "normal": b.normal, "centroid": b.centroid, "uv": b.uv, "ao": b.ao, "depth": b.depth,
              "type": b.type, "channels": b.sheet}
    writers = [lambda d, k=k, a=a: write_png(a, into(d) / f"{k}.png") for k, a in arrays.items()]
    info = {"shape": b.shape, "seed": seed, "attractors": attractors, "leaves": b.leaves, "nodes": b.nodes,
            "size": int(b.rgba.shape[0]), "treeform": __version__,
            "encodings": {"normal": "(n + 1) / 2, x right, y up, z toward the viewer",
                          "centroid": "R, G = leaf centre pixel (x / W, y / H); branches: the pixel itself",
                          "uv": "R, G = leaflet texture coordinates (glTF, v down)", "ao": "1 = unoccluded",
                          "depth": "uint16, 0 nearest .. 65535 farthest over the bounding sphere",
                          "type": "255 leaf, 128 branch, 0 empty"}}
    writers.append(lambda d: write_json(into(d) / "leaflets.json", info))
    return writers


def _write(b: LeafletBillboard, out: Path, *, seed: int, attractors: int) -> dict:
    from treeform.io.outputs import write_staged

    return write_staged(out, leaflet_writers(b, seed=seed, attractors=attractors))


def read_leaflet_billboard(folder) -> LeafletBillboard:
    """A leaflet billboard folder (``treeform leaflets``, an impostor's ``leaflets/``) read back.

    Raises
    ------
    InputError
        A missing or unreadable channel, or channels of different sizes.
    """
    import json

    import cv2

    d = Path(folder)
    arrays = {}
    for name in CHANNELS:
        img = cv2.imread(str(d / f"{name}.png"), cv2.IMREAD_UNCHANGED)
        if img is None:
            raise InputError(f"{d / (name + '.png')}: missing or unreadable")
        if img.ndim == 3:  # BGR(A) -> RGB(A)
            img = np.dstack([img[..., 2::-1], img[..., 3:]]) if img.shape[2] == 4 else img[..., ::-1]
        arrays[name] = np.ascontiguousarray(img)
    if arrays["rgba"].ndim != 3 or arrays["rgba"].shape[2] != 4:
        raise InputError(f"{d / 'rgba.png'}: expected an RGBA image")
    if len({a.shape[:2] for a in arrays.values()}) != 1:
        raise InputError(f"{d}: the channels differ in size")
    info = {}
    if (d / "leaflets.json").is_file():
        try:
            info = json.loads((d / "leaflets.json").read_text())
        except (OSError, ValueError):
            info = {}
    return LeafletBillboard(shape=str(info.get("shape", "sphere")), leaves=int(info.get("leaves", 0)),
                            nodes=int(info.get("nodes", 0)), **arrays)
