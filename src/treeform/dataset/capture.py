"""A synthetic multi-view capture of one tree in a park, with exact ground truth (seed 002 §3, issue 14).

:func:`synthetic_capture` grows a tree (or loads a third-party GLB), stands it in a small 3D
park and photographs it from ``views`` cameras on a circle around it, as a person walking
around the tree with a phone would: eye height, landscape 4:3, a phone's main-camera field
of view, JPEG with EXIF. It writes the ground truth every multi-view stage can be scored
against: the skeleton, the tree mesh, the cameras (in the format of
:meth:`treeform.sfm.result.SfmResult.cameras_json`) and per-view labels.

The park is real 3D geometry, because structure from motion needs parallax, not a picture
pasted behind each view: a ground with large, unique textures (grass with tufts and dry
spots, worn earth, a gravel path, leaf litter, stones, daisies, the trees' baked shadows;
a sharper second texture over the camera circle), a ring of hedges and garden walls and,
behind it, a ring of facades (windows, shop signs, posters, murals) and tree lines, 2–4
other grown trees, and props (benches, rocks, bins, planters, kiosks, notice boards) as
textured boxes. All props and walls are one :class:`~treeform.structures.MeshPart` over
one texture atlas (hundreds of small parts would overflow the renderer's buffer cache). The
sky is a gradient with soft clouds that depends on the view direction only (infinitely far,
so consistent between views).

Where things stand, so that nothing hides the trunk: the cameras stand on a circle of
radius R around the trunk and look inward. The walls, the background trees (their whole
crowns) and the tall props stand *outside* that circle: the disc is convex, so the segment
from any camera to any point of the tree inside it stays inside it, and scenery out there
shows only behind or beside the tree. Inside the circle stand only low props (below
1.2 m, under every eye at 1.4 m or more), each kept off every camera's line of sight to the
trunk: a line of sight to a point higher than the props passes above them everywhere, so
they could hide nothing but the foot of the trunk, and that they are kept clear of. They
give structure from motion texture near the tree, seen by every camera.

Images are rendered single-sample at twice the size and box-filtered (anti-aliasing); the
labels take the majority of each pixel's four sub-samples, as in
:func:`treeform.dataset.synthetic.make_sample`. Registration needs views no more than
about 15° apart (24 around the tree): in this scene COLMAP registers all of 24 views at
480 px or more, but only some of 12–18.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import shutil
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from treeform._shared.checks import check_choice, check_finite, check_int
from treeform._shared.errors import InputError, OutputError
from treeform._shared.rng import check_seed
from treeform._shared.timing import ProgressCallback, StageTimer

__all__ = ["CaptureResult", "FOCAL_35MM", "STAGES", "synthetic_capture"]

FOCAL_35MM = 25.0
"""35 mm-equivalent focal length of the virtual phone (its :data:`FOCAL_MM` lens on a 1/2.55" 4:3
sensor, a typical main camera), in mm. Defined by the diagonal of the frame, as phones write it and
as :func:`treeform.sfm.photos.exif_focal_px` reads it (``f_px = f35 * diag_px / 43.27``)."""
FOCAL_MM = 4.25
"""The lens's true focal length written to EXIF (a 1/2.55" sensor: 5.9 mm wide)."""
_SUPERSAMPLE = 2
_JPEG_QUALITY = 92
STAGES = ("tree", "scene", "render", "truth", "write")
"""The stages reported to ``progress``."""

LABELS = {"background": 0, "foliage": 1, "wood": 2}


@dataclass
class CaptureResult:
    """What :func:`synthetic_capture` wrote.

    Attributes
    ----------
    out : Path
        The capture folder.
    images : list of Path, length N
        ``out/images/view_00.jpg`` ...
    truth : dict of str -> Path or list of Path
        ``skeleton`` (absent for a GLB model), ``tree``, ``cameras``, ``meta`` and
        ``labels`` (a list, one PNG per view).
    height : float
        The tree's height in metres.
    seconds : float
        Wall-clock time of the whole call.
    timings : dict of str -> float
        Seconds per stage (:data:`STAGES`).
    """

    out: Path
    images: list
    truth: dict
    height: float
    seconds: float
    timings: dict = field(default_factory=dict)


# ============================================================================ checks
def _check_args(out, views, size, species, seed, model, clutter, radius, camera_height, progress) -> tuple:
    from treeform.growth.species import SPECIES
    from treeform.io.outputs import check_out_dir

    views = check_int(views, "views", 3, 360)
    size = check_int(size, "size", 64, 4096)
    seed = check_seed(seed)
    check_choice(species, "species", SPECIES)
    radius = check_finite(radius, "radius")
    if not 0.5 <= radius <= 10.0:
        raise InputError(f"radius: expected a multiple of the tree height in [0.5, 10], got {radius!r}")
    camera_height = check_finite(camera_height, "camera_height")
    if not 0.3 <= camera_height <= 10.0:
        raise InputError(f"camera_height: expected metres in [0.3, 10], got {camera_height!r}")
    if not isinstance(clutter, (bool, np.bool_)):
        raise InputError(f"clutter: expected True or False, got {clutter!r}")
    if progress is not None and not callable(progress):
        raise InputError(f"progress: expected a callable or None, got {type(progress).__name__}")
    if model is not None:
        model = Path(model)
        if not model.is_file():
            raise InputError(f"model: {model}: no such file")
        if model.suffix.lower() != ".glb":
            raise InputError(f"model: {model}: expected a .glb file")
    out = check_out_dir(out, "out")
    return out, views, size, seed, model, bool(clutter), radius, camera_height


# ============================================================================ trees
def _grow_tree(species: str, rng, lod: str):
    """A grown tree of ``species``: (skeleton, mesh) with random materials (as make_sample draws them)."""
    from treeform.dataset.synthetic import _BARK_VARIANTS, _LEAF_VARIANTS, _leaf_variant, _materials
    from treeform.geometry import LOD_PRESETS, foliage_budget, tree_mesh
    from treeform.growth.leaves import twig_foliage, twig_nodes
    from treeform.growth.phenomenological import grow
    from treeform.growth.species import load_species, load_species_appearance

    tree_seed = int(rng.integers(2**31))
    skeleton = grow(load_species(species), seed=tree_seed)
    skeleton.meta["species"] = species
    look = load_species_appearance(species)
    leaf_rgb = np.clip(np.asarray(look.leaf_color) * rng.normal(1.0, 0.06, 3) * rng.uniform(0.9, 1.1), 0.02, 1.0)
    n_leaves = int(round(3.0 * len(twig_nodes(skeleton))))
    n_leaves, factor = foliage_budget(skeleton, n_leaves, max_triangles=LOD_PRESETS[lod])
    foliage = twig_foliage(skeleton, leaf_color=leaf_rgb, size=look.leaf_size * factor, leaves=n_leaves, seed=rng)
    leaf_k, bark_k = int(rng.integers(_LEAF_VARIANTS)), int(rng.integers(_BARK_VARIANTS))
    mesh = tree_mesh(skeleton, foliage, max_triangles=LOD_PRESETS[lod], leaf_texture=_leaf_variant(leaf_k)[0],
                     seed=tree_seed)
    _materials(mesh, {"bark": bark_k, "leaves": leaf_k}, rng)
    return skeleton, mesh, tree_seed


