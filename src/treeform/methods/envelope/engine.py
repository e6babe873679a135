"""Levels of detail for game engines: a tree as a chain of GLBs, and a forest as one instanced GLB.

An engine has no relief-mapping shader and no per-leaf clipping, so the chain bakes what the
forest renderer (:mod:`treeform.methods.envelope.forest`) draws into plain glTF:

* ``lod0.glb`` – the full mesh (the tree's own ``tree.glb``);
* ``lod1.glb`` – the billboard cloud: two crossed leaflet quads on each of the 144 branch
  points (seed 001 §4.2; a static quad cannot face the camera), each leaf outside the crown's
  RDM cut out of its quad's tile (the paper's per-leaf clipping, baked: the quads do not move),
  tinted with the colour cubemap in its direction, unlit (``KHR_materials_unlit``, the
  renderer's mean lighting baked in), over the trunk and limbs (``wood.glb``, lit);
* ``lod2.glb`` – impostor cards: three vertical planes through the crown's axis, 60° apart,
  each side textured with the relief-mapped RDM drawn from the direction it faces (six views
  in one atlas; seed 001 §4.1's renderer bakes them), unlit, alpha-tested;
* ``lods.json`` – the files, their triangles and the distances at which an engine switches.

:func:`forest_glb` writes a scattered forest as one GLB: each species' impostor cards once,
drawn at every tree with ``EXT_mesh_gpu_instancing`` (validated by the Khronos validator).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from treeform._shared.errors import InputError

__all__ = ["CARD_VIEWS", "CLOUD_TILE", "cloud_lod_mesh", "engine_writers", "forest_glb", "impostor_cards",
           "mean_lighting"]

CARD_VIEWS = 6
"""Sides of the impostor cards: three planes, both faces of each (every 60°)."""


def mean_lighting(lighting=None) -> np.ndarray:
    """The renderer's lighting averaged over all normal directions, per RGB channel.

    ``(sky + ground) / 2 + key / 4`` for :class:`~treeform.render.Lighting`'s hemisphere ambient
    plus its key light (the mean of ``max(n·l, 0)`` over the sphere is 1/4): what an unlit,
    baked colour is multiplied by so that it matches the lit meshes beside it.
    """
    from treeform.render import Lighting

    lt = lighting or Lighting()
    return 0.5 * (np.asarray(lt.sky) + np.asarray(lt.ground)) + 0.25 * np.asarray(lt.key)


def _bleed(rgba: np.ndarray, iterations: int = 6) -> np.ndarray:
    """Spread the colours of opaque texels into the transparent ones (no dark fringes when mip levels
    and filtering mix the two); alpha unchanged.

    ``iterations`` rings are the mean of their opaque neighbours (a smooth edge); every texel
    beyond takes the colour of its nearest opaque texel, so that no mip level of an engine (which
    averages colours without weighting them by alpha) reaches the black of an empty texel: a card
    128 texels wide seen a few pixels tall is sampled from its 5th to 7th level.
    """
    import cv2
    import scipy.ndimage as ndi

    out = rgba.copy()
    known = out[..., 3] >= 128
    for _ in range(iterations):
        if known.all():
            break
        w = cv2.dilate(known.astype(np.uint8), np.ones((3, 3), np.uint8)).astype(bool) & ~known
        acc = np.zeros(out.shape[:2] + (3,), np.float64)
        cnt = np.zeros(out.shape[:2], np.float64)
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                k = np.roll(np.roll(known, dy, 0), dx, 1)
                c = np.roll(np.roll(out[..., :3], dy, 0), dx, 1)
                acc += c * k[..., None]
                cnt += k
        fill = w & (cnt > 0)
        out[fill, :3] = (acc[fill] / cnt[fill, None]).astype(np.uint8)
        known = known | fill
    if known.any() and not known.all():
        iy, ix = ndi.distance_transform_edt(~known, return_distances=False, return_indices=True)
        out[~known, :3] = out[iy[~known], ix[~known], :3]
    return out


def impostor_cards(imp, *, size: int = 256, lighting=None, unlit: bool = False):
    """Six-view impostor cards of a tree, baked by the relief-mapped RDM renderer.

    Parameters
    ----------
    imp : Impostor
        :func:`~treeform.methods.envelope.impostor.make_impostor` / ``read_impostor``.
    size : int
        Edge of one view in texels (the atlas is 3 x 2 views).
    lighting : Lighting, optional
    unlit : bool
        Mark the material unlit (the light is baked in), for a renderer that would light it again;
        a GLB gets ``KHR_materials_unlit`` from its node either way.

    Returns
    -------
    Mesh
        One part, 12 triangles: single-sided quads (the two faces of each plane are separate
        quads facing opposite ways), an RGBA atlas, MASK at 0.5.
    """
    from treeform.render.impostor import render_rdm_impostor
    from treeform.structures.camera import Camera
    from treeform.structures.mesh import Material, Mesh, MeshPart

    rdm = imp.rdm
    lo, hi = rdm.bounds()
    c = np.asarray(rdm.center, np.float64)
    half = max(float(np.max(np.abs(np.r_[hi[[0, 2]] - c[[0, 2]], c[[0, 2]] - lo[[0, 2]]]))), 0.5 * float(hi[1] - lo[1]))
    mid = np.array([c[0], 0.5 * (lo[1] + hi[1]), c[2]])
    dist = 50.0 * half
    fov = math.degrees(2 * math.atan(half / dist))
    atlas = np.zeros((2 * size, 3 * size, 4), np.uint8)
    pos, uv = [], []
    for k in range(CARD_VIEWS):
        az = math.radians(60.0 * k)
        d = np.array([math.sin(az), 0.0, math.cos(az)])
        cam = Camera(size, size, fov, tuple(mid + d * dist), tuple(mid), near=dist - 2 * half, far=dist + 2 * half)
        res = render_rdm_impostor(rdm, cam, color=imp.color, lighting=lighting, opacity=imp.opacity)
        row, col = divmod(k, 3)
        atlas[row * size:(row + 1) * size, col * size:(col + 1) * size] = res.color
        right, up, _ = cam.axes()
        for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1)):  # counter-clockwise seen from d
            pos.append(mid + half * (sx * right + sy * up))
            uv.append(((col + 0.5 + 0.5 * sx) / 3.0, (row + 0.5 - 0.5 * sy) / 2.0))
    b = 4 * np.arange(CARD_VIEWS)
    idx = np.concatenate([np.stack([b, b + 1, b + 2], 1), np.stack([b, b + 2, b + 3], 1)])
    normals = np.repeat([[math.sin(math.radians(60.0 * k)), 0.0, math.cos(math.radians(60.0 * k))]
                         for k in range(CARD_VIEWS)], 4, axis=0)
    mat = Material(name="impostor_cards", texture=_bleed(atlas), alpha_mode="MASK", alpha_cutoff=0.5,
                   double_sided=False, roughness=1.0, metallic=0.0, unlit=unlit)
    part = MeshPart(np.asarray(pos, np.float32), normals.astype(np.float32), np.asarray(uv, np.float32), None,
                    idx.astype(np.uint32), mat)
    part.name = "impostor_cards"
    return Mesh([part])


CLOUD_TILE = 48
"""Edge in texels of one quad's tile in the billboard cloud's atlas (288 tiles with their borders: 884
texels, in a 1,024-texel square). 64 draws the same silhouettes (IoU against the mesh within 0.001)
in a 30 % larger GLB."""


def cloud_lod_mesh(imp, *, lighting=None, seed: int = 0, tile: int = CLOUD_TILE):
    """The billboard cloud as static geometry: two crossed quads per branch point, clipped per leaf.

    Each point gets two vertical quads at right angles, turned about +Y by a random angle, of
    the forest renderer's billboard edge. An engine cannot clip leaves in a shader, but a static
    quad's leaves do not move: each leaf's centre (the leaflet's centroid channel) is placed on
    its quad and tested against the radial distance map once, and the leaves outside the crown
    are cut out of that quad's own tile of an atlas, whole (seed 001 §4.2's clipping, baked). The
    texture is the leaflet's brightness (its AO included); each quad's vertex colour is the
    colour cubemap in the point's direction times :func:`mean_lighting`, over the leaves' mean
    brightness, so the unlit cloud matches lit meshes (and the impostor cards after it).

    Parameters
    ----------
    imp : Impostor
    lighting : Lighting, optional
    seed : int
        The quads' turns.
    tile : int
        Edge of one quad's tile in texels (8..512).

    Returns
    -------
    Mesh
        One part, 4 triangles a point, MASK, double-sided, an atlas of one tile a quad.
    """
    import cv2

    from treeform._shared.checks import check_int
    from treeform._shared.rng import as_rng
    from treeform.structures.mesh import Material, Mesh, MeshPart
    from treeform.structures.rdm import direction_to_texel

    tile = check_int(tile, "tile", 8, 512)
    rng = as_rng(seed)
    pts = np.asarray(imp.cloud_points, np.float64)
    n = len(pts)
    s = 0.5 * float(imp.cloud_size)
    leaf = imp.leaflets
    rgba = np.asarray(leaf.rgba, np.uint8)
    luma = rgba[..., :3].astype(np.float64) @ [0.299, 0.587, 0.114]
    ao = (leaf.ao if leaf.ao.ndim == 2 else leaf.ao[..., 0]).astype(np.float64) / 255.0
    shade = luma * (0.4 + 0.6 * ao)
    opaque = rgba[..., 3] >= 128
    ref = float(np.percentile(shade[opaque], 90)) if opaque.any() else 255.0
    grey = np.clip(shade / max(ref, 1.0) * 255.0, 0, 255).astype(np.uint8)
    tex = _bleed(np.dstack([grey, grey, grey, rgba[..., 3]]))
    tex = cv2.resize(tex, (tile, tile), interpolation=cv2.INTER_AREA)
    # each texel's leaf centre on the quad, (u, v) in [0, 1] (a branch texel: itself); nearest, never blended
    cen = cv2.resize(np.asarray(leaf.centroid, np.uint8)[..., :2], (tile, tile), interpolation=cv2.INTER_NEAREST)
    cu, cv_ = cen[..., 0].astype(np.float64) / 255.0, cen[..., 1].astype(np.float64) / 255.0
    d = pts - np.asarray(imp.rdm.center)
    f, r, c = direction_to_texel(d, imp.color.shape[1])
    # the texture holds the brightness over its 90th percentile; the colour is scaled back by the
    # leaves' mean over it, so the cloud's mean colour is the cubemap's (as the forest shader's tint)
    gain = ref / max(float(shade[opaque].mean()), 1.0) if opaque.any() else 1.0
    col = imp.color[f, r, c].astype(np.float64) / 255.0 * mean_lighting(lighting) * gain
    yaw = rng.uniform(0, np.pi, n)
    up = np.array([0.0, 1.0, 0.0])
    q_total = 2 * n
    grid = int(np.ceil(np.sqrt(q_total)))
    pad = 2  # transparent texels around each tile: no neighbour bleeds in through filtering
    cell = tile + 2 * pad
    side = 1 << int(np.ceil(np.log2(grid * cell)))  # a power of two: mip chains everywhere (WebGL 1 too)
    atlas = np.zeros((side, side, 4), np.uint8)
    pos, uv, nrm, colors = [], [], [], []
    corners = ((-1, -1), (1, -1), (1, 1), (-1, 1))
    cells = np.zeros((grid * grid, cell, cell, 4), np.uint8)  # quad k's tile is cell k, row by row
    cells[:q_total, pad:pad + tile, pad:pad + tile, :3] = tex[..., :3]
    for t, turn in enumerate((0.0, 0.5 * np.pi)):
        a = yaw + turn
        right = np.stack([np.cos(a), np.zeros(n), -np.sin(a)], 1)
        normal = np.stack([np.sin(a), np.zeros(n), np.cos(a)], 1)
        # the leaves' centres in the tree's frame, (n, tile, tile, 3); kept where inside the crown
        centre = pts[:, None, None, :] + 2 * s * ((cu - 0.5)[None, ..., None] * right[:, None, None, :]
                                                  + (0.5 - cv_)[None, ..., None] * up)
        keep = imp.rdm.contains(centre.reshape(-1, 3)).reshape(n, tile, tile)
        cells[t * n:(t + 1) * n, pad:pad + tile, pad:pad + tile, 3] = np.where(keep, tex[..., 3], 0)
        k = t * n + np.arange(n)
        gy, gx = np.divmod(k, grid)
        u0, v0 = (gx * cell + pad) / atlas.shape[1], (gy * cell + pad) / atlas.shape[0]
        du, dv = tile / atlas.shape[1], tile / atlas.shape[0]
        for sx, sy in corners:
            pos.append(pts + s * (sx * right + sy * up))
            uv.append(np.column_stack([u0 + du * (0.5 + 0.5 * sx), v0 + dv * (0.5 - 0.5 * sy)]))
            nrm.append(normal)
            colors.append(np.column_stack([col, np.ones(n)]))
    # vertex index = corner * (2n) + quad, quads = (turn, point)
    pos = np.stack(pos, 0)  # (8, n, 3): turn-major corners
    pos = np.concatenate([pos[0:4], pos[4:8]], axis=1).reshape(-1, 3)
    uv = np.concatenate([np.stack(uv[0:4]), np.stack(uv[4:8])], axis=1).reshape(-1, 2)
    nrm = np.concatenate([np.stack(nrm[0:4]), np.stack(nrm[4:8])], axis=1).reshape(-1, 3)
    colors = np.concatenate([np.stack(colors[0:4]), np.stack(colors[4:8])], axis=1).reshape(-1, 4)
    q = np.arange(q_total)
    corner = [k * q_total + q for k in range(4)]
    idx = np.concatenate([np.stack([corner[0], corner[1], corner[2]], 1), np.stack([corner[0], corner[2], corner[3]], 1)])
    atlas[:grid * cell, :grid * cell] = cells.reshape(grid, grid, cell, cell, 4).transpose(0, 2, 1, 3, 4) \
        .reshape(grid * cell, grid * cell, 4)
    mat = Material(name="billboard_cloud", texture=_bleed(atlas), alpha_mode="MASK", alpha_cutoff=0.5,
                   double_sided=True, roughness=1.0, metallic=0.0)
    part = MeshPart(pos.astype(np.float32), nrm.astype(np.float32), uv.astype(np.float32),
                    np.clip(colors, 0, 1).astype(np.float32), idx.astype(np.uint32), mat)
    part.name = "billboard_cloud"
    return Mesh([part])


def engine_writers(imp, glb: Path, *, near: float, far: float, folder: str = "engine", seed: int = 0) -> list:
    """Writers (:class:`~treeform.io.outputs.StagedOutputs`) of the LoD chain in ``folder``.

    ``near``: the full mesh's range in metres (to the crown centre); ``far``: where the billboard
    cloud gives way to the impostor cards (the forest's switch distance d).
    """
    import shutil

    from treeform.io.gltf import GlbNode, write_glb_scene
    from treeform.io.outputs import write_json

    if not 0 < near < far:
        raise InputError(f"switch distances: expected 0 < near < far, got {near}, {far}")
    cloud = cloud_lod_mesh(imp, seed=seed)
    cards = impostor_cards(imp)

    def into(d: Path) -> Path:
        target = d / folder
        target.mkdir(exist_ok=True)
        return target

    levels = [
        {"file": "lod0.glb", "representation": "full mesh", "from_m": 0.0, "to_m": float(near)},
        {"file": "lod1.glb", "representation": "billboard cloud (crossed leaflet quads, unlit) over the trunk and limbs",
         "from_m": float(near), "to_m": float(far),
         "triangles": int(cloud.n_triangles + imp.wood.n_triangles)},
        {"file": "lod2.glb", "representation": "impostor cards (6 views of the relief-mapped RDM, unlit)",
         "from_m": float(far), "to_m": None, "triangles": int(cards.n_triangles)},
    ]
    from treeform.io.gltf import read_glb_counts

    levels[0]["triangles"] = int(read_glb_counts(glb)[1])
    manifest = {"distance_to": "the crown centre", "crown_center": [round(float(x), 6) for x in imp.rdm.center],
                "levels": levels}
    return [lambda d: shutil.copyfile(glb, into(d) / "lod0.glb"),
            lambda d: write_glb_scene([GlbNode(cloud, unlit=True), GlbNode(imp.wood, name="wood")],
                                      into(d) / "lod1.glb"),
            lambda d: write_glb_scene([GlbNode(cards, unlit=True)], into(d) / "lod2.glb"),
            lambda d: write_json(into(d) / "lods.json", manifest)]


def forest_glb(species: list, trees: np.ndarray, path, *, ground=None, cards=None):
    """A scattered forest as one GLB: every species' impostor cards, GPU-instanced at its trees.

    Parameters
    ----------
    species : list of Species
        (:func:`~treeform.methods.envelope.forest.load_species`).
    trees : ndarray, shape (N, 7)
        ``x, y, z, scale, yaw, count, species`` rows (:func:`~treeform.methods.envelope.forest.scatter_trees`).
    path : path
    ground : MeshPart, optional
        Written as a plain node.
    cards : list of Mesh, optional
        Each species' :func:`impostor_cards`, made beforehand (they are drawn with OpenGL: on
        the thread that owns the context, not in an output writer's thread).
    """
    from treeform.io.gltf import GlbNode, write_glb_scene
    from treeform.structures.mesh import Mesh

    nodes = [] if ground is None else [GlbNode(Mesh([ground]), name="ground")]
    for k, s in enumerate(species):
        rows = trees[trees[:, 6] == k, :6]
        if len(rows):
            mesh = cards[k] if cards is not None else impostor_cards(s.impostor)
            nodes.append(GlbNode(mesh, name=s.name, instances=rows, unlit=True))
    return write_glb_scene(nodes, path)
