"""Wavefront OBJ + MTL writer (with one PNG per textured material).

OBJ's texture origin is the bottom-left corner, glTF's (and :class:`Mesh`'s) the top-left,
so ``vt`` is written as ``(u, 1 - v)``. Coordinates are written unchanged (metres, +Y up).

Vertex colours: the GLB carries the leaf colours as ``COLOR_0`` multiplied with the leaf
texture, but OBJ has no standard vertex colour (the ``v x y z r g b`` extension is read by
some tools, e.g. Blender into a colour attribute, yet no importer feeds it into the
material). So the colours of a textured part are baked into its texture instead
(:func:`bake_vertex_colors`): the face colours are clustered into at most 64 swatches, the
texture is repeated once per swatch in an atlas, each tile multiplied by its swatch colour,
and every face's UVs are moved into its swatch's tile -- any OBJ viewer that shows
``map_Kd`` shows the colours.
"""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import numpy as np

from treeform._shared.checks import check_choice
from treeform._shared.errors import InputError
from treeform.io._atomic import atomic_paths
from treeform.structures.mesh import Material, Mesh, MeshPart

__all__ = ["BAKE_CLUSTERS", "MAX_ATLAS_TEXELS", "bake_vertex_colors", "write_obj"]

BAKE_CLUSTERS = 64
"""Most colour swatches (atlas tiles) :func:`bake_vertex_colors` makes of a part's colours."""
MAX_ATLAS_TEXELS = 4096 * 4096
"""Largest atlas (texels) a bake may make; a part whose atlas would not fit at least
``MIN_BAKE_CLUSTERS`` tiles (or one per distinct colour) keeps ``v x y z r g b`` colours."""
MIN_BAKE_CLUSTERS = 8


def _safe_name(name: str, taken: set[str]) -> str:
    """An OBJ/MTL/file-name-safe, unique version of ``name`` (no spaces or path characters)."""
    base = re.sub(r"[^A-Za-z0-9_-]+", "_", str(name)).strip("_") or "material"
    out, k = base, 1
    while out in taken:
        k += 1
        out = f"{base}_{k}"
    taken.add(out)
    return out


def _fmt_float(x: float) -> str:
    return f"{float(x):.6g}"


OBJ_DECIMALS = 6
"""Decimal places of the numbers in an OBJ (micrometres for positions in metres)."""


def _write_rows(f, arr: np.ndarray, prefix: str) -> None:
    """Write ``prefix`` and one row of ``arr`` per line to the binary file ``f``.

    Floats get :data:`OBJ_DECIMALS` places, trailing zeros dropped; an int64 (N, 3) array
    of one-based indices with prefix ``"f"`` becomes ``f a/a/a b/b/b c/c/c`` lines. Compiled
    (:mod:`treeform.io._text_kernels`): five times faster than Python's ``%`` and without the
    GIL. Values of 1e12 or more, or not finite, fall back to ``%.6g``.
    """
    from treeform.io import _text_kernels

    arr = np.ascontiguousarray(arr)
    if prefix == "f":
        f.write(_text_kernels.face_rows(arr.astype(np.int64, copy=False)).data)
        return
    arr = arr.astype(np.float64, copy=False)
    if np.all(np.abs(arr) < 1e12):
        f.write(_text_kernels.float_rows(np.frombuffer(prefix.encode(), np.uint8), arr, OBJ_DECIMALS).data)
        return
    fmt = prefix + " %.6g" * arr.shape[1] + "\n"
    for i in range(0, len(arr), 20000):
        block = arr[i:i + 20000]
        f.write(((fmt * len(block)) % tuple(block.ravel().tolist())).encode())