def _read_model(path: Path):
    """A GLB tree as a :class:`Mesh` in treeform's frame: metres, Y up, base at the origin.

    The glTF node transforms are applied (glTF is Y up: a Z-up model carries its rotation in
    a node, as COLLADA2GLTF writes it). Parts are named ``leaves`` when their material is
    alpha-tested or blended (or named like leaves), else ``bark``; blended materials are
    alpha-tested at 0.5 instead, so that the labels are exact.
    """
    import io as _io

    from PIL import Image

    from treeform.io.gltf import accessor_array, read_glb, scene_primitives
    from treeform.structures import Material, Mesh, MeshPart

    gltf, bin_chunk = read_glb(path)
    parts, textures, groups = [], {}, {}
    try:
        mats = gltf.get("materials", [])
        for m, prim in scene_primitives(gltf, f"model: {path}"):
            if prim.get("mode", 4) != 4:
                continue
            att = prim["attributes"]
            pos = accessor_array(gltf, bin_chunk, att["POSITION"]).astype(np.float64) @ m[:3, :3].T + m[:3, 3]
            if "NORMAL" in att:
                nrm = accessor_array(gltf, bin_chunk, att["NORMAL"]).astype(np.float64) @ np.linalg.inv(m[:3, :3])
                nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-12)
            else:
                nrm = np.zeros_like(pos)
            uv = (accessor_array(gltf, bin_chunk, att["TEXCOORD_0"]).astype(np.float32) if "TEXCOORD_0" in att
                  else np.zeros((len(pos), 2), np.float32))
            idx = (accessor_array(gltf, bin_chunk, prim["indices"]).astype(np.int64).reshape(-1, 3)
                   if "indices" in prim else np.arange(len(pos) - len(pos) % 3).reshape(-1, 3))
            if np.linalg.det(m[:3, :3]) < 0:
                idx = idx[:, ::-1]
            mat = mats[prim["material"]] if "material" in prim else {}
            pbr = mat.get("pbrMetallicRoughness", {})
            ref = pbr.get("baseColorTexture")
            tex = None
            if ref is not None:
                k = gltf["textures"][ref["index"]]["source"]
                if k not in textures:
                    view = gltf["bufferViews"][gltf["images"][k]["bufferView"]]
                    start = view.get("byteOffset", 0)
                    with Image.open(_io.BytesIO(bin_chunk[start:start + view["byteLength"]])) as im:
                        textures[k] = np.ascontiguousarray(np.asarray(im.convert("RGBA")))
                tex = textures[k]
            mode = mat.get("alphaMode", "OPAQUE")
            name = str(mat.get("name", ""))
            leafy = mode != "OPAQUE" or any(w in name.lower() for w in ("leaf", "leaves", "foliage", "needle"))
            material = Material("leaves" if leafy else "bark", tuple(pbr.get("baseColorFactor", (1, 1, 1, 1))),
                                tex, "MASK" if mode == "BLEND" else mode, float(mat.get("alphaCutoff", 0.5)),
                                bool(mat.get("doubleSided", False)), float(pbr.get("roughnessFactor", 1.0)), 0.0)
            key = prim.get("material", -1)  # one part per material: the renderer caches a few dozen parts
            if key not in groups:
                groups[key] = (material, [])
            groups[key][1].append((pos, nrm, uv, idx))
    except InputError:
        raise
    except (KeyError, IndexError, TypeError, ValueError, OSError) as exc:
        raise InputError(f"model: {path}: malformed glTF mesh data ({type(exc).__name__})") from None
    if len(groups) > 32:
        raise InputError(f"model: {path}: {len(groups)} materials; at most 32 are supported")
    for material, pieces in groups.values():
        offsets = np.cumsum([0] + [len(p[0]) for p in pieces[:-1]])
        parts.append(MeshPart(np.concatenate([p[0] for p in pieces]), np.concatenate([p[1] for p in pieces]),
                              np.concatenate([p[2] for p in pieces]), None,
                              np.concatenate([p[3] + o for p, o in zip(pieces, offsets)]), material, material.name))
    if not parts or not sum(p.n_triangles for p in parts):
        raise InputError(f"model: {path}: the GLB holds no triangles")
    mesh = Mesh(parts)
    lo, hi = mesh.bounds()
    pts = np.concatenate([p.positions for p in parts]).astype(np.float64)
    foot = pts[pts[:, 1] <= lo[1] + 0.02 * (hi[1] - lo[1])]
    base = np.array([foot[:, 0].mean(), lo[1], foot[:, 2].mean()])
    for p in parts:
        p.positions = (p.positions - base).astype(np.float32)
    return mesh


# ============================================================================ textures
def _fbm(rng, h: int, w: int, scales, weights=None) -> np.ndarray:
    """Zero-mean, unit-std value noise: the sum of random grids every ``s`` texels, smoothly upsampled.

    Returns
    -------
    ndarray, shape (h, w), float32
    """
    import cv2

    out = np.zeros((h, w), np.float32)
    for s, a in zip(scales, weights if weights is not None else [1.0] * len(scales)):
        if s <= 1.0:
            out += a * rng.standard_normal((h, w), dtype=np.float32)
            continue
        gh, gw = int(math.ceil(h / s)) + 3, int(math.ceil(w / s)) + 3
        g = rng.standard_normal((gh, gw), dtype=np.float32)
        up = cv2.resize(g, (int(round(gw * s)), int(round(gh * s))), interpolation=cv2.INTER_CUBIC)
        oy, ox = int(s), int(s)
        out += a * up[oy:oy + h, ox:ox + w]
    out -= out.mean()
    out /= max(float(out.std()), 1e-6)
    return out


