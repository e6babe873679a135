"""Mesh: triangle mesh parts, each with one PBR material (what exporters and the renderer read)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from treeform._shared.errors import InputError
from treeform.structures._npz import load_npz, save_npz


@dataclass
class Material:
    """A glTF-style metallic-roughness material.

    Parameters
    ----------
    name : str
    base_color : tuple of 4 floats
        Linear RGBA factor multiplied with the texture and vertex colours.
    texture : ndarray, shape (H, W, 4), uint8, optional
        sRGB RGBA base-colour texture.
    alpha_mode : {"OPAQUE", "MASK", "BLEND"}
    alpha_cutoff : float
    double_sided : bool
    roughness, metallic : float
    normal_texture : ndarray, shape (H, W, 4), uint8, optional
        Tangent-space normal map (glTF ``normalTexture``: RGB = (n + 1) / 2, +X right, +Y up
        in the texture, +Z out of the surface), sampled with the same UVs as ``texture``.
    normal_scale : float
        Scales the normal map's X and Y (glTF ``normalTexture.scale``).
    unlit : bool
        Shown as its colour alone, with no lighting (glTF ``KHR_materials_unlit``: billboards and
        impostor cards whose light is baked into the texture).
    """

    name: str = "material"
    base_color: tuple = (1.0, 1.0, 1.0, 1.0)
    texture: np.ndarray | None = None
    alpha_mode: str = "OPAQUE"
    alpha_cutoff: float = 0.5
    double_sided: bool = False
    roughness: float = 0.9
    metallic: float = 0.0
    normal_texture: np.ndarray | None = None
    normal_scale: float = 1.0
    unlit: bool = False

    def validate(self) -> None:
        if self.alpha_mode not in ("OPAQUE", "MASK", "BLEND"):
            raise InputError(f"Material.alpha_mode: expected OPAQUE, MASK or BLEND, got {self.alpha_mode!r}")
        if self.texture is not None:
            t = self.texture
            if t.ndim != 3 or t.shape[2] != 4 or t.dtype != np.uint8:
                raise InputError(f"Material.texture: expected (H, W, 4) uint8, got {t.shape} {t.dtype}")
        if self.normal_texture is not None:
            t = self.normal_texture
            if t.ndim != 3 or t.shape[2] != 4 or t.dtype != np.uint8:
                raise InputError(f"Material.normal_texture: expected (H, W, 4) uint8, got {t.shape} {t.dtype}")
        if not np.isfinite(self.normal_scale):
            raise InputError(f"Material.normal_scale: expected a finite number, got {self.normal_scale!r}")
        if not 0.0 <= self.roughness <= 1.0:
            raise InputError(f"Material.roughness: expected a number in [0, 1], got {self.roughness!r}")


@dataclass
class MeshPart:
    """One primitive: vertices with normals, UVs and colours, triangles, and a material.

    Parameters
    ----------
    positions : ndarray, shape (V, 3), float32
    normals : ndarray, shape (V, 3), float32
    uvs : ndarray, shape (V, 2), float32
    colors : ndarray, shape (V, 4), float32 in [0, 1]
    indices : ndarray, shape (F, 3), uint32
    material : Material
    """

    positions: np.ndarray
    normals: np.ndarray
    uvs: np.ndarray
    colors: np.ndarray
    indices: np.ndarray
    material: Material = field(default_factory=Material)
    name: str = "part"

    def __post_init__(self):
        self.positions = np.ascontiguousarray(self.positions, np.float32).reshape(-1, 3)
        v = len(self.positions)
        self.normals = np.ascontiguousarray(self.normals, np.float32).reshape(-1, 3)
        self.uvs = np.ascontiguousarray(self.uvs, np.float32).reshape(-1, 2)
        if self.colors is None:
            self.colors = np.ones((v, 4), np.float32)
        self.colors = np.ascontiguousarray(self.colors, np.float32).reshape(-1, 4)
        self.indices = np.ascontiguousarray(self.indices, np.uint32).reshape(-1, 3)
        self.validate()

    @property
    def n_vertices(self) -> int:
        return len(self.positions)

    @property
    def n_triangles(self) -> int:
        return len(self.indices)

    def validate(self) -> None:
        v = len(self.positions)
        for name in ("normals", "uvs", "colors"):
            if len(getattr(self, name)) != v:
                raise InputError(f"MeshPart.{name}: length {len(getattr(self, name))} != {v} vertices")
        if len(self.indices) and int(self.indices.max()) >= v:
            raise InputError("MeshPart.indices: index out of range")
        if v and not np.all(np.isfinite(self.positions)):
            raise InputError("MeshPart.positions: must be finite")
        self.material.validate()


@dataclass
class Mesh:
    """A list of :class:`MeshPart` (e.g. ``bark`` and ``leaves``)."""

    parts: list = field(default_factory=list)

    @property
    def n_vertices(self) -> int:
        return sum(p.n_vertices for p in self.parts)

    @property
    def n_triangles(self) -> int:
        return sum(p.n_triangles for p in self.parts)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        pts = np.concatenate([p.positions for p in self.parts if p.n_vertices]) if self.parts else np.zeros((1, 3))
        return pts.min(axis=0), pts.max(axis=0)

    def validate(self) -> None:
        for p in self.parts:
            p.validate()

    def triangles(self, material: str) -> np.ndarray | None:
        """Corner positions of the triangles of every part drawn with the material ``material``.

        The same selection as the GLB reader's (:func:`treeform.io.gltf.read_glb_geometry`
        takes the triangles of the ``leaves`` material for the leaf area index).

        Returns
        -------
        ndarray, shape (T, 3, 3), float64, or None
            None when no part uses that material or those parts hold no triangle.

        Examples
        --------
        >>> import numpy as np
        >>> corners = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
        >>> quad = MeshPart(corners, np.zeros((4, 3)), np.zeros((4, 2)), None, np.array([0, 1, 2, 0, 2, 3]),
        ...                 Material("leaves"))
        >>> Mesh([quad]).triangles("leaves").shape
        (2, 3, 3)
        >>> Mesh([quad]).triangles("bark") is None
        True
        """
        tris = [np.asarray(p.positions, np.float64)[np.asarray(p.indices, np.int64).reshape(-1, 3)]
                for p in self.parts if p.material.name == material and p.n_triangles]
        return np.concatenate(tris) if tris else None

    def save(self, path):
        arrays = {}
        for i, p in enumerate(self.parts):
            for k in ("positions", "normals", "uvs", "colors", "indices"):
                arrays[f"{i}_{k}"] = getattr(p, k)
            m = p.material
            arrays[f"{i}_material"] = np.array(repr((p.name, m.name, tuple(m.base_color), m.alpha_mode,
                                                      m.alpha_cutoff, m.double_sided, m.roughness, m.metallic,
                                                      m.normal_scale)))
            if m.texture is not None:
                arrays[f"{i}_texture"] = m.texture
            if m.normal_texture is not None:
                arrays[f"{i}_normal_texture"] = m.normal_texture
        return save_npz(path, "Mesh", n_parts=np.array(len(self.parts)), **arrays)

    @classmethod
    def load(cls, path) -> "Mesh":
        import ast

        d = load_npz(path, "Mesh")
        parts = []
        for i in range(int(d["n_parts"])):
            pname, mname, bc, am, ac, ds, ro, me, *rest = ast.literal_eval(str(d[f"{i}_material"]))
            mat = Material(mname, bc, d.get(f"{i}_texture"), am, ac, ds, ro, me, d.get(f"{i}_normal_texture"),
                           *rest)
            parts.append(MeshPart(*(d[f"{i}_{k}"] for k in ("positions", "normals", "uvs", "colors", "indices")), mat, pname))
        return cls(parts)