def write_obj(mesh: Mesh, path, *, colors: str = "bake") -> Path:
    """Write ``mesh`` as ``<stem>.obj`` + ``<stem>.mtl`` (+ ``<stem>_<material>.png``), atomically.

    Each non-empty :class:`MeshPart` becomes an ``o``/``g`` group with ``usemtl``, written as
    ``v`` (positions; plus ``r g b`` vertex colours when some colour differs from 1 and they
    were not baked), ``vt`` (``u, 1 - v``), ``vn`` and ``f v/vt/vn`` lines. With
    ``colors="bake"`` a textured part with vertex colours (the leaf cards) is first passed
    through :func:`bake_vertex_colors`: its PNG is then a colour-swatch atlas of its texture
    (at most 64 tiles, e.g. 2048² for a 256² leaf texture) and its vertices carry no colour,
    so viewers whose materials ignore vertex colours show the leaf colours too (Blender's
    OBJ importer, for one, makes ``r g b`` a colour attribute its material does not use);
    untextured parts, and parts whose atlas would not fit, keep ``v x y z r g b``.
    The MTL has, per material, ``Kd`` (base colour), ``d`` (base alpha), ``Pr``/``Pm``
    (roughness, metallic), ``map_Kd`` for a texture and ``map_d`` (the same PNG, whose alpha
    channel is the opacity) for MASK/BLEND materials whose texture has transparent pixels.
    All files are written to temporary names first and renamed together at the end, the
    ``.obj`` last.

    Parameters
    ----------
    mesh : Mesh
    path : str or path-like
        The ``.obj`` path; the ``.mtl`` and PNGs go next to it, named after its stem.
    colors : {"bake", "vertex"}
        ``"vertex"``: write colours only as ``v x y z r g b``, textures unchanged.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InputError
        ``mesh`` is not a Mesh or fails validation.
    OutputError
        The files cannot be written.
    """
    from treeform.io.images import texture_png

    if not isinstance(mesh, Mesh):
        raise InputError(f"mesh: expected a treeform Mesh, got {type(mesh).__name__}")
    mesh.validate()
    check_choice(colors, "colors", ("bake", "vertex"))
    path = Path(path)
    stem = path.stem if path.suffix.lower() == ".obj" else path.name
    mtl_path = path.with_name(stem + ".mtl")
    parts = [p for p in mesh.parts if p.n_vertices and p.n_triangles]
    if colors == "bake":
        parts = [b if (b := bake_vertex_colors(p)) is not None else p for p in parts]

    # materials (shared Material objects -> one entry)
    taken: set[str] = set()
    mat_names: dict[int, str] = {}
    mats: list[tuple[str, Material]] = []
    for p in parts:
        if id(p.material) not in mat_names:
            mat_names[id(p.material)] = _safe_name(p.material.name, taken)
            mats.append((mat_names[id(p.material)], p.material))
    png_paths = {name: path.with_name(f"{stem}_{name}.png") for name, m in mats if m.texture is not None}

    outputs = [*png_paths.values(), mtl_path, path]
    with atomic_paths(outputs) as temps:
        tmp_of = dict(zip(outputs, temps))
        # textures
        for name, m in mats:
            if m.texture is not None:
                Path(tmp_of[png_paths[name]]).write_bytes(texture_png(m.texture))
        # MTL
        lines = ["# treeform MTL", ""]
        for name, m in mats:
            r, g, b, a = (float(c) for c in m.base_color)
            lines += [f"newmtl {name}",
                      f"Kd {_fmt_float(r)} {_fmt_float(g)} {_fmt_float(b)}",
                      "Ka 0 0 0", "Ks 0 0 0", "illum 1",
                      f"d {_fmt_float(a)}",
                      f"Pr {_fmt_float(m.roughness)}", f"Pm {_fmt_float(m.metallic)}"]
            if m.texture is not None:
                png = png_paths[name].name
                lines.append(f"map_Kd {png}")
                if m.alpha_mode != "OPAQUE" and np.any(m.texture[..., 3] < 255):
                    lines.append(f"map_d {png}")
            lines.append("")
        tmp_of[mtl_path].write_text("\n".join(lines), encoding="utf-8")
        # OBJ
        with open(tmp_of[path], "wb") as f:
            f.write(f"# treeform OBJ: {mesh.n_vertices} vertices, {mesh.n_triangles} triangles; metres, +Y up\n"
                    f"mtllib {mtl_path.name}\n".encode())
            offset = 1
            taken_groups: set[str] = set()
            for p in parts:
                group = _safe_name(p.name, taken_groups)
                f.write(f"o {group}\ng {group}\n".encode())
                if np.any(p.colors[:, :3] != 1.0):
                    _write_rows(f, np.hstack([p.positions, np.clip(p.colors[:, :3], 0, 1)]), "v")
                else:
                    _write_rows(f, p.positions, "v")
                _write_rows(f, np.column_stack([p.uvs[:, 0], 1.0 - p.uvs[:, 1]]), "vt")
                _write_rows(f, p.normals, "vn")
                f.write(f"usemtl {mat_names[id(p.material)]}\ns off\n".encode())
                _write_rows(f, p.indices.astype(np.int64) + offset, "f")
                offset += p.n_vertices
    return path