def _smoothstep(x, lo, hi):
    t = np.clip((x - lo) / (hi - lo), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def _mix(a, b, t):
    """Blend colour images / colours ``a`` and ``b`` by weight ``t`` (H, W)."""
    t = np.asarray(t, np.float32)[..., None]
    return a * (1.0 - t) + np.asarray(b, np.float32) * t


def _dots(img, rng, n, colors, jitter=18.0, sizes=(1, 2), where=None):
    """Scatter ``n`` small square dots (``sizes`` texels) of random ``colors`` onto float RGB ``img``, in place.

    ``where``: optional (H, W) probability map (dots are kept with that probability).
    """
    h, w = img.shape[:2]
    ys, xs = rng.integers(0, h, n), rng.integers(0, w, n)
    if where is not None:
        keep = rng.random(n, dtype=np.float32) < where[ys, xs]
        ys, xs = ys[keep], xs[keep]
    n = len(ys)
    col = np.asarray(colors, np.float32)[rng.integers(0, len(colors), n)] + rng.normal(0, jitter, (n, 3))
    k = rng.integers(sizes[0], sizes[1] + 1, n)
    for dy in range(max(sizes)):
        for dx in range(max(sizes)):
            sel = (dy < k) & (dx < k)
            img[np.minimum(ys[sel] + dy, h - 1), np.minimum(xs[sel] + dx, w - 1)] = col[sel]


def _ground_maps(rng, L: int, half: float, trees, path_pts, casters=(), sun=(0.0, 1.0, 0.0)) -> dict:
    """The park's ground at low resolution: colour and masks over [-half, half]² metres, (L, L) each.

    Grass (lush to dry patches, mottling), worn earth in patches and under every tree (a disc
    with a frayed edge), a gravel path, where leaf litter lies (under the crowns), and the soft
    shadows of the trees (``casters``: (P, 3) point arrays, e.g. leaf vertices, projected along
    the unit ``sun`` direction; baked, so that every view sees the same shadow). Row 0 is
    z = -half, column 0 is x = -half. :func:`_ground_texture` adds the fine detail.
    """
    import cv2

    ml = 2.0 * half / L  # metres per texel
    px = lambda metres: max(metres / ml, 1.0)  # noqa: E731
    big = _fbm(rng, L, L, [px(20), px(7)], [1.0, 0.6])
    mot = _fbm(rng, L, L, [px(1.6), px(0.6)], [1.0, 0.6])
    lush, dry = np.array([62, 104, 40], np.float32), np.array([134, 140, 74], np.float32)
    col = _mix(np.broadcast_to(lush, (L, L, 3)), dry, _smoothstep(big, -0.6, 1.6)) * (1.0 + 0.12 * mot)[..., None]

    zz, xx = np.meshgrid((np.arange(L) + 0.5) * ml - half, (np.arange(L) + 0.5) * ml - half, indexing="ij")
    earth = _smoothstep(_fbm(rng, L, L, [px(5), px(1.2)], [1.0, 0.5]), 1.7, 2.3)
    litter = np.zeros((L, L), np.float32)
    fray = _fbm(rng, L, L, [px(0.8), 1.0], [1.0, 0.5])
    for (tx, tz, r_trunk, r_crown) in trees:
        d = np.hypot(xx - tx, zz - tz)
        earth = np.maximum(earth, _smoothstep(-(d + 0.5 * fray - r_trunk), -0.4, 0.3))
        litter = np.maximum(litter, 0.6 * _smoothstep(-(d - r_crown), -1.5, 1.5))
    col = _mix(col, np.array([112, 88, 62], np.float32) * (1.0 + 0.15 * mot)[..., None], earth)

    mask = np.zeros((L, L), np.uint8)  # the path: a thick polyline with soft, frayed edges
    pts = np.round((np.asarray(path_pts) + half) / ml * 16).astype(np.int32)[:, None, :]
    cv2.polylines(mask, [pts], False, 255, thickness=int(px(2.4)), lineType=cv2.LINE_AA, shift=4)
    edge = cv2.GaussianBlur(mask.astype(np.float32) / 255.0, (0, 0), 0.8)
    gravel = np.clip(edge + 0.3 * fray * (edge > 0.05) * (edge < 0.95), 0, 1)
    col = _mix(col, (168, 158, 138), gravel)
    litter *= 1.0 - gravel

    shadow = np.zeros((L, L), np.float32)
    sun = np.asarray(sun, np.float64)
    for p in casters:
        flat = p[:, [0, 2]] - p[:, 1:2] / sun[1] * sun[[0, 2]]
        ij = np.floor((flat + half) / ml).astype(np.int64)
        ok = np.all((ij >= 0) & (ij < L), axis=1)
        np.add.at(shadow, (ij[ok, 1], ij[ok, 0]), 1.0)
    if len(casters) and shadow.max() > 0:
        shadow = cv2.GaussianBlur(shadow, (0, 0), px(0.35))
        shadow = _smoothstep(shadow / max(float(np.percentile(shadow[shadow > 0], 90)), 1e-6), 0.05, 0.9)
        col *= (1.0 - 0.5 * shadow)[..., None]
    grass = (1.0 - earth) * (1.0 - gravel)
    amp = 0.13 + 0.1 * earth + 0.2 * gravel
    return {"half": half, "color": col.astype(np.float32), "amp": amp.astype(np.float32),
            "litter": litter.astype(np.float32), "gravel": gravel.astype(np.float32), "grass": grass.astype(np.float32),
            "flowers": (0.7 * _smoothstep(big, 0.3, 1.2) * grass).astype(np.float32)}


def _ground_texture(rng, maps: dict, n: int, x0: float, z0: float, size: float) -> np.ndarray:
    """The ground over the square [x0, x0 + size] x [z0, z0 + size] metres: (n, n, 4) uint8.

    The colour of :func:`_ground_maps`, resampled, times luminance detail (stronger on gravel
    and earth), with tufts and dry spots, leaf litter, gravel grains, daisies and stones, all
    in metric sizes, so that textures of any window and resolution agree where they meet.
    """
    import cv2

    half = maps["half"]
    L = maps["color"].shape[0]
    m, ml = size / n, 2.0 * half / L
    a = m / ml  # output texel -> low-resolution texel (centre-aligned affine map)
    M = np.array([[a, 0.0, (x0 + 0.5 * m + half) / ml - 0.5], [0.0, a, (z0 + 0.5 * m + half) / ml - 0.5]])
    flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    warp = lambda img: cv2.warpAffine(img, M, (n, n), flags=flags, borderMode=cv2.BORDER_REPLICATE)  # noqa: E731
    lowres = {k: warp(maps[k]) for k in ("amp", "litter", "gravel", "grass", "flowers")}
    px = lambda metres: max(metres / m, 1.0)  # noqa: E731
    area = size * size

    # tufts and dry spots of 0.3-1.4 m: blobs large enough to outlast the mipmaps of the grazing
    # view, so that structure from motion finds them in the distance too
    tone = np.ones((n, n), np.float32)
    k = int(0.25 * area)
    xs, ys = rng.integers(0, n, k).tolist(), rng.integers(0, n, k).tolist()
    r = rng.uniform(0.15, 0.7, k) / m
    ax = np.maximum(1, r).astype(np.int64).tolist()
    ay = np.maximum(1, r * rng.uniform(0.4, 1.0, k)).astype(np.int64).tolist()
    ang, val = rng.uniform(0, 180, k).tolist(), rng.choice([0.62, 0.75, 1.25, 1.4], k) * rng.uniform(0.95, 1.05, k)
    for i, v in enumerate(val.tolist()):
        cv2.ellipse(tone, (xs[i], ys[i]), (ax[i], ay[i]), ang[i], 0, 360, v, -1)
    detail = _fbm(rng, n, n, [1.0, 2.0, px(0.15)], [1.0, 0.7, 0.6])
    img = warp(maps["color"])
    img *= (tone * (1.0 + lowres["amp"] * detail))[..., None]
    big = int(min(4, px(0.06)))
    _dots(img, rng, int(30 * area), [(150, 96, 40), (120, 70, 35), (185, 140, 60), (95, 60, 30), (170, 70, 40)],
          sizes=(max(1, big // 2), max(1, big)), where=lowres["litter"])
    _dots(img, rng, int(12 * area), [(120, 118, 112), (200, 196, 186), (90, 86, 80)],
          sizes=(1, int(min(3, px(0.04)))), where=lowres["gravel"])
    _dots(img, rng, int(2 * area), [(235, 235, 225), (240, 215, 60)], jitter=10,
          sizes=(1, int(min(3, px(0.03)))), where=lowres["flowers"])
    _dots(img, rng, int(5 * area), [(40, 70, 28), (50, 82, 34)], jitter=8, sizes=(max(1, big // 2), max(2, big)),
          where=lowres["grass"])
    out = np.clip(img, 0, 255).astype(np.uint8)
    k = int(0.3 * area)  # stones: a dark (shadow) ellipse under a lit one
    ys, xs = rng.integers(0, n, k).tolist(), rng.integers(0, n, k).tolist()
    r = np.maximum(rng.uniform(0.06, 0.3, k) / m, 1.0)
    ax = np.maximum(1, r.astype(np.int64)).tolist()
    ay = np.maximum(1, (r * rng.uniform(0.5, 0.9, k)).astype(np.int64)).tolist()
    ang, g = rng.uniform(0, 180, k).tolist(), rng.integers(95, 190, k).tolist()
    off = max(1, int(px(0.02)))
    for i in range(k):
        cv2.ellipse(out, (xs[i], ys[i]), (ax[i], ay[i]), ang[i], 0, 360, (g[i] // 2,) * 3, -1)
        cv2.ellipse(out, (xs[i] - off, ys[i] - off), (ax[i], ay[i]), ang[i], 0, 360, (g[i], g[i] - 4, g[i] - 10), -1)
    return np.dstack([out, np.full((n, n), 255, np.uint8)])


_PLASTER = [(222, 206, 172), (205, 184, 150), (186, 118, 84), (232, 226, 212), (165, 164, 158), (206, 174, 120),
            (160, 176, 184), (214, 196, 150), (176, 150, 130)]
_ROOFS = [(150, 70, 50), (80, 80, 86), (110, 60, 45), (60, 62, 70)]
_GREENS = [(38, 70, 30), (52, 88, 36), (70, 104, 44), (30, 56, 26), (84, 112, 52), (58, 80, 40)]


def _facade(rng, w: int, h: int, wm: float, hm: float) -> np.ndarray:
    """A building front, ``wm`` x ``hm`` metres on (h, w, 4) texels: plaster or brick, windows, a roof band."""
    import cv2

    sx, sy = w / wm, h / hm
    base = np.array(_PLASTER[int(rng.integers(len(_PLASTER)))], np.float32)
    noise = _fbm(rng, h, w, [sx * 3, sx * 0.6, 2.0, 1.0], [1.0, 0.5, 0.4, 0.3])
    img = np.broadcast_to(base, (h, w, 3)) * (1.0 + 0.07 * noise)[..., None]
    grime = np.linspace(0.0, 1.0, h, dtype=np.float32)[:, None] ** 3 * 0.18  # darker towards the foot
    img = img * (1.0 - grime)[..., None]
    if rng.random() < 0.35:  # brick
        bw, bh = max(3, int(0.24 * sx)), max(2, int(0.075 * sy))
        col = np.array([(150, 68, 48), (128, 58, 42), (168, 92, 62), (110, 52, 40)], np.float32)
        rows = np.arange(h) // bh
        shift = (rows % 2) * (bw // 2)
        cols = (np.arange(w)[None, :] + shift[:, None]) // bw
        ids = (rows[:, None] * 7919 + cols * 104729) % 9973
        brick_rng = np.random.default_rng(int(rng.integers(2**31)))
        table = col[brick_rng.integers(0, 4, 9973)] * brick_rng.uniform(0.85, 1.15, (9973, 1))
        img = table[ids] * (1.0 + 0.06 * noise)[..., None]
        mortar = ((np.arange(h) % bh) == 0)[:, None] | (((np.arange(w)[None, :] + shift[:, None]) % bw) == 0)
        img[mortar] = (185, 178, 165)
    out = np.clip(img, 0, 255).astype(np.uint8)
    roof = _ROOFS[int(rng.integers(len(_ROOFS)))]
    cv2.rectangle(out, (0, 0), (w, int(0.7 * sy)), tuple(int(c) for c in roof), -1)
    cv2.line(out, (0, int(0.7 * sy)), (w, int(0.7 * sy)), (235, 232, 222), max(1, int(0.12 * sy)))
    floor = rng.uniform(2.9, 3.4)
    ww, wh = rng.uniform(0.9, 1.4), rng.uniform(1.3, 1.7)
    pitch = rng.uniform(2.2, 3.4)
    frame = (240, 238, 230) if rng.random() < 0.6 else (90, 60, 40)
    shutters = rng.random() < 0.35
    shutter_col = (60, 100, 70) if rng.random() < 0.5 else (120, 80, 50)
    n_floors = int((hm - 1.2) // floor)
    for f in range(n_floors):
        y1 = hm - (f * floor + (1.0 if f == 0 else 0.9))  # sill height above ground, metres from the top
        for k in range(int(wm // pitch)):
            x0 = (k + 0.5) * pitch - ww / 2 + rng.normal(0, 0.03)
            if f == 0 and rng.random() < 0.25:  # a door
                p0, p1 = (int(x0 * sx), int((hm - 2.2) * sy)), (int((x0 + 1.1) * sx), h)
                cv2.rectangle(out, p0, p1, (70 + int(rng.integers(60)), 50, 40), -1)
                cv2.rectangle(out, p0, p1, frame, max(1, int(0.06 * sx)))
                continue
            p0 = (int(x0 * sx), int((y1 - wh) * sy))
            p1 = (int((x0 + ww) * sx), int(y1 * sy))
            glass = np.array([50, 62, 78]) + rng.integers(-15, 30)
            cv2.rectangle(out, p0, p1, tuple(int(c) for c in glass), -1)
            # sky reflection in the upper panes, a curtain sometimes
            cv2.rectangle(out, p0, (p1[0], p0[1] + (p1[1] - p0[1]) // 3), tuple(int(c) for c in glass + 40), -1)
            if rng.random() < 0.4:
                cw = int(rng.uniform(0.2, 0.5) * (p1[0] - p0[0]))
                cc = tuple(int(c) for c in rng.integers(150, 240, 3))
                cv2.rectangle(out, p0, (p0[0] + cw, p1[1]), cc, -1)
            cv2.rectangle(out, p0, p1, frame, max(1, int(0.07 * sx)))
            cv2.line(out, ((p0[0] + p1[0]) // 2, p0[1]), ((p0[0] + p1[0]) // 2, p1[1]), frame, max(1, int(0.05 * sx)))
            cv2.line(out, (p0[0] - 2, p1[1] + 1), (p1[0] + 2, p1[1] + 1), (225, 222, 215), max(1, int(0.06 * sy)))
            if shutters:
                sw = int(0.45 * ww * sx)
                cv2.rectangle(out, (p0[0] - sw, p0[1]), (p0[0] - 1, p1[1]), shutter_col, -1)
                cv2.rectangle(out, (p1[0] + 1, p0[1]), (p1[0] + sw, p1[1]), shutter_col, -1)
    _signs(out, rng, sx, sy, wm, hm)
    return np.dstack([out, np.full((h, w), 255, np.uint8)])


def _signs(out: np.ndarray, rng, sx: float, sy: float, wm: float, hm: float) -> None:
    """Shop signs, posters and a mural or two: large, unique, high-contrast marks (seen from afar), in place."""
    import cv2

    for _ in range(int(rng.integers(1, 3 + int(wm // 10)))):
        kind = rng.choice(["sign", "poster", "mural"] if hm > 4 else ["poster", "mural"])
        if kind == "sign":
            bw, bh = rng.uniform(2.5, 6.0), rng.uniform(0.5, 0.9)
        elif kind == "poster":
            bw, bh = rng.uniform(0.8, 1.6), rng.uniform(1.1, 2.0)
        else:
            bw, bh = rng.uniform(2.5, 5.0), rng.uniform(1.5, 4.0)
        bw, bh = min(bw, 0.9 * wm), min(bh, 0.8 * hm)
        x0 = rng.uniform(0, wm - bw)
        y0 = hm - bh - (rng.uniform(2.6, 3.0) if kind == "sign" else rng.uniform(0.3, max(0.35, hm - bh - 0.3)))
        p0, p1 = (int(x0 * sx), int(y0 * sy)), (int((x0 + bw) * sx), int((y0 + bh) * sy))
        ground = tuple(int(c) for c in rng.integers(20, 250, 3))
        cv2.rectangle(out, p0, p1, ground, -1)
        w, h = p1[0] - p0[0], p1[1] - p0[1]
        if w < 4 or h < 4:
            continue
        if kind == "sign":  # letters: dark or light blocks of random widths
            ink = (20, 20, 20) if sum(ground) > 380 else (245, 245, 240)
            x = p0[0] + h // 3
            while x < p1[0] - h // 3:
                cw = int(h * rng.uniform(0.25, 0.6))
                if rng.random() > 0.15:
                    cv2.rectangle(out, (x, p0[1] + h // 4), (min(x + cw, p1[0] - 1), p1[1] - h // 4), ink, -1)
                x += cw + max(1, h // 8)
        else:  # shapes: discs, bars and triangles in a few colours
            for _ in range(int(rng.integers(3, 9))):
                c = tuple(int(v) for v in rng.integers(0, 256, 3))
                cx, cy = p0[0] + int(rng.uniform(0, w)), p0[1] + int(rng.uniform(0, h))
                r = max(1, int(rng.uniform(0.1, 0.4) * min(w, h)))
                shape = rng.integers(3)
                if shape == 0:
                    cv2.circle(out, (cx, cy), r, c, -1)
                elif shape == 1:
                    cv2.rectangle(out, (cx - r, cy - r // 3), (cx + r, cy + r // 3), c, -1)
                else:
                    tri = np.array([[cx, cy - r], [cx - r, cy + r], [cx + r, cy + r]], np.int32)
                    cv2.fillPoly(out, [tri], c)
            cv2.rectangle(out, p0, p1, (235, 235, 230), max(1, int(0.05 * sx)))


def _foliage_wall(rng, w: int, h: int, wm: float, hm: float, *, hedge: bool) -> np.ndarray:
    """A hedge (clipped, flat top) or a line of trees (billowing top, trunks below) with alpha."""
    import cv2

    sx, sy = w / wm, h / hm
    base = np.array(_GREENS[int(rng.integers(len(_GREENS)))], np.float32)
    shade = _fbm(rng, h, w, [sx * (0.8 if hedge else 2.5), sx * 0.25, 2.0, 1.0], [1.0, 0.7, 0.6, 0.5])
    img = np.broadcast_to(base, (h, w, 3)) * (1.0 + 0.28 * shade)[..., None]
    alpha = np.zeros((h, w), np.uint8)
    out = np.clip(img, 0, 255).astype(np.uint8)
    if hedge:
        top = (0.08 * hm + 0.04 * hm * _fbm(rng, 1, w, [sx * 1.5, sx * 0.3])[0]) * sy
        alpha[np.arange(h)[:, None] >= top[None, :]] = 255
        blobs, rmin, rmax = int(wm * hm * 40), 0.04, 0.16
    else:
        # trunks in the lower part, crowns as overlapping discs filling to an irregular top
        for x in np.cumsum(rng.uniform(2.0, 5.0, int(wm / 2) + 2)):
            cx = int(x * sx)
            tw = max(1, int(rng.uniform(0.15, 0.4) * sx))
            cv2.rectangle(alpha, (cx - tw, int(0.6 * h)), (cx + tw, h), 255, -1)
            cv2.rectangle(out, (cx - tw, int(0.6 * h)), (cx + tw, h), (70, 58, 46), -1)
        for _ in range(int(wm * 1.2)):
            cx, cy = rng.uniform(0, wm), rng.uniform(0.15 * hm, 0.7 * hm)
            r = rng.uniform(1.2, 3.0)
            cv2.ellipse(alpha, (int(cx * sx), int(cy * sy)), (int(r * sx), int(r * sy)), 0, 0, 360, 255, -1)
        blobs, rmin, rmax = int(wm * hm * 6), 0.15, 0.6
    # leaf clumps: a dark shadow under a lighter, tinted top (random numbers drawn at once)
    cx, cy = rng.integers(0, w, blobs), rng.integers(0, h, blobs)
    r, squash = rng.uniform(rmin, rmax, blobs), rng.uniform(0.6, 1.0, blobs)
    cols = np.clip(base * rng.uniform(0.6, 1.6, (blobs, 1)) + rng.normal(0, 10, (blobs, 3)), 0, 255)
    lit, dark = cols.astype(np.int64).tolist(), (0.55 * cols).astype(np.int64).tolist()
    ax = np.maximum(1, (r * sx).astype(np.int64)).tolist()
    ay = np.maximum(1, (r * sy * squash).astype(np.int64)).tolist()
    inside = (alpha[cy, cx] > 0).tolist()
    for i, (x, y) in enumerate(zip(cx.tolist(), cy.tolist())):
        if inside[i]:
            cv2.ellipse(out, (x, y + max(1, ay[i] // 3)), (ax[i], ay[i]), 0, 0, 360, dark[i], -1)
            cv2.ellipse(out, (x, y), (ax[i], ay[i]), 0, 0, 360, lit[i], -1)
    return np.dstack([out, alpha])


def _prop_texture(rng, kind: str, w: int, h: int) -> np.ndarray:
    """The (h, w, 4) texture of a prop box: bench slats, rock, bin, planter, kiosk or notice board."""
    import cv2

    noise = _fbm(rng, h, w, [w / 4, w / 16, 2.0, 1.0], [1.0, 0.6, 0.5, 0.4])
    if kind == "bench":
        wood = np.array([122, 84, 52], np.float32) * rng.uniform(0.8, 1.2)
        grain = _fbm(rng, h, w, [6.0, 2.0], [1.0, 0.5])
        img = np.broadcast_to(wood, (h, w, 3)) * (1.0 + 0.12 * noise + 0.12 * grain)[..., None]
        slat = max(4, h // 6)
        img[(np.arange(h) % slat) < max(1, slat // 5)] *= 0.35
    elif kind == "rock":
        g = rng.uniform(105, 165)
        img = np.broadcast_to(np.array([g, g * 0.98, g * 0.94], np.float32), (h, w, 3)) * (1.0 + 0.2 * noise)[..., None]
        lichen = _smoothstep(_fbm(rng, h, w, [w / 8, 3.0]), 1.0, 1.6)
        img = _mix(img, (150, 150, 70), 0.7 * lichen)
    elif kind == "bin":
        col = np.array([(36, 66, 44), (40, 40, 44), (120, 30, 30), (30, 50, 90)][int(rng.integers(4))], np.float32)
        img = np.broadcast_to(col, (h, w, 3)) * (1.0 + 0.1 * noise)[..., None]
        rib = max(3, w // 12)
        img[:, (np.arange(w) % rib) < max(1, rib // 3)] *= 1.5
    elif kind == "planter":
        img = np.broadcast_to(np.array([170, 166, 158], np.float32), (h, w, 3)) * (1.0 + 0.12 * noise)[..., None]
        top = h // 2
        img[:top] = np.array([50, 90, 36], np.float32) * (1.0 + 0.3 * noise[:top])[..., None]
        _dots(img[:top], rng, w * top // 6, [(220, 40, 50), (240, 200, 40), (250, 250, 245), (150, 60, 180),
                                             (240, 120, 30)], jitter=12, sizes=(1, 3))
    else:  # kiosk / board: planks, posters with "text" lines
        col = np.array([(140, 98, 60), (90, 110, 90), (160, 150, 130), (100, 70, 50)][int(rng.integers(4))], np.float32)
        img = np.broadcast_to(col, (h, w, 3)) * (1.0 + 0.12 * noise)[..., None]
        plank = max(4, w // 14)
        img[:, (np.arange(w) % plank) == 0] *= 0.5
    out = np.clip(img, 0, 255).astype(np.uint8)
    if kind in ("kiosk", "board", "bin"):
        for _ in range(int(rng.integers(2, 7)) if kind != "bin" else 1):
            pw, ph = int(rng.uniform(0.15, 0.35) * w), int(rng.uniform(0.15, 0.4) * h)
            x0, y0 = int(rng.uniform(0, w - pw)), int(rng.uniform(0.05 * h, 0.9 * h - ph))
            paper = tuple(int(c) for c in rng.integers(120, 255, 3))
            cv2.rectangle(out, (x0, y0), (x0 + pw, y0 + ph), paper, -1)
            ink = tuple(int(c) for c in rng.integers(0, 110, 3))
            cv2.rectangle(out, (x0 + pw // 8, y0 + ph // 8), (x0 + pw - pw // 8, y0 + ph // 3), ink, -1)
            for yy in range(y0 + ph // 2, y0 + ph - 2, max(2, ph // 9)):
                xe = x0 + pw // 8 + int(rng.uniform(0.3, 0.75) * pw)
                cv2.line(out, (x0 + pw // 8, yy), (xe, yy), (30, 30, 30), 1)
    return np.dstack([out, np.full((h, w), 255, np.uint8)])


class _Atlas:
    """Shelf-packs texture tiles into one square atlas and hands out UV rectangles.

    Each tile is stored with a border of its own edge texels (``pad``), so that the mipmaps
    of one tile do not bleed in its neighbours' colours or the empty space's zero alpha.
    """

    pad = 4

    def __init__(self, size: int):
        self.size = size
        self.image = np.zeros((size, size, 4), np.uint8)
        self.x = self.y = self.row = 0

    def add(self, tile: np.ndarray) -> tuple:
        """Place ``tile``; returns (u0, v0, u1, v1) inset by one texel (v0 is the tile's top row)."""
        import cv2

        p = self.pad
        h, w = tile.shape[0] + 2 * p, tile.shape[1] + 2 * p
        if self.x + w > self.size:
            self.x, self.y, self.row = 0, self.y + self.row, 0
        if self.y + h > self.size or w > self.size:
            raise RuntimeError("texture atlas full")  # a sizing bug, never the user's input
        self.image[self.y:self.y + h, self.x:self.x + w] = cv2.copyMakeBorder(tile, p, p, p, p, cv2.BORDER_REPLICATE)
        s = float(self.size)
        x0, y0 = self.x + p, self.y + p
        uv = ((x0 + 1) / s, (y0 + 1) / s, (x0 + w - 2 * p - 1) / s, (y0 + h - 2 * p - 1) / s)
        self.x += w
        self.row = max(self.row, h)
        return uv


# ============================================================================ scene
class _Quads:
    """Textured quads collected into one MeshPart (positions (4Q, 3), UVs from the atlas)."""

    def __init__(self):
        self.pos, self.uv = [], []

    def quad(self, corners, uv):
        """``corners``: bottom-left, bottom-right, top-right, top-left (counter-clockwise seen from the front)."""
        u0, v0, u1, v1 = uv
        self.pos.append(np.asarray(corners, np.float64))
        self.uv.append([[u0, v1], [u1, v1], [u1, v0], [u0, v0]])

    def box(self, center, size, rot, uv, lift=None):
        """A box standing on the ground (no bottom face), turned ``rot`` radians about +Y."""
        sx, sy, sz = size
        c, s = math.cos(rot), math.sin(rot)
        R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
        lift = np.zeros(4) if lift is None else lift
        lo = np.array([[-sx, 0, sz], [sx, 0, sz], [sx, 0, -sz], [-sx, 0, -sz]]) / 2
        hi = lo + np.array([0.0, sy, 0.0])
        hi[:, 1] += lift
        lo, hi = lo @ R.T + center, hi @ R.T + center
        for i in range(4):
            j = (i + 1) % 4
            self.quad([lo[i], lo[j], hi[j], hi[i]], uv)
        self.quad([hi[0], hi[1], hi[2], hi[3]], uv)

    def part(self, material, name: str):
        from treeform.structures import MeshPart

        P = np.concatenate(self.pos)
        n = np.cross(P[1::4] - P[0::4], P[2::4] - P[0::4])
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
        idx = (np.array([[0, 1, 2], [0, 2, 3]])[None] + 4 * np.arange(len(self.pos))[:, None, None]).reshape(-1, 3)
        return MeshPart(P, np.repeat(n, 4, axis=0), np.concatenate(self.uv), None, idx, material, name)


def _path_points(rng, r_cam: float, half: float) -> np.ndarray:
    """A gently winding footpath across the park, passing between the tree and the cameras: (K, 2) x, z."""
    a = rng.uniform(0, 2 * math.pi)
    off = rng.uniform(0.45, 0.7) * r_cam
    t = np.linspace(-half, half, 200)
    wiggle = 0.08 * r_cam * np.sin(t / rng.uniform(6, 12) + rng.uniform(0, 6))
    d, n = np.array([math.cos(a), math.sin(a)]), np.array([-math.sin(a), math.cos(a)])
    return t[:, None] * d + (off + wiggle)[:, None] * n


def _ring_segments(rng, radius: float, spread: float, length: tuple, gap: float):
    """(a0, a1, r) wall segments around a ring: arcs of ``length`` metres, radii ``radius`` + U(0, spread)."""
    segs, a = [], rng.uniform(0, 2 * math.pi)
    end = a + 2 * math.pi
    while a < end - 1e-6:
        r = radius + rng.uniform(0, spread)
        da = min(rng.uniform(*length) / r, end - a)
        if rng.random() >= gap:
            segs.append((a, a + da, r))
        a += da
    return segs


def _scene(rng, tree, height: float, crown: float, eyes, trunk_r: float, clutter: bool, main_species, bg_rng,
           sun, texture: int = 4096):
    """Ground, walls, props and background trees around the tree; returns (parts, layout description).

    ``eyes``: (N, 3) camera positions; ``trunk_r``: the trunk's radius at its foot.
    """
    from treeform.growth.species import SPECIES
    from treeform.structures import Material

    cams_xz = [(float(x), float(z)) for x, _y, z in eyes]
    min_eye = float(min(y for _x, y, _z in eyes))
    r_cam = float(max(math.hypot(x, z) for x, z in cams_xz))
    # -- background trees: 2-4, other species, whole crown outside the camera circle
    others = [s for s in SPECIES if s != main_species]
    n_bg = int(bg_rng.integers(2, 5))
    kinds = [others[i] for i in bg_rng.permutation(len(others))[:n_bg]]
    bg_parts, bg_desc, trunks = [], [], []
    a0 = bg_rng.uniform(0, 2 * math.pi)
    for k, sp in enumerate(kinds):
        _sk, mesh, tseed = _grow_tree(sp, bg_rng, "low")
        top = float(mesh.bounds()[1][1])
        reach = float(np.max(np.hypot(*np.concatenate([p.positions for p in mesh.parts])[:, [0, 2]].T)))
        a = a0 + 2 * math.pi * k / n_bg + bg_rng.uniform(-0.4, 0.4)
        r = r_cam + reach + bg_rng.uniform(2.0, 7.0)
        spin = bg_rng.uniform(0, 2 * math.pi)
        c, s = math.cos(spin), math.sin(spin)
        R = np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]], np.float32)
        at = np.array([r * math.sin(a), 0.0, r * math.cos(a)], np.float32)
        for p in mesh.parts:
            p.positions = p.positions @ R.T + at
            p.normals = p.normals @ R.T
            bg_parts.append(p)
        trunks.append((float(at[0]), float(at[2]), reach))
        bg_desc.append({"species": sp, "seed": tseed, "position": [round(float(at[0]), 3), 0.0, round(float(at[2]), 3)],
                        "height": round(top, 3)})
    r_bg = max((math.hypot(x, z) + reach for x, z, reach in trunks), default=r_cam)

    # -- ground, walls (hedges / garden walls, then facades / tree lines behind), props
    r_hedge = max(r_bg + 2.0, 1.5 * r_cam)
    r_far = r_hedge + 6.0
    half = r_far + 22.0
    atlas = _Atlas(texture)
    q = _Quads()
    # texels per metre on walls: 36 (about a rendered pixel at that distance) unless the atlas would overflow
    wall_m2 = 2 * math.pi * ((r_far + 10.0) * 16.0 * 0.56 + (r_hedge + 3.0) * 3.0)
    density = min(36.0, math.sqrt(0.45 * atlas.size ** 2 / wall_m2))
    for a0_, a1_, r in _ring_segments(rng, r_hedge, 3.0, (8.0, 16.0), gap=0.3):
        p0, p1 = (r * math.sin(a0_), 0.0, r * math.cos(a0_)), (r * math.sin(a1_), 0.0, r * math.cos(a1_))
        wm, hm = math.dist(p0, p1), rng.uniform(1.6, 3.0)
        w, h = int(wm * density), int(hm * density)
        tile = (_foliage_wall(rng, w, h, wm, hm, hedge=True) if rng.random() < 0.7 else
                _facade(rng, w, h, wm, hm))  # a low garden wall: brick or plaster without windows fits
        q.quad([p1, p0, (p0[0], hm, p0[2]), (p1[0], hm, p1[2])], atlas.add(tile))  # front faces the park
    for a0_, a1_, r in _ring_segments(rng, r_far, 10.0, (12.0, 22.0), gap=0.0):
        p0, p1 = (r * math.sin(a0_), 0.0, r * math.cos(a0_)), (r * math.sin(a1_), 0.0, r * math.cos(a1_))
        facade = rng.random() < 0.55
        wm, hm = math.dist(p0, p1), (rng.uniform(8.0, 16.0) if facade else rng.uniform(8.0, 13.0))
        d = density * 0.75
        w, h = int(wm * d), int(hm * d)
        tile = _facade(rng, w, h, wm, hm) if facade else _foliage_wall(rng, w, h, wm, hm, hedge=False)
        q.quad([p1, p0, (p0[0], hm, p0[2]), (p1[0], hm, p1[2])], atlas.add(tile))  # front faces the park

    props = []
    if clutter:
        tall = ["bench", "bench", "rock", "rock", "bin", "planter", "kiosk", "board"]
        blocked = [(x, z, 1.0) for x, z, _reach in trunks]
        # outside the camera circle: anything (it can only show behind or beside the tree)
        n_out = int(rng.integers(26, 34))
        _place_props(rng, q, atlas, texture, props, n_out, tall, (r_cam + 1.5, r_hedge - 1.0),
                     lambda x, z, foot: not _near(x, z, foot + 0.8, blocked + props))
        # inside it: low props only (lower than every eye), off every camera's line of sight to the trunk
        low = ["bench", "rock", "rock", "bin", "planter"]
        n_in = int(rng.integers(6, 11)) if min_eye >= _LOW_PROPS + 0.1 else 0
        clear, inner = trunk_r + 0.5, max(3.0, 4 * trunk_r)

        def inside_ok(x, z, foot):
            if _near(x, z, foot + 0.8, props) or math.hypot(x, z) < inner + foot:
                return False
            for cx, cz in cams_xz:
                if math.hypot(x - cx, z - cz) < foot + 2.5:
                    return False
                t = np.clip((x * cx + z * cz) / (cx * cx + cz * cz), 0.0, 1.0)  # segment camera -> trunk axis
                if math.hypot(x - t * cx, z - t * cz) < foot + clear:
                    return False
            return True
        _place_props(rng, q, atlas, texture, props, n_in, low, (inner, 0.8 * r_cam), inside_ok)
    scenery = q.part(Material("scenery", texture=atlas.image, alpha_mode="MASK", double_sided=True, roughness=0.9),
                     "scenery")

    # the ground: one texture over the whole park, a sharper one over the camera circle (where the
    # cameras see the ground closest); 3 x 3 quads with the centre one apart, so no edge has a T-junction
    trees = [(0.0, 0.0, max(1.5, 0.12 * height), crown)] + [(x, z, 1.5, reach) for x, z, reach in trunks]
    casters = [p.positions.astype(np.float64) for p in list(tree.parts) + bg_parts if p.name == "leaves"]
    maps = _ground_maps(rng, texture // 4, half, trees, _path_points(rng, r_cam, half), casters, sun)
    inner = 1.1 * r_cam
    outer_tex = _ground_texture(rng, maps, texture // 2, -half, -half, 2 * half)  # seen from afar only
    inner_tex = _ground_texture(rng, maps, texture, -inner, -inner, 2 * inner)
    edges = [-half, -inner, inner, half]
    outer, centre = _Quads(), _Quads()
    for i in range(3):
        for j in range(3):
            x0, x1, z0, z1 = edges[i], edges[i + 1], edges[j], edges[j + 1]
            if (i, j) == (1, 1):
                centre.quad([(x0, 0, z1), (x1, 0, z1), (x1, 0, z0), (x0, 0, z0)], (0.0, 0.0, 1.0, 1.0))
            else:
                u = lambda v: (v + half) / (2 * half)  # noqa: E731
                outer.quad([(x0, 0, z1), (x1, 0, z1), (x1, 0, z0), (x0, 0, z0)], (u(x0), u(z0), u(x1), u(z1)))
    ground = [outer.part(Material("ground", texture=outer_tex, roughness=1.0), "ground"),
              centre.part(Material("ground_near", texture=inner_tex, roughness=1.0), "ground_near")]
    layout = {"background_trees": bg_desc, "props": len(props), "hedge_radius_m": round(r_hedge, 3),
              "facade_radius_m": round(r_far, 3), "ground_half_size_m": round(half, 3)}
    return bg_parts + ground + [scenery], layout


_PROP_SIZES = {"bench": ((1.6, 2.0), (0.45, 0.5), (0.45, 0.6)), "rock": ((0.5, 1.8), (0.3, 0.9), (0.5, 1.5)),
               "bin": ((0.5, 0.7), (0.9, 1.05), (0.5, 0.7)), "planter": ((1.2, 2.5), (0.4, 0.7), (0.8, 1.5)),
               "kiosk": ((2.0, 3.5), (2.2, 2.8), (1.8, 3.0)), "board": ((1.0, 1.8), (1.6, 2.2), (0.1, 0.15))}
"""Ranges of width, height and depth (metres) per prop kind; benches, rocks, bins, planters stay below 1.2 m."""
_LOW_PROPS = 1.2
"""Metres: no bench (with backrest), rock (with its tilted top), bin or planter is taller."""


def _near(x, z, reach, others) -> bool:
    """Whether (x, z) is closer than ``reach`` + r to any (x, z, r) of ``others``."""
    return any(math.hypot(x - ox, z - oz) < reach + orad for ox, oz, orad in others)


def _place_props(rng, q, atlas, texture: int, props: list, n: int, kinds, r_range, ok, tries: int = 2000) -> None:
    """Add up to ``n`` props of ``kinds`` at radii ``r_range`` where ``ok(x, z, footprint)``.

    Each prop placed is appended to ``props`` as (x, z, footprint radius).
    """
    placed = 0
    for _ in range(tries):
        if placed >= n:
            break
        kind = kinds[int(rng.integers(len(kinds)))]
        size = tuple(rng.uniform(*s) for s in _PROP_SIZES[kind])
        foot = 0.5 * math.hypot(size[0], size[2])
        lo, hi = r_range[0] + foot, r_range[1] - foot
        if hi <= lo:
            return
        r, a = rng.uniform(lo, hi), rng.uniform(0, 2 * math.pi)
        x, z = r * math.sin(a), r * math.cos(a)
        if not ok(x, z, foot):
            continue
        props.append((x, z, foot))
        placed += 1
        rot = a + (math.pi / 2 if kind in ("bench", "board") else 0.0) + rng.uniform(-0.4, 0.4)
        dens = 110.0 * texture / 4096  # texels per metre
        tw = int(np.clip(max(size[0], size[2]) * dens, 24, 320))
        th = int(np.clip(size[1] * dens, 16, 320)) if kind != "rock" else tw
        lift = rng.uniform(-0.3, 0.2, 4) * size[1] if kind == "rock" else None
        q.box((x, 0.0, z), size, rot, atlas.add(_prop_texture(rng, kind, tw, th)), lift)
        if kind == "bench":  # the backrest
            c, s = math.cos(rot), math.sin(rot)
            back = np.array([x, 0.0, z]) + np.array([s, 0.0, c]) * (-size[2] / 2 + 0.04)
            q.box(back, (size[0], 0.95, 0.06), rot, atlas.add(_prop_texture(rng, "bench", tw, max(16, int(dens)))))


# ============================================================================ cameras
def _aim(eye: np.ndarray, pts: np.ndarray, width: int, height: int, fov_y: float, yaw_j: float, roll: float):
    """A camera at ``eye`` centred on ``pts`` (yaw jittered by ``yaw_j`` of the slack); None if they don't fit."""
    from treeform.structures import Camera

    rel = pts - eye
    yaw = np.arctan2(rel[:, 0], rel[:, 2])
    yaw0 = math.atan2(-eye[0], -eye[2])
    dyaw = (yaw - yaw0 + math.pi) % (2 * math.pi) - math.pi
    pitch = np.arctan2(rel[:, 1], np.hypot(rel[:, 0], rel[:, 2]))
    cy = yaw0 + 0.5 * (dyaw.min() + dyaw.max())
    cp = 0.5 * (pitch.min() + pitch.max())
    fwd = np.array([math.sin(cy) * math.cos(cp), math.sin(cp), math.cos(cy) * math.cos(cp)])
    right = np.cross(fwd, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up0 = np.cross(right, fwd)
    up = math.cos(roll) * up0 + math.sin(roll) * right
    cam = Camera(width, height, fov_y, tuple(eye), tuple(eye + fwd), tuple(up), near=0.3, far=2000.0)
    uvz = cam.project(pts)
    margin = 0.03 * height
    slack_l, slack_r = uvz[:, 0].min() - margin, width - margin - uvz[:, 0].max()
    if min(slack_l, slack_r) < 0 or uvz[:, 1].min() < margin or uvz[:, 1].max() > height - margin:
        return None
    # a hand-held framing: shift the tree sideways within the slack
    shift = yaw_j * (slack_l + slack_r) / 2 / cam.focal
    if abs(shift) > 1e-9:
        c, s = math.cos(shift), math.sin(shift)
        f2 = c * fwd + s * right
        cam2 = Camera(width, height, fov_y, tuple(eye), tuple(eye + f2), tuple(up), near=0.3, far=2000.0)
        uvz = cam2.project(pts)
        if uvz[:, 0].min() >= margin and uvz[:, 0].max() <= width - margin:
            cam = cam2
    return cam


def _cameras(rng, pts, views: int, width: int, height: int, fov_y: float, dist: float, cam_h: float):
    """The capture circle: N cameras at jittered azimuths, heights and distances, each framing the whole tree."""
    cams, desc = [], []
    step = 2 * math.pi / views
    for k in range(views):
        az = k * step + rng.uniform(-0.12, 0.12) * min(step, math.radians(30))
        h = cam_h + rng.uniform(-0.2, 0.2)
        d = dist * rng.uniform(0.96, 1.04)
        yaw_j, roll = rng.uniform(-0.5, 0.5), math.radians(rng.uniform(-1.5, 1.5))
        cam = None
        for _ in range(60):
            eye = np.array([d * math.sin(az), h, d * math.cos(az)])
            cam = _aim(eye, pts, width, height, fov_y, yaw_j, roll)
            if cam is not None:
                break
            d *= 1.04
        if cam is None:  # pragma: no cover - 60 steps of 4 % move any tree into the frame
            raise InputError("radius: the tree does not fit in the frame")
        cams.append(cam)
        desc.append({"azimuth_deg": round(math.degrees(az), 4), "distance_m": round(d, 4), "height_m": round(h, 4),
                     "roll_deg": round(math.degrees(roll), 4)})
    return cams, desc


def _cam_to_world(cam) -> np.ndarray:
    """(4, 4) camera-to-world with OpenCV axes (x right, y down, z forward)."""
    r, u, f = cam.axes()
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = r, -u, f, cam.position
    return m


# ============================================================================ per view
def _sky_image(cam, clouds: np.ndarray, step: int = 8) -> np.ndarray:
    """Sky for ``cam``, (H, W, 3) uint8: a horizon-to-zenith gradient with soft clouds by view direction.

    The sky is infinitely far: its colour depends on the direction only, so it agrees between
    views. Computed every ``step`` pixels and upsampled (it is smooth).
    """
    import cv2

    w, h = int(cam.width), int(cam.height)
    gw, gh = -(-w // step) + 1, -(-h // step) + 1
    r, u, f = cam.axes()
    xs = (np.arange(gw, dtype=np.float64) * step - w / 2) / cam.focal
    ys = (h / 2 - np.arange(gh, dtype=np.float64) * step) / cam.focal
    d = r[None, None, :] * xs[None, :, None] + u[None, None, :] * ys[:, None, None] + f[None, None, :]
    d /= np.linalg.norm(d, axis=2, keepdims=True)
    el = np.arcsin(np.clip(d[..., 1], -1, 1))
    t = (np.clip(el / (math.pi / 2), 0, 1) ** 0.6)[..., None]
    sky = np.array([206, 220, 236]) * (1 - t) + np.array([96, 140, 206]) * t
    # clouds: a texture on a horizontal layer far above, seen through each direction
    n = clouds.shape[0]
    q = d[..., [0, 2]] / np.maximum(d[..., 1:2], 0.05) / _CLOUD_REACH
    m = ((q * 0.5 + 0.5) * (n - 1)).astype(np.float32)
    c = cv2.remap(clouds, m[..., 0], m[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    c = (c * _smoothstep(el, 0.09, 0.35))[..., None]  # thinning out towards the horizon
    sky = np.clip(np.rint(sky * (1 - c) + 248.0 * c), 0, 255).astype(np.uint8)
    return cv2.resize(sky, ((gw - 1) * step + 1, (gh - 1) * step + 1), interpolation=cv2.INTER_LINEAR)[:h, :w]


_CLOUD_REACH = 12.0
"""The cloud texture spans horizontal offsets up to this many times the layer's altitude."""


def _cloud_map(rng) -> np.ndarray:
    """(1024, 1024) float32 cloud cover of a horizontal layer (see :func:`_sky_image`)."""
    n = _fbm(rng, 1024, 1024, [40.0, 14.0, 5.0, 2.0], [1.0, 0.6, 0.35, 0.2])
    return (0.8 * _smoothstep(n, 0.2, 1.8)).astype(np.float32)


def _downsample(rgb: np.ndarray, labels: np.ndarray, f: int):
    """Box-filter (H f, W f, 3) uint8 ``f``x down; labels by majority of the sub-samples (wood on a tie).

    Returns (H, W, 3) uint8 and (H, W) uint8 labels.
    """
    import cv2

    h, w = rgb.shape[0] // f, rgb.shape[1] // f
    img = cv2.resize(rgb, (w, h), interpolation=cv2.INTER_AREA)
    # sub-sample counts: box means of 0/1 masks (exact in float32 for these few samples) times f²
    tree = cv2.resize((labels > 0).astype(np.float32), (w, h), interpolation=cv2.INTER_AREA) * (f * f)
    wood = cv2.resize((labels == LABELS["wood"]).astype(np.float32), (w, h), interpolation=cv2.INTER_AREA) * (f * f)
    lab = np.where(2 * tree >= f * f - 1e-3, np.where(2 * wood >= tree - 1e-3, LABELS["wood"], LABELS["foliage"]), 0)
    return img, lab.astype(np.uint8)


def _exif(k: int, width: int, height: int) -> bytes:
    """EXIF as a phone writes it: make, model, focal length, 35 mm equivalent, orientation, date."""
    from PIL import Image

    exif = Image.Exif()
    exif[0x010F] = "treeform"  # Make
    exif[0x0110] = "Synthetic Phone 1"  # Model
    exif[0x0112] = 1  # Orientation: top-left
    exif[0x0131] = "treeform synthetic_capture"  # Software
    exif[0x0132] = f"2024:05:18 10:{k // 60:02d}:{k % 60:02d}"  # DateTime
    ifd = exif.get_ifd(0x8769)
    ifd[0x920A] = FOCAL_MM  # FocalLength
    ifd[0xA405] = int(round(FOCAL_35MM))  # FocalLengthIn35mmFilm
    ifd[0x9003] = f"2024:05:18 10:{k // 60:02d}:{k % 60:02d}"  # DateTimeOriginal
    ifd[0xA002], ifd[0xA003] = int(width), int(height)  # PixelXDimension, PixelYDimension
    return exif.tobytes()


# ============================================================================ staging
def _publish(stage: Path, out: Path) -> None:
    """Move the staged ``images/`` and ``truth/`` into ``out`` (replacing earlier ones), then drop the stage."""
    if not out.exists():
        os.rename(stage, out)
        return
    old = Path(tempfile.mkdtemp(prefix=".treeform-old-", dir=out.parent))
    try:
        for name in sorted(os.listdir(stage)):
            if (out / name).exists():
                os.replace(out / name, old / name)
            os.replace(stage / name, out / name)
    finally:
        shutil.rmtree(old, ignore_errors=True)
        shutil.rmtree(stage, ignore_errors=True)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


# ============================================================================ public
def synthetic_capture(out, *, views: int = 24, size: int = 1024, species: str = "oak", seed: int = 0,
                      model: str | os.PathLike | None = None, clutter: bool = True, radius: float = 1.3,
                      camera_height: float = 1.6, progress: ProgressCallback | None = None) -> CaptureResult:
    """Photograph a grown tree in a 3D park from ``views`` cameras around it, with exact ground truth.

    The test and benchmark data of the multi-view method (seed 002 §3: a capture walks around
    the tree with a hand-held camera at eye height). Same arguments -> identical files, JPEG
    bytes included.

    Parameters
    ----------
    out : str or path-like
        The capture folder. Written all-or-nothing: everything is made in a hidden folder
        beside it and renamed into place at the end (an existing ``out`` keeps its other
        files; its ``images/`` and ``truth/`` are replaced).
    views : int
        Number of photos, 3–360, at evenly spaced azimuths (each jittered a little).
    size : int
        Image width in pixels, 64–4096; landscape 4:3 (height ``round(0.75 * size)``).
    species : str
        Growth preset of the tree (:data:`treeform.growth.species.SPECIES`).
    seed : int
        Seeds the tree, the park, the cameras and the sensor noise (independent streams).
    model : str or path-like, optional
        A third-party GLB tree instead of a grown one (glTF node transforms applied: Y up;
        base moved to the origin). There is then no skeleton truth.
    clutter : bool
        Props (benches, rocks, bins, planters, kiosks, notice boards) outside the camera circle.
    radius : float
        Camera distance from the trunk as a multiple of the tree height, 0.5–10 (a camera
        steps back, 4 % at a time, where the whole tree would not fit in its frame).
    camera_height : float
        Eye height in metres (each camera ±0.2 m).
    progress : callable, optional
        ``progress(stage, event, seconds)`` for the stages :data:`STAGES`.

    Returns
    -------
    CaptureResult

    Notes
    -----
    Files written::

        out/images/view_00.jpg ...     JPEG q92, EXIF Make/Model/FocalLength/FocalLengthIn35mmFilm
        out/truth/cameras.json         {name: {"K": 3x3, "cam_to_world": 4x4 (OpenCV axes), "size": [w, h]}}
        out/truth/labels/view_00.png   uint8: 0 background, 1 foliage, 2 wood (main tree only)
        out/truth/skeleton.json        TreeSkeleton (grown trees only)
        out/truth/tree.glb             the tree alone
        out/truth/meta.json            species, seed, height, views, size, fov, cameras, scene

    The cameras are pinhole with the principal point at the image centre and no distortion;
    ``f_px = 26 / 36 * width`` (a 26 mm-equivalent lens; vertical field of view about 55°).
    World frame: metres, Y up, tree base at the origin.

    Raises
    ------
    InputError
        A bad argument (one line naming it) or an unreadable model.
    OutputError
        ``out`` cannot be written.
    RenderError
        No OpenGL context.
    """
    from PIL import Image

    t_start = time.perf_counter()
    out, views, size, seed, model, clutter, radius, camera_height = _check_args(
        out, views, size, species, seed, model, clutter, radius, camera_height, progress)
    from treeform.io.gltf import write_glb
    from treeform.render import Lighting, Renderer
    from treeform.sfm.photos import DIAGONAL_35MM
    from treeform.structures import Mesh

    timer = StageTimer(progress)
    width, height = size, int(round(0.75 * size))
    f_px = FOCAL_35MM * math.hypot(width, height) / DIAGONAL_35MM
    fov_y = math.degrees(2.0 * math.atan(0.5 * height / f_px))
    stream = lambda k: np.random.default_rng([seed, k])  # noqa: E731

    with timer.stage("tree"):
        if model is None:
            skeleton, tree, tree_seed = _grow_tree(species, stream(1), "high")
        else:
            skeleton, tree, tree_seed = None, _read_model(model), None
        hi = tree.bounds()[1]
        tree_h = float(hi[1])
        pts = np.concatenate([p.positions for p in tree.parts]).astype(np.float64)
        crown = float(np.max(np.hypot(pts[:, 0], pts[:, 2])))
        wood = [p.positions for p in tree.parts if p.name == "bark"]
        foot = np.concatenate(wood) if wood else pts
        foot = foot[foot[:, 1] < 0.5]
        trunk_r = float(np.max(np.hypot(foot[:, 0], foot[:, 2]))) if len(foot) else 0.3
        # the points every frame must hold: a sample of the vertices, the extreme ones and the base
        extremes = np.concatenate([np.argmin(pts, axis=0), np.argmax(pts, axis=0)])
        sample = pts[np.random.default_rng(0).choice(len(pts), min(len(pts), 20000), replace=False)]
        sample = np.concatenate([sample, pts[extremes], [[0.0, 0.0, 0.0]]])

    with timer.stage("scene"):
        cams, cam_desc = _cameras(stream(2), sample, views, width, height, fov_y, radius * tree_h, camera_height)
        sun_rng = stream(6)
        sun_az, sun_el = sun_rng.uniform(0, 2 * math.pi), math.radians(sun_rng.uniform(35, 60))
        sun = (math.cos(sun_el) * math.sin(sun_az), math.sin(sun_el), math.cos(sun_el) * math.cos(sun_az))
        scenery, layout = _scene(stream(3), tree, tree_h, crown, [c.position for c in cams], trunk_r, clutter,
                                 species if model is None else None,
                                 stream(4), sun, texture=4096 if size >= 768 else 2048 if size >= 320 else 1024)
        scene = Mesh(list(tree.parts) + scenery)
        part_label = np.zeros(len(scene.parts) + 1, np.uint8)  # the extra last entry: part -1, the sky
        for i, p in enumerate(tree.parts):
            part_label[i] = LABELS["wood"] if p.name == "bark" else LABELS["foliage"]
        clouds = _cloud_map(stream(5))
        lighting = Lighting(direction=sun,
                            key=(0.78, 0.75, 0.68), sky=(0.42, 0.46, 0.52), ground=(0.24, 0.23, 0.2), specular=0.08)

    try:
        stage = Path(tempfile.mkdtemp(prefix=f".{out.name}-", dir=out.parent))
    except OSError as exc:
        raise OutputError(f"out {out}: cannot write ({exc.strerror})") from None
    digits = max(2, len(str(views - 1)))
    names = [f"view_{k:0{digits}d}" for k in range(views)]
    try:
        os.chmod(stage, 0o777 & ~_umask())  # mkdtemp makes it private; the result is an ordinary folder
        (stage / "images").mkdir()
        (stage / "truth" / "labels").mkdir(parents=True)
        with timer.stage("render"):
            f = _SUPERSAMPLE
            renderer = Renderer(cams[0], samples=1, background=(0.0, 0.0, 0.0, 0.0), lighting=lighting)
            try:
                for k, cam in enumerate(cams):
                    big = dataclasses.replace(cam, width=cam.width * f, height=cam.height * f)
                    renderer.camera = big
                    res = renderer.render(scene)
                    rgb = np.where(res.mask[..., None], res.color[..., :3], _sky_image(big, clouds))
                    img, lab = _downsample(rgb, part_label[res.part], f)
                    # sensor: a little exposure variation and noise
                    noise_rng = np.random.default_rng([seed, 7, k])
                    gain = np.float32(noise_rng.uniform(0.96, 1.04))
                    img = img * gain + noise_rng.standard_normal(img.shape, np.float32)
                    img = np.clip(np.rint(img, out=img), 0, 255, out=img).astype(np.uint8)
                    Image.fromarray(img).save(stage / "images" / f"{names[k]}.jpg", quality=_JPEG_QUALITY,
                                              exif=_exif(k, width, height))
                    Image.fromarray(lab).save(stage / "truth" / "labels" / f"{names[k]}.png")
            finally:
                renderer.release()
        with timer.stage("truth"):
            K = np.array([[f_px, 0.0, width / 2.0], [0.0, f_px, height / 2.0], [0.0, 0.0, 1.0]])
            cams_json = {f"{n}.jpg": {"K": np.round(K, 6).tolist(),
                                      "cam_to_world": np.round(_cam_to_world(c), 6).tolist(),
                                      "size": [width, height]} for n, c in zip(names, cams)}
            (stage / "truth" / "cameras.json").write_text(json.dumps(cams_json, indent=1))
            write_glb(tree, stage / "truth" / "tree.glb")
            if skeleton is not None:
                skeleton.save(stage / "truth" / "skeleton.json")
            meta = {
                "species": species if model is None else None, "model": str(model) if model is not None else None,
                "seed": seed, "tree_seed": tree_seed, "height": round(tree_h, 4), "crown_radius": round(crown, 4),
                "views": views, "size": [width, height], "fov_y_deg": round(fov_y, 4),
                "fov_x_deg": round(math.degrees(2 * math.atan(0.5 * width / f_px)), 4), "focal_px": round(f_px, 4),
                "focal_35mm": FOCAL_35MM, "focal_mm": FOCAL_MM, "skeleton": skeleton is not None,
                "skeleton_note": None if skeleton is not None else
                "a third-party model: no skeleton truth (truth/tree.glb is the mesh only)",
                "labels": LABELS, "radius": radius, "camera_height": camera_height, "clutter": clutter,
                "cameras": [{"name": f"{n}.jpg", **d} for n, d in zip(names, cam_desc)],
                "scene": layout, "sun": {"azimuth_deg": round(math.degrees(sun_az), 3),
                                         "elevation_deg": round(math.degrees(sun_el), 3)},
                "frame": "metres, Y up, tree base at the origin; cameras: OpenCV axes (x right, y down, z forward)",
            }
            (stage / "truth" / "meta.json").write_text(json.dumps(meta, indent=1))
        with timer.stage("write"):
            try:
                _publish(stage, out)
            except OSError as exc:
                raise OutputError(f"out {out}: write failed ({exc.strerror or exc})") from None
    except BaseException:
        shutil.rmtree(stage, ignore_errors=True)
        raise
    images = [out / "images" / f"{n}.jpg" for n in names]
    truth = {"cameras": out / "truth" / "cameras.json", "tree": out / "truth" / "tree.glb",
             "meta": out / "truth" / "meta.json", "labels": [out / "truth" / "labels" / f"{n}.png" for n in names]}
    if skeleton is not None:
        truth["skeleton"] = out / "truth" / "skeleton.json"
    return CaptureResult(out, images, truth, tree_h, time.perf_counter() - t_start, dict(timer.timings))
