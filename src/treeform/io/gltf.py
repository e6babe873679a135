"""glTF 2.0 binary (GLB) writer and a small reader, with numpy + json + struct only.

The layout follows the glTF 2.0 specification (Khronos, §4.4 "GLB File Format
Specification"): a 12-byte header, a JSON chunk padded with spaces and a BIN chunk padded
with zeros, every chunk and every bufferView aligned to 4 bytes.

Conventions: metres, right-handed, +Y up -- glTF's own, so no axis flip is applied.
Texture coordinates are taken as glTF stores them: (0, 0) is the top-left corner of the
texture (row 0 of ``Material.texture``), ``v`` grows downwards.
"""

from __future__ import annotations

import io
import json
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from treeform._shared.errors import InputError
from treeform.io._atomic import atomic_path
from treeform.structures.mesh import Material, Mesh, MeshPart

__all__ = ["GlbNode", "write_glb", "write_glb_scene", "read_glb", "read_glb_counts", "read_glb_mesh", "read_glb_textures", "accessor_array"]

_GLB_MAGIC = 0x46546C67  # b"glTF"
_CHUNK_JSON = 0x4E4F534A  # b"JSON"
_CHUNK_BIN = 0x004E4942  # b"BIN\0"

# componentType
_FLOAT = 5126
_UNSIGNED_SHORT = 5123
_UNSIGNED_INT = 5125
# bufferView.target
_ARRAY_BUFFER = 34962
_ELEMENT_ARRAY_BUFFER = 34963
# sampler
_LINEAR = 9729
_LINEAR_MIPMAP_LINEAR = 9987
_REPEAT = 10497
# primitive.mode
_TRIANGLES = 4

_COMPONENT_SIZE = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}


def _pad4(n: int) -> int:
    return (4 - n % 4) % 4


class _BinBuilder:
    """Accumulates the BIN chunk, bufferViews and accessors (every view 4-byte aligned)."""

    def __init__(self):
        self.chunks: list[bytes] = []
        self.length = 0
        self.buffer_views: list[dict] = []
        self.accessors: list[dict] = []

    def add_view(self, data: bytes, target: int | None = None) -> int:
        view = {"buffer": 0, "byteOffset": self.length, "byteLength": len(data)}
        if target is not None:
            view["target"] = target
        self.chunks.append(data)
        pad = _pad4(len(data))
        if pad:
            self.chunks.append(b"\0" * pad)
        self.length += len(data) + pad
        self.buffer_views.append(view)
        return len(self.buffer_views) - 1

    def add_accessor(self, array: np.ndarray, component_type: int, type_: str, *,
                     target: int, min_max: bool = False) -> int:
        array = np.ascontiguousarray(array)
        view = self.add_view(array.tobytes(), target)
        acc = {"bufferView": view, "byteOffset": 0, "componentType": component_type,
               "count": int(len(array)), "type": type_}
        if min_max:
            acc["min"] = [float(x) for x in array.min(axis=0)]
            acc["max"] = [float(x) for x in array.max(axis=0)]
        self.accessors.append(acc)
        return len(self.accessors) - 1

    def bytes(self) -> bytes:
        return b"".join(self.chunks)


def _unit_normals(normals: np.ndarray) -> np.ndarray:
    """(V, 3) float32 unit normals; zero-length normals become +Y (glTF requires unit length)."""
    n = normals.astype(np.float64)
    length = np.linalg.norm(n, axis=1)
    bad = ~(length > 1e-12)
    n[bad] = (0.0, 1.0, 0.0)
    length[bad] = 1.0
    return (n / length[:, None]).astype(np.float32)