# --------------------------------------------------------------------------- colour bake
def _srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """sRGB-encoded values in [0, 1] -> linear (IEC 61966-2-1)."""
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def _linear_to_srgb(c: np.ndarray) -> np.ndarray:
    """Linear values in [0, 1] -> sRGB-encoded."""
    c = np.clip(c, 0.0, 1.0)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * np.power(c, 1.0 / 2.4) - 0.055)


def _kmeans(points: np.ndarray, weights: np.ndarray, k: int, *, iterations: int = 20) -> np.ndarray:
    """(N,) cluster labels of weighted points (N, D) into ``k`` clusters (N > k).

    Deterministic: k-means++ seeding with a fixed generator, then Lloyd iterations; an
    emptied cluster is re-seeded at the point farthest from its centre.
    """
    rng = np.random.default_rng(0)
    w = weights / weights.sum()
    sq = np.sum(points**2, axis=1)

    def dist2(c):  # (N, K) squared distances
        return np.maximum(sq[:, None] - 2.0 * points @ c.T + np.sum(c**2, axis=1)[None, :], 0.0)

    idx = [int(np.argmax(weights))]
    d2 = dist2(points[idx])[:, 0]
    for _ in range(1, k):
        p = d2 * w
        i = int(rng.choice(len(points), p=p / p.sum())) if p.sum() > 0 else int(np.argmax(d2))
        idx.append(i)
        d2 = np.minimum(d2, dist2(points[i:i + 1])[:, 0])
    c = points[idx].copy()
    for _ in range(iterations):
        dist = dist2(c)
        labels = np.argmin(dist, axis=1)
        mass = np.bincount(labels, weights, minlength=k)
        new = np.stack([np.bincount(labels, weights * points[:, j], minlength=k) for j in range(points.shape[1])], 1)
        empty = mass <= 0
        new[~empty] /= mass[~empty, None]
        if np.any(empty):
            far = np.argsort(-dist[np.arange(len(points)), labels], kind="stable")[: int(empty.sum())]
            new[empty] = points[far]
        done = np.allclose(new, c, atol=1e-6)
        c = new
        if done:
            break
    return np.argmin(dist2(c), axis=1)


