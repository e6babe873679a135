"""Wavefront OBJ + MTL writer (with one PNG per textured material).

OBJ's texture origin is the bottom-left corner, glTF's (and :class:`Mesh`'s) the top-left,
so ``vt`` is written as ``(u, 1 - v)``. Coordinates are written unchanged (metres, +Y up).
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from treeform._shared.errors import InputError
from treeform.io._atomic import atomic_paths
from treeform.structures.mesh import Material, Mesh

__all__ = ["write_obj"]


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


def _write_rows(f, arr: np.ndarray, fmt: str, chunk: int = 20000) -> None:
    """Write one formatted line per row; one C-level ``%`` per chunk (much faster than np.savetxt)."""
    arr = np.asarray(arr)
    for i in range(0, len(arr), chunk):
        block = arr[i:i + chunk]
        f.write(((fmt + "\n") * len(block)) % tuple(block.ravel().tolist()))


def write_obj(mesh: Mesh, path) -> Path:
    """Write ``mesh`` as ``<stem>.obj`` + ``<stem>.mtl`` (+ ``<stem>_<material>.png``), atomically.

    Each non-empty :class:`MeshPart` becomes an ``o``/``g`` group with ``usemtl``, written as
    ``v`` (positions; plus ``r g b`` vertex colours when some colour differs from 1),
    ``vt`` (``u, 1 - v``), ``vn`` and ``f v/vt/vn`` lines. The MTL has, per material,
    ``Kd`` (base colour), ``d`` (base alpha), ``Pr``/``Pm`` (roughness, metallic),
    ``map_Kd`` for a texture and ``map_d`` (the same PNG, whose alpha channel is the
    opacity) for MASK/BLEND materials whose texture has transparent pixels. All files are
    written to temporary names first and renamed together at the end, the ``.obj`` last.

    Parameters
    ----------
    mesh : Mesh
    path : str or path-like
        The ``.obj`` path; the ``.mtl`` and PNGs go next to it, named after its stem.

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
    from PIL import Image

    if not isinstance(mesh, Mesh):
        raise InputError(f"mesh: expected a treeform Mesh, got {type(mesh).__name__}")
    mesh.validate()
    path = Path(path)
    stem = path.stem if path.suffix.lower() == ".obj" else path.name
    mtl_path = path.with_name(stem + ".mtl")
    parts = [p for p in mesh.parts if p.n_vertices and p.n_triangles]

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
                Image.fromarray(np.ascontiguousarray(m.texture, np.uint8)).save(tmp_of[png_paths[name]], format="PNG")
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
        with open(tmp_of[path], "w", encoding="utf-8", newline="\n") as f:
            f.write(f"# treeform OBJ: {mesh.n_vertices} vertices, {mesh.n_triangles} triangles; metres, +Y up\n")
            f.write(f"mtllib {mtl_path.name}\n")
            offset = 1
            taken_groups: set[str] = set()
            for p in parts:
                group = _safe_name(p.name, taken_groups)
                f.write(f"o {group}\ng {group}\n")
                if np.any(p.colors[:, :3] != 1.0):
                    v = np.hstack([p.positions, np.clip(p.colors[:, :3], 0, 1)])
                    _write_rows(f, v, "v %.6g %.6g %.6g %.4g %.4g %.4g")
                else:
                    _write_rows(f, p.positions, "v %.6g %.6g %.6g")
                vt = np.column_stack([p.uvs[:, 0], 1.0 - p.uvs[:, 1]])
                _write_rows(f, vt, "vt %.6g %.6g")
                _write_rows(f, p.normals, "vn %.6g %.6g %.6g")
                f.write(f"usemtl {mat_names[id(p.material)]}\ns off\n")
                idx = p.indices.astype(np.int64) + offset
                _write_rows(f, np.repeat(idx, 3, axis=1), "f %d/%d/%d %d/%d/%d %d/%d/%d")
                offset += p.n_vertices
    return path