def _vertex_tangents(positions: np.ndarray, normals: np.ndarray, uvs: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """(V, 4) float32 glTF tangents: the direction of increasing u, orthogonal to the unit normal,
    and w = +-1 the handedness (bitangent = w * normal x tangent), from the triangles' UV gradients
    summed at each vertex. Vertices without a usable gradient get any unit vector orthogonal to
    their normal (glTF requires unit tangents).
    """
    p = positions.astype(np.float64)
    uv = uvs.astype(np.float64)
    f = indices.reshape(-1, 3).astype(np.int64)
    e1, e2 = p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]]
    d1, d2 = uv[f[:, 1]] - uv[f[:, 0]], uv[f[:, 2]] - uv[f[:, 0]]
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    r = np.where(np.abs(det) > 1e-20, 1.0 / np.where(det == 0, 1.0, det), 0.0)[:, None]
    t_face = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) * r
    b_face = (e2 * d1[:, 0:1] - e1 * d2[:, 0:1]) * r
    T = np.zeros_like(p)
    B = np.zeros_like(p)
    for k in range(3):
        np.add.at(T, f[:, k], t_face)
        np.add.at(B, f[:, k], b_face)
    n = normals.astype(np.float64)
    T -= n * np.sum(n * T, axis=1, keepdims=True)
    length = np.linalg.norm(T, axis=1)
    bad = ~(length > 1e-12)
    if bad.any():  # any direction in the tangent plane
        a = np.where(np.abs(n[bad, 0:1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
        T[bad] = a - n[bad] * np.sum(n[bad] * a, axis=1, keepdims=True)
        length[bad] = np.linalg.norm(T[bad], axis=1)
    T /= length[:, None]
    w = np.where(np.sum(np.cross(n, T) * B, axis=1) < 0.0, -1.0, 1.0)
    return np.column_stack([T, w]).astype(np.float32)


def _encode_png(texture: np.ndarray) -> bytes:
    """PNG bytes of an (H, W, 4) uint8 RGBA texture (:func:`treeform.io.images.texture_png`)."""
    from treeform.io.images import texture_png

    return texture_png(texture)


def _clamp01(x) -> float:
    return float(min(max(float(x), 0.0), 1.0))


def _check_finite(part: MeshPart, index: int) -> None:
    for attr in ("normals", "uvs", "colors"):
        if not np.all(np.isfinite(getattr(part, attr))):
            raise InputError(f"mesh.parts[{index}] ({part.name!r}).{attr}: contains NaN or infinite values")


def write_glb(mesh: Mesh, path, *, generator: str = "treeform") -> Path:
    """Write ``mesh`` as a glTF 2.0 binary file (``.glb``), atomically.

    One glTF mesh with one triangle primitive per non-empty :class:`MeshPart` (parts with
    no vertices or no triangles are skipped), one node and one scene. Each primitive has
    ``POSITION`` (float VEC3 with min/max), ``NORMAL`` (normalised; zero-length normals
    become +Y), ``TEXCOORD_0`` and, only when some vertex colour differs from 1,
    ``COLOR_0`` (float VEC4, clamped to [0, 1]), and ``TANGENT`` (float VEC4) when its
    material has a normal texture; indices are ``UNSIGNED_SHORT`` when every
    index fits below 65535 (the primitive-restart value is never used), else
    ``UNSIGNED_INT``. Materials are PBR metallic-roughness with ``baseColorFactor``, an
    embedded PNG ``baseColorTexture`` when :attr:`Material.texture` is set (sampler
    LINEAR_MIPMAP_LINEAR / LINEAR, REPEAT), a ``normalTexture`` when
    :attr:`Material.normal_texture` is set, ``alphaMode``, ``alphaCutoff`` (MASK only) and
    ``doubleSided``. Parts that share one :class:`Material` object share one glTF material.

    Parameters
    ----------
    mesh : Mesh
        Parts with positions (V, 3), normals (V, 3), uvs (V, 2), colors (V, 4) and
        indices (F, 3); metres, +Y up (glTF's convention: no axis flip).
    path : str or path-like
        Output file; written to a temporary name first, then renamed.
    generator : str, keyword-only
        Stored in ``asset.generator``.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InputError
        ``mesh`` is not a Mesh, fails validation, has no triangles, or holds NaN/inf.
    OutputError
        ``path`` cannot be written.
    """
    if not isinstance(mesh, Mesh):
        raise InputError(f"mesh: expected a treeform Mesh, got {type(mesh).__name__}")
    return write_glb_scene([GlbNode(mesh)], path, generator=generator)


@dataclass
class GlbNode:
    """One node of :func:`write_glb_scene`: a mesh, drawn once or once per instance.

    ``instances``: (N, 6) rows ``x, y, z, scale, yaw, count`` (:mod:`treeform.render.instances`),
    written with ``EXT_mesh_gpu_instancing`` (TRANSLATION, ROTATION about +Y, uniform SCALE);
    ``unlit``: its materials get ``KHR_materials_unlit`` (colours baked in: billboards, impostor
    cards); ``name``: the node's name (default the parts' names joined by '+'); ``translation`` and
    ``yaw``: the place and turn of a node drawn once (one tree of a group placed from a photo).
    """

    mesh: Mesh
    name: str | None = None
    instances: np.ndarray | None = None
    unlit: bool = False
    translation: tuple | None = None
    """Where a node drawn once stands (x, y, z), and its turn about +Y in radians (``yaw``)."""
    yaw: float = 0.0


def write_glb_scene(nodes, path, *, generator: str = "treeform") -> Path:
    """Write several meshes, each a node, drawn once or GPU-instanced, as one GLB, atomically.

    Every node's mesh is written as :func:`write_glb` writes one mesh (one primitive per
    non-empty part; materials and textures shared where the same objects are). Instanced
    nodes carry ``EXT_mesh_gpu_instancing`` (listed in ``extensionsUsed`` and
    ``extensionsRequired``: a viewer without it would draw one tree where a forest stands);
    unlit nodes' materials, and materials that are unlit themselves (:attr:`Material.unlit`),
    ``KHR_materials_unlit``.

    Parameters
    ----------
    nodes : sequence of GlbNode
    path : str or path-like
    generator : str

    Returns
    -------
    Path

    Raises
    ------
    InputError
        A node that is not a :class:`GlbNode`, a mesh without triangles, bad instances.
    """
    nodes = list(nodes)
    if not nodes:
        raise InputError("nodes: nothing to write")
    b = _BinBuilder()
    materials: list[dict] = []
    material_index: dict[tuple, int] = {}
    images: list[dict] = []
    textures: list[dict] = []
    texture_index: dict[int, int] = {}
    meshes: list[dict] = []
    gnodes: list[dict] = []
    used: set = set()

    def material_of(m: Material, unlit: bool) -> int:
        if (id(m), unlit) in material_index:
            return material_index[(id(m), unlit)]
        pbr = {
            "baseColorFactor": [_clamp01(c) for c in m.base_color],
            "metallicFactor": _clamp01(m.metallic),
            "roughnessFactor": _clamp01(m.roughness),
        }
        def texture_of(array, name) -> int:
            key = id(array)
            if key not in texture_index:
                view = b.add_view(_encode_png(array))
                images.append({"bufferView": view, "mimeType": "image/png", "name": name})
                textures.append({"sampler": 0, "source": len(images) - 1})
                texture_index[key] = len(textures) - 1
            return texture_index[key]

        if m.texture is not None:
            pbr["baseColorTexture"] = {"index": texture_of(m.texture, m.name), "texCoord": 0}
        mat = {"name": m.name, "pbrMetallicRoughness": pbr, "alphaMode": m.alpha_mode,
               "doubleSided": bool(m.double_sided)}
        if m.normal_texture is not None and not unlit:
            mat["normalTexture"] = {"index": texture_of(m.normal_texture, f"{m.name}_normal"), "texCoord": 0}
            if float(m.normal_scale) != 1.0:
                mat["normalTexture"]["scale"] = float(m.normal_scale)
        if m.alpha_mode == "MASK":
            mat["alphaCutoff"] = max(float(m.alpha_cutoff), 0.0)
        if unlit:
            mat["extensions"] = {"KHR_materials_unlit": {}}
            used.add("KHR_materials_unlit")
        materials.append(mat)
        material_index[(id(m), unlit)] = len(materials) - 1
        return material_index[(id(m), unlit)]

    for k, node in enumerate(nodes):
        if not isinstance(node, GlbNode):
            raise InputError(f"nodes[{k}]: expected a GlbNode, got {type(node).__name__}")
        mesh = node.mesh
        if not isinstance(mesh, Mesh):
            raise InputError(f"mesh: expected a treeform Mesh, got {type(mesh).__name__}")
        mesh.validate()
        parts = [(i, p) for i, p in enumerate(mesh.parts) if p.n_vertices and p.n_triangles]
        if not parts:
            raise InputError("mesh: has no non-empty part (no triangles to write)")
        primitives: list[dict] = []
        for i, p in parts:
            _check_finite(p, i)
            attributes = {
                "POSITION": b.add_accessor(p.positions, _FLOAT, "VEC3", target=_ARRAY_BUFFER, min_max=True),
                "NORMAL": b.add_accessor(_unit_normals(p.normals), _FLOAT, "VEC3", target=_ARRAY_BUFFER),
                "TEXCOORD_0": b.add_accessor(p.uvs.astype(np.float32), _FLOAT, "VEC2", target=_ARRAY_BUFFER),
            }
            unlit = node.unlit or p.material.unlit
            if p.material.normal_texture is not None and len(p.indices) and not unlit:
                # with a normal map, the tangent space travels with the mesh (a client's generated one
                # may differ: the Khronos validator warns)
                attributes["TANGENT"] = b.add_accessor(
                    _vertex_tangents(p.positions, _unit_normals(p.normals), p.uvs, p.indices), _FLOAT, "VEC4",
                    target=_ARRAY_BUFFER)
            if np.any(p.colors != 1.0):
                colors = np.clip(p.colors, 0.0, 1.0).astype(np.float32)
                attributes["COLOR_0"] = b.add_accessor(colors, _FLOAT, "VEC4", target=_ARRAY_BUFFER)
            flat = p.indices.reshape(-1)
            if int(flat.max()) < 65535:
                idx = b.add_accessor(flat.astype("<u2"), _UNSIGNED_SHORT, "SCALAR", target=_ELEMENT_ARRAY_BUFFER)
            else:
                idx = b.add_accessor(flat.astype("<u4"), _UNSIGNED_INT, "SCALAR", target=_ELEMENT_ARRAY_BUFFER)
            primitives.append({"attributes": attributes, "indices": idx, "material": material_of(p.material, unlit),
                               "mode": _TRIANGLES, "extras": {"name": p.name}})
        name = node.name if node.name is not None else "+".join(p.name for _, p in parts)
        meshes.append({"name": name, "primitives": primitives})
        gnode = {"name": name, "mesh": len(meshes) - 1}
        if node.translation is not None or node.yaw:
            if node.instances is not None:
                raise InputError(f"nodes[{k}]: translation / yaw are for a node drawn once, not instanced")
            t = np.asarray(node.translation if node.translation is not None else (0.0, 0.0, 0.0), np.float64)
            if t.shape != (3,) or not np.all(np.isfinite(t)) or not np.isfinite(node.yaw):
                raise InputError(f"nodes[{k}]: translation must be 3 finite numbers and yaw finite, "
                                 f"got {node.translation}, {node.yaw}")
            gnode["translation"] = [float(x) for x in t]
            if node.yaw:
                gnode["rotation"] = [0.0, float(np.sin(0.5 * node.yaw)), 0.0, float(np.cos(0.5 * node.yaw))]
        if node.instances is not None:
            from treeform.render.instances import check_instances

            inst = check_instances(node.instances, f"nodes[{k}].instances").astype(np.float64)
            if not len(inst):
                raise InputError(f"nodes[{k}].instances: no instances (leave the node out)")
            half = 0.5 * inst[:, 4]
            quat = np.stack([np.zeros(len(inst)), np.sin(half), np.zeros(len(inst)), np.cos(half)], 1)
            gnode["extensions"] = {"EXT_mesh_gpu_instancing": {"attributes": {
                "TRANSLATION": b.add_accessor(inst[:, :3].astype(np.float32), _FLOAT, "VEC3", target=None),
                "ROTATION": b.add_accessor(quat.astype(np.float32), _FLOAT, "VEC4", target=None),
                "SCALE": b.add_accessor(np.repeat(inst[:, 3:4], 3, 1).astype(np.float32), _FLOAT, "VEC3",
                                        target=None)}}}
            used.add("EXT_mesh_gpu_instancing")
        gnodes.append(gnode)

    gltf: dict = {
        "asset": {"version": "2.0", "generator": str(generator)},
        "scene": 0,
        "scenes": [{"name": "scene", "nodes": list(range(len(gnodes)))}],
        "nodes": gnodes,
        "meshes": meshes,
        "materials": materials,
        "accessors": b.accessors,
        "bufferViews": b.buffer_views,
        "buffers": [{"byteLength": b.length}],
    }
    if used:
        gltf["extensionsUsed"] = sorted(used)
        if "EXT_mesh_gpu_instancing" in used:
            gltf["extensionsRequired"] = ["EXT_mesh_gpu_instancing"]
    if textures:
        gltf["samplers"] = [{"magFilter": _LINEAR, "minFilter": _LINEAR_MIPMAP_LINEAR,
                             "wrapS": _REPEAT, "wrapT": _REPEAT}]
        gltf["images"] = images
        gltf["textures"] = textures

    return _write_document(gltf, b.bytes(), path)


def _write_document(gltf: dict, bin_bytes: bytes, path) -> Path:
    """Write a glTF JSON document and its BIN chunk (a multiple of 4 bytes) as a GLB, atomically."""
    json_bytes = json.dumps(gltf, separators=(",", ":"), ensure_ascii=False).encode("utf-8")
    json_bytes += b" " * _pad4(len(json_bytes))
    total = 12 + 8 + len(json_bytes) + 8 + len(bin_bytes)
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            f.write(struct.pack("<III", _GLB_MAGIC, 2, total))
            f.write(struct.pack("<II", len(json_bytes), _CHUNK_JSON))
            f.write(json_bytes)
            f.write(struct.pack("<II", len(bin_bytes), _CHUNK_BIN))
            f.write(bin_bytes)
    return Path(path)


def write_animated_glb(source, path, rig, skins: list, *, name: str = "wind") -> Path:
    """A treeform GLB skinned to ``rig``'s joints and animated by its keyframes, looping.

    The source's one mesh node becomes a skinned mesh: each primitive gains ``JOINTS_0``
    (UNSIGNED_SHORT VEC4) and ``WEIGHTS_0`` (FLOAT VEC4, up to four joints per vertex, the
    weights normalised to sum 1);
    the joints become a node hierarchy (translations from parent pivot to pivot, rest
    rotation identity) with inverse bind matrices, and one animation ``name`` drives
    every joint's rotation (LINEAR, keyframe times from 0 to the period; the last pose
    equals the first, so a player looping the clip shows no jump).

    Parameters
    ----------
    source : str or path-like
        A GLB written by :func:`write_glb` (one node holding one mesh).
    path : str or path-like
        Output file, written atomically.
    rig : Rig
    skins : list of (ndarray, ndarray)
        For each primitive of the mesh, in order: the joints (V_p, K) int and weights
        (V_p, K) of its vertices, K <= 4.

    Raises
    ------
    InputError
        The source is not a one-mesh GLB, or ``skins`` does not match its primitives.
    """
    gltf, bin_chunk = read_glb(source)
    nodes, meshes = gltf.get("nodes", []), gltf.get("meshes", [])
    if len(nodes) != 1 or "mesh" not in nodes[0] or len(meshes) != 1:
        raise InputError(f"{source}: expected a treeform GLB with one node holding one mesh")
    if any(k in nodes[0] for k in ("matrix", "rotation", "scale", "translation")):
        raise InputError(f"{source}: the mesh node carries a transform; expected the mesh in world space")
    prims = meshes[0]["primitives"]
    if len(skins) != len(prims):
        raise InputError(f"skins: expected one (joints, weights) pair per primitive ({len(prims)}), got {len(skins)}")
    J = rig.n_joints
    if J > 65535:
        raise InputError(f"rig: at most 65535 joints, got {J}")
    b = _BinBuilder()
    b.chunks, b.length = [bin_chunk], len(bin_chunk)
    b.buffer_views, b.accessors = list(gltf.get("bufferViews", [])), list(gltf.get("accessors", []))
    if b.length % 4:
        pad = _pad4(b.length)
        b.chunks.append(b"\0" * pad)
        b.length += pad
    for prim, (jv, wv) in zip(prims, skins):
        n = gltf["accessors"][prim["attributes"]["POSITION"]]["count"]
        jv = np.asarray(jv, np.int64).reshape(n, -1) if n else np.zeros((0, 1), np.int64)
        wv = np.asarray(wv, np.float64).reshape(jv.shape) if n else np.zeros((0, 1))
        if jv.shape[1] > 4 or (n and (jv.min() < 0 or jv.max() >= J)) or np.any(wv < 0) \
                or (n and np.any(wv.sum(1) <= 0)):
            raise InputError(f"skins: a primitive of {n} vertices needs up to 4 joints in [0, {J}) with "
                             "non-negative weights per vertex")
        j4 = np.zeros((n, 4), "<u2")
        j4[:, :jv.shape[1]] = np.where(wv > 0, jv, 0)
        w4 = np.zeros((n, 4), "<f4")
        w4[:, :wv.shape[1]] = wv / wv.sum(1, keepdims=True)
        prim["attributes"]["JOINTS_0"] = b.add_accessor(j4, _UNSIGNED_SHORT, "VEC4", target=_ARRAY_BUFFER)
        prim["attributes"]["WEIGHTS_0"] = b.add_accessor(w4, _FLOAT, "VEC4", target=_ARRAY_BUFFER)
    first = len(nodes)
    children: list[list[int]] = [[] for _ in range(J)]
    for j in range(1, J):
        children[rig.parent[j]].append(first + j)
    for j in range(J):
        offset = rig.pivots[j] - (rig.pivots[rig.parent[j]] if j else 0.0)
        node = {"name": f"joint_{j}", "translation": [float(x) for x in offset]}
        if children[j]:
            node["children"] = children[j]
        nodes.append(node)
    ibm = np.tile(np.eye(4, dtype="<f4"), (J, 1, 1))
    ibm[:, 3, :3] = -rig.pivots  # column-major: the translation is the last column
    gltf["skins"] = [{"name": "branches", "joints": list(range(first, first + J)), "skeleton": first,
                      "inverseBindMatrices": b.add_accessor(ibm.reshape(J, 16), _FLOAT, "MAT4", target=None)}]
    nodes[0]["skin"] = 0
    gltf["scenes"][gltf.get("scene", 0)]["nodes"].append(first)
    times = b.add_accessor(rig.times.astype("<f4")[:, None], _FLOAT, "SCALAR", target=None, min_max=True)
    samplers, channels = [], []
    for j in range(J):
        out = b.add_accessor(rig.rotations[:, j].astype("<f4"), _FLOAT, "VEC4", target=None)
        samplers.append({"input": times, "output": out, "interpolation": "LINEAR"})
        channels.append({"sampler": j, "target": {"node": first + j, "path": "rotation"}})
    gltf["animations"] = [{"name": name, "samplers": samplers, "channels": channels}]
    gltf["accessors"], gltf["bufferViews"] = b.accessors, b.buffer_views
    gltf["buffers"] = [{"byteLength": b.length}]
    return _write_document(gltf, b.bytes(), path)


def read_glb(path) -> tuple[dict, bytes]:
    """Parse a GLB file into its JSON document and its BIN chunk.

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    gltf : dict
        The parsed JSON chunk.
    bin : bytes
        The BIN chunk (``b""`` when absent).

    Raises
    ------
    InputError
        Missing file, or not a well-formed glTF 2.0 binary.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise InputError(f"{path}: is a directory, not a GLB file") from None
    if len(data) < 20:
        raise InputError(f"{path}: not a GLB file (too short)")
    magic, version, length = struct.unpack_from("<III", data, 0)
    if magic != _GLB_MAGIC:
        raise InputError(f"{path}: not a GLB file (bad magic)")
    if version != 2:
        raise InputError(f"{path}: unsupported GLB version {version}, expected 2")
    if length > len(data):
        raise InputError(f"{path}: truncated GLB file ({len(data)} of {length} bytes)")
    offset, gltf, bin_chunk = 12, None, b""
    while offset + 8 <= length:
        clen, ctype = struct.unpack_from("<II", data, offset)
        chunk = data[offset + 8: offset + 8 + clen]
        if len(chunk) != clen:
            raise InputError(f"{path}: truncated GLB chunk")
        if ctype == _CHUNK_JSON and gltf is None:
            try:
                gltf = json.loads(chunk.decode("utf-8"))
            except (UnicodeDecodeError, json.JSONDecodeError):
                raise InputError(f"{path}: GLB JSON chunk is not valid JSON") from None
        elif ctype == _CHUNK_BIN and not bin_chunk:
            bin_chunk = chunk
        offset += 8 + clen
    if not isinstance(gltf, dict):
        raise InputError(f"{path}: GLB file has no JSON chunk")
    return gltf, bin_chunk


def read_glb_textures(path) -> dict:
    """The base-colour textures of a GLB's materials, decoded.

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    dict of str -> ndarray, shape (H, W, 4), uint8
        Material name -> its ``baseColorTexture`` as RGBA (materials without one are left out;
        embedded images only, as :func:`write_glb` writes them).

    Raises
    ------
    InputError
        Not a GLB, or a texture that is not an embedded, readable image.
    """
    from PIL import Image

    gltf, bin_chunk = read_glb(path)
    out = {}
    try:
        for i, m in enumerate(gltf.get("materials", [])):
            ref = m.get("pbrMetallicRoughness", {}).get("baseColorTexture")
            if ref is None:
                continue
            view = gltf["bufferViews"][gltf["images"][gltf["textures"][ref["index"]]["source"]]["bufferView"]]
            start = view.get("byteOffset", 0)
            with Image.open(io.BytesIO(bin_chunk[start:start + view["byteLength"]])) as im:
                out[m.get("name", f"material_{i}")] = np.asarray(im.convert("RGBA"))
    except (KeyError, IndexError, TypeError, OSError):
        raise InputError(f"{path}: malformed or non-embedded glTF texture") from None
    return out


def read_glb_counts(path) -> tuple[int, int]:
    """Total vertex and triangle counts of a GLB's meshes (each primitive counted once).

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    n_vertices : int
        Sum of the ``POSITION`` accessor counts.
    n_triangles : int
        Sum over triangle primitives of index count / 3 (vertex count / 3 when unindexed).

    Raises
    ------
    InputError
        Not a GLB file, or a primitive that is not a triangle list.
    """
    gltf, _ = read_glb(path)
    accessors = gltf.get("accessors", [])
    n_vertices = n_triangles = 0
    try:
        for mesh in gltf.get("meshes", []):
            for prim in mesh["primitives"]:
                if prim.get("mode", _TRIANGLES) != _TRIANGLES:
                    raise InputError(f"{path}: primitive mode {prim['mode']} is not a triangle list")
                nv = int(accessors[prim["attributes"]["POSITION"]]["count"])
                n_vertices += nv
                n_idx = int(accessors[prim["indices"]]["count"]) if "indices" in prim else nv
                n_triangles += n_idx // 3
    except (KeyError, IndexError, TypeError):
        raise InputError(f"{path}: malformed glTF mesh/accessor data") from None
    return n_vertices, n_triangles


def accessor_array(gltf: dict, bin_chunk: bytes, index: int) -> np.ndarray:
    """Read accessor ``index`` of a GLB (tightly packed, non-sparse) as a numpy array.

    Parameters
    ----------
    gltf : dict
    bin_chunk : bytes
    index : int

    Returns
    -------
    ndarray, shape (count,) or (count, k)
    """
    acc = gltf["accessors"][index]
    view = gltf["bufferViews"][acc["bufferView"]]
    dtype = {5120: "<i1", 5121: "<u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}[acc["componentType"]]
    k = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}[acc["type"]]
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    arr = np.frombuffer(bin_chunk, dtype=dtype, count=acc["count"] * k, offset=start)
    return arr.reshape(-1, k) if k > 1 else arr


def _node_matrix(node: dict):
    """A glTF node's local 4x4 transform (``matrix``, or translation * rotation * scale)."""
    if "matrix" in node:
        return np.array(node["matrix"], np.float64).reshape(4, 4).T  # column-major in glTF
    x, y, z, w = node.get("rotation", (0.0, 0.0, 0.0, 1.0))
    rot = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                    [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                    [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    m = np.eye(4)
    m[:3, :3] = rot * np.asarray(node.get("scale", (1.0, 1.0, 1.0)), np.float64)
    m[:3, 3] = node.get("translation", (0.0, 0.0, 0.0))
    return m


def scene_primitives(gltf: dict, path):
    """Yield ``(world_matrix (4, 4), primitive)`` for every mesh primitive of the default scene.

    Node transforms are composed from the scene's roots (every parentless node when the file
    has no scene); a hierarchy deeper than 64 (a cycle) is an InputError naming ``path``.
    Malformed node or mesh entries raise KeyError / IndexError / TypeError for the caller to
    turn into its own message.
    """
    nodes = gltf.get("nodes", [])
    scenes = gltf.get("scenes", [])
    if scenes:
        roots = list(scenes[gltf.get("scene", 0)].get("nodes", []))
    else:
        kids = {c for n in nodes for c in n.get("children", [])}
        roots = [i for i in range(len(nodes)) if i not in kids]
    stack = [(i, np.eye(4), 0) for i in roots]
    while stack:
        i, parent_m, depth = stack.pop()
        if depth > 64:
            raise InputError(f"{path}: glTF node hierarchy too deep (a cycle?)")
        node = nodes[i]
        m = parent_m @ _node_matrix(node)
        stack.extend((c, m, depth + 1) for c in node.get("children", []))
        if "mesh" in node:
            for prim in gltf["meshes"][node["mesh"]]["primitives"]:
                yield m, prim


def read_glb_geometry(path) -> tuple[np.ndarray, np.ndarray | None]:
    """All vertex positions and the leaf triangles of a GLB, in world space.

    Node transforms of the default scene are applied; leaf triangles are those of primitives
    whose material is named ``leaves`` (treeform's leaf material).

    Returns
    -------
    vertices : ndarray, shape (V, 3), float64
    leaf_triangles : ndarray, shape (T, 3, 3), float64, or None
        None when no primitive uses a ``leaves`` material.

    Raises
    ------
    InputError
        Not a GLB, a malformed scene or mesh, a node cycle, or no vertices.
    """
    gltf, bin_chunk = read_glb(path)
    mats = gltf.get("materials", [])
    verts, leaves = [], []
    try:
        for m, prim in scene_primitives(gltf, path):
            pos = accessor_array(gltf, bin_chunk, prim["attributes"]["POSITION"]).astype(np.float64)
            pos = pos @ m[:3, :3].T + m[:3, 3]
            verts.append(pos)
            mat = mats[prim["material"]].get("name", "") if "material" in prim else ""
            if mat == "leaves" and prim.get("mode", 4) == 4:
                idx = (accessor_array(gltf, bin_chunk, prim["indices"]).astype(np.int64)
                       if "indices" in prim else np.arange(len(pos)))
                leaves.append(pos[idx.reshape(-1, 3)])
    except (KeyError, IndexError, TypeError, ValueError):
        raise InputError(f"{path}: malformed glTF scene or mesh data") from None
    if not verts or not sum(len(v) for v in verts):
        raise InputError(f"{path}: the GLB holds no mesh vertices")
    return np.concatenate(verts), (np.concatenate(leaves) if leaves else None)


def read_glb_mesh(path) -> Mesh:
    """A GLB's triangles as a :class:`Mesh`: one part per primitive, in world space.

    Reads what :func:`write_glb` writes (and simple glTF binaries like it): positions,
    normals (zeros where absent), ``TEXCOORD_0``, ``COLOR_0`` (white where absent), indices,
    and per material its name, ``baseColorFactor``, embedded ``baseColorTexture``,
    ``alphaMode``, ``alphaCutoff``, ``doubleSided``, roughness, metallic and ``KHR_materials_unlit``. Node transforms
    of the default scene are applied (normals by the inverse transpose). Normal maps and
    animations are left out.

    Raises
    ------
    InputError
        Not a GLB, a malformed scene, or no triangles.
    """
    from PIL import Image

    gltf, bin_chunk = read_glb(path)
    materials: dict[int, Material] = {}

    def material(i) -> Material:
        if i is None:
            return Material()
        if i not in materials:
            m = gltf["materials"][i]
            pbr = m.get("pbrMetallicRoughness", {})
            tex = None
            ref = pbr.get("baseColorTexture")
            if ref is not None:
                view = gltf["bufferViews"][gltf["images"][gltf["textures"][ref["index"]]["source"]]["bufferView"]]
                start = view.get("byteOffset", 0)
                with Image.open(io.BytesIO(bin_chunk[start:start + view["byteLength"]])) as im:
                    tex = np.asarray(im.convert("RGBA"))
            materials[i] = Material(name=m.get("name", f"material_{i}"),
                                    base_color=tuple(pbr.get("baseColorFactor", (1.0, 1.0, 1.0, 1.0))),
                                    texture=tex, alpha_mode=m.get("alphaMode", "OPAQUE"),
                                    alpha_cutoff=float(m.get("alphaCutoff", 0.5)),
                                    double_sided=bool(m.get("doubleSided", False)),
                                    roughness=float(pbr.get("roughnessFactor", 1.0)),
                                    metallic=float(pbr.get("metallicFactor", 1.0)),
                                    unlit="KHR_materials_unlit" in m.get("extensions", {}))
        return materials[i]

    parts = []
    try:
        for m, prim in scene_primitives(gltf, path):
            if prim.get("mode", 4) != 4:
                continue
            att = prim["attributes"]
            pos = accessor_array(gltf, bin_chunk, att["POSITION"]).astype(np.float64)
            n = len(pos)
            nrm = (accessor_array(gltf, bin_chunk, att["NORMAL"]).astype(np.float64) if "NORMAL" in att
                   else np.zeros((n, 3)))
            uv = accessor_array(gltf, bin_chunk, att["TEXCOORD_0"]) if "TEXCOORD_0" in att else np.zeros((n, 2))
            col = accessor_array(gltf, bin_chunk, att["COLOR_0"]) if "COLOR_0" in att else np.ones((n, 4))
            if col.shape[1] == 3:
                col = np.column_stack([col, np.ones(n)])
            idx = (accessor_array(gltf, bin_chunk, prim["indices"]).astype(np.int64) if "indices" in prim
                   else np.arange(n)).reshape(-1, 3)
            lin = m[:3, :3]
            nrm = nrm @ np.linalg.inv(lin)  # (inverse transpose)ᵀ applied to row vectors
            nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-12)
            mat = material(prim.get("material"))
            parts.append(MeshPart((pos @ lin.T + m[:3, 3]).astype(np.float32), nrm.astype(np.float32),
                                  np.asarray(uv, np.float32), np.asarray(col, np.float32),
                                  idx.astype(np.uint32), mat, mat.name))
    except (KeyError, IndexError, TypeError, ValueError, OSError, np.linalg.LinAlgError):
        raise InputError(f"{path}: malformed glTF mesh or material") from None
    if not parts or not any(len(p.indices) for p in parts):
        raise InputError(f"{path}: no triangles in this GLB")
    return Mesh(parts)