def bake_vertex_colors(part: MeshPart, *, clusters: int = BAKE_CLUSTERS,
                       max_texels: int = MAX_ATLAS_TEXELS) -> MeshPart | None:
    """Bake a textured part's vertex colours into a colour-swatch atlas of its texture.

    glTF multiplies ``COLOR_0`` (linear) with the sRGB-decoded base-colour texture; this
    makes the same product a texture, for formats whose viewers ignore vertex colours (OBJ).
    Each face's colour (the mean of its corners') is clustered with a deterministic k-means
    on sRGB-encoded values into ``K <= clusters`` swatches (exact when there are at most
    ``clusters`` distinct colours); swatch ``k``'s colour ``c_k`` is the face-weighted mean
    of its members' linear colours. The atlas holds ``K`` tiles (``cols`` a power of two,
    ``rows = ceil(K / cols)``, ordered by luminance so neighbouring tiles are alike), tile
    ``k`` = ``srgb(linear(texture) · c_k)`` with alpha ``texture alpha · a_k``; each face's
    UVs are moved into its tile (vertices shared by faces of different swatches are
    duplicated). Positions, normals and triangles are unchanged.

    Parameters
    ----------
    part : MeshPart
        V vertices, F triangles, a material with an (H, W, 4) texture, UVs in [0, 1].
    clusters : int
        Most swatches (>= 1).
    max_texels : int
        Largest atlas in texels: ``K`` is also at most ``max_texels // (H·W)``.

    Returns
    -------
    MeshPart or None
        V' >= V vertices with white colours, the same triangles, a copy of the material
        whose texture is the (rows·H, cols·W, 4) uint8 atlas; None when there is nothing
        to bake or no atlas fits: no texture, all colours 1, UVs outside [0, 1] (a
        repeating texture cannot be tiled), or room for fewer than
        ``min(MIN_BAKE_CLUSTERS, distinct colours)`` tiles.

    Examples
    --------
    >>> tex = np.full((4, 4, 4), 255, np.uint8)
    >>> quad = MeshPart([[0, 0, 0], [1, 0, 0], [1, 1, 0]], [[0, 0, 1]] * 3, [[0, 1], [1, 1], [1, 0]],
    ...                 [[0.2, 0.5, 0.1, 1]] * 3, [[0, 1, 2]], Material(texture=tex))
    >>> baked = bake_vertex_colors(quad)
    >>> baked.material.texture.shape, baked.material.texture[0, 0].tolist(), baked.colors[0].tolist()
    ((4, 4, 4), [124, 188, 89, 255], [1.0, 1.0, 1.0, 1.0])
    """
    if not isinstance(part, MeshPart):
        raise InputError(f"part: expected a MeshPart, got {type(part).__name__}")
    if isinstance(clusters, bool) or not isinstance(clusters, (int, np.integer)) or clusters < 1:
        raise InputError(f"clusters: expected a positive integer, got {clusters!r}")
    tex = part.material.texture
    if tex is None or not part.n_triangles or np.all(part.colors == 1.0):
        return None
    if part.uvs.min() < -1e-4 or part.uvs.max() > 1.0 + 1e-4:
        return None
    h, w = tex.shape[:2]
    face_col = part.colors[part.indices].astype(np.float64).mean(axis=1)  # (F, 4)
    uniq, inv, counts = np.unique(face_col, axis=0, return_inverse=True, return_counts=True)
    inv = inv.reshape(-1)
    fit = int(max_texels) // (h * w)
    k = min(int(clusters), len(uniq), fit)
    if k < min(MIN_BAKE_CLUSTERS, len(uniq)):
        return None
    # cluster the distinct colours, perceptually (sRGB-encoded), weighted by their face counts
    if len(uniq) <= k:
        labels = np.arange(len(uniq))
    else:
        feats = np.column_stack([_linear_to_srgb(uniq[:, :3]), uniq[:, 3]])
        labels = _kmeans(feats, counts.astype(np.float64), k)
        _, labels = np.unique(labels, return_inverse=True)  # drop unused labels
        labels = labels.reshape(-1)
    k = int(labels.max()) + 1
    mass = np.bincount(labels, counts, minlength=k)
    swatch = np.stack([np.bincount(labels, counts * uniq[:, j], minlength=k) for j in range(4)], 1) / mass[:, None]
    order = np.argsort(swatch[:, :3] @ [0.2126, 0.7152, 0.0722], kind="stable")  # tile t holds swatch order[t]
    tile_of = np.empty(k, np.int64)
    tile_of[order] = np.arange(k)
    face_tile = tile_of[labels[inv]]  # (F,)
    cols = 1 << int(np.ceil(np.log2(max(np.ceil(np.sqrt(k)), 1))))
    rows = -(-k // cols)
    # atlas: tile t = srgb(linear(texture) * colour of swatch order[t])
    lin = _srgb_to_linear(np.arange(256, dtype=np.float32) / 255.0)[tex[..., :3]]
    # linear -> 8-bit sRGB through a 4096-step table (finer than one 8-bit step everywhere)
    encode = np.rint(_linear_to_srgb(np.arange(4096) / 4095.0) * 255.0).astype(np.uint8)
    alpha = tex[..., 3].astype(np.float64)
    atlas = np.zeros((rows * h, cols * w, 4), np.uint8)
    for t in range(k):
        c = swatch[order[t]]
        r, q = divmod(t, cols)
        step = np.rint(lin * (np.clip(c[:3], 0.0, 1.0) * 4095.0).astype(np.float32)).astype(np.int32)
        atlas[r * h:(r + 1) * h, q * w:(q + 1) * w, :3] = encode[step]
        atlas[r * h:(r + 1) * h, q * w:(q + 1) * w, 3] = np.rint(alpha * np.clip(c[3], 0.0, 1.0))
    # vertices: one per (vertex, tile) pair used by a face corner
    corner_v = part.indices.astype(np.int64)  # (F, 3)
    key = corner_v * k + face_tile[:, None]
    uniq_key, new_idx = np.unique(key.reshape(-1), return_inverse=True)
    src, tile = np.divmod(uniq_key, k)
    uv = part.uvs[src].astype(np.float64)
    tr, tq = np.divmod(tile, cols)
    new_uv = np.column_stack([(tq + uv[:, 0]) / cols, (tr + uv[:, 1]) / rows])
    material = dataclasses.replace(part.material, texture=atlas)
    return MeshPart(part.positions[src], part.normals[src], new_uv, np.ones((len(src), 4), np.float32),
                    new_idx.reshape(-1, 3), material, part.name)
