"""Shared fixtures for the io tests: a small tree-like mesh and skeleton."""

from __future__ import annotations

import numpy as np
import pytest

from treeform.structures.mesh import Material, Mesh, MeshPart
from treeform.structures.skeleton import TreeSkeleton


def cylinder_part(n: int = 12, rings: int = 3, radius: float = 0.1, name: str = "bark",
                  material: Material | None = None, colored: bool = True) -> MeshPart:
    """An open cylinder along +Y: (rings * n) vertices, 2 n (rings - 1) triangles."""
    ang = np.linspace(0, 2 * np.pi, n, endpoint=False)
    y = np.linspace(0, 1, rings)
    a, yy = np.meshgrid(ang, y)
    pos = np.stack([radius * np.cos(a), yy, radius * np.sin(a)], -1).reshape(-1, 3)
    nor = np.stack([np.cos(a), np.zeros_like(a), np.sin(a)], -1).reshape(-1, 3) * 3.0  # not unit on purpose
    uv = np.stack([a / (2 * np.pi), 1 - yy], -1).reshape(-1, 2)
    col = np.ones((len(pos), 4))
    if colored:
        col[:, 0] = np.linspace(0.2, 0.9, len(pos))
        col[:, 1] = 0.5
    tris = []
    for r in range(rings - 1):
        for i in range(n):
            j = (i + 1) % n
            a0, a1, b0, b1 = r * n + i, r * n + j, (r + 1) * n + i, (r + 1) * n + j
            tris += [[a0, b1, a1], [a0, b0, b1]]
    mat = material or Material("bark", (0.35, 0.25, 0.15, 1.0), roughness=0.95)
    return MeshPart(pos, nor, uv, col, tris, mat, name)


def leaf_texture(size: int = 32) -> np.ndarray:
    """(size, size, 4) uint8 RGBA: a green ellipse on transparent, with a gradient."""
    yy, xx = np.mgrid[0:size, 0:size]
    tex = np.zeros((size, size, 4), np.uint8)
    tex[..., 0] = (xx * 255 // (size - 1)).astype(np.uint8)
    tex[..., 1] = 160
    tex[..., 2] = (yy * 255 // (size - 1)).astype(np.uint8)
    inside = ((xx - size / 2 + 0.5) / (size * 0.3)) ** 2 + ((yy - size / 2 + 0.5) / (size * 0.45)) ** 2 <= 1
    tex[..., 3] = np.where(inside, 255, 0)
    return tex


def leaf_part(n_leaves: int = 5, material: Material | None = None, name: str = "leaves") -> MeshPart:
    """``n_leaves`` quads (4 vertices, 2 triangles each) with white (all-1) colours."""
    rng = np.random.default_rng(0)
    pos, uv, tris = [], [], []
    for k in range(n_leaves):
        c = rng.uniform(-0.5, 0.5, 3) + (0, 1.5, 0)
        pos += [c + d for d in ([0, 0, 0], [0.1, 0, 0], [0.1, 0.15, 0], [0, 0.15, 0])]
        uv += [[0, 1], [1, 1], [1, 0], [0, 0]]
        tris += [[4 * k, 4 * k + 1, 4 * k + 2], [4 * k, 4 * k + 2, 4 * k + 3]]
    mat = material or Material("leaf", (0.9, 1.0, 0.9, 1.0), leaf_texture(), "MASK", 0.4, True, 0.7, 0.0)
    nor = np.tile([0.0, 0.0, 1.0], (len(pos), 1))
    return MeshPart(np.array(pos), nor, np.array(uv), None, tris, mat, name)


def empty_part() -> MeshPart:
    return MeshPart(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros((0, 2)), np.zeros((0, 4)), np.zeros((0, 3)),
                    name="empty")


@pytest.fixture
def tree_mesh() -> Mesh:
    """Bark (vertex colours, opaque), leaves (RGBA texture, MASK, double-sided), a BLEND
    part with an opaque texture, and an empty part (skipped by the writers)."""
    glass = np.zeros((8, 8, 4), np.uint8)
    glass[..., :3] = 90
    glass[..., 3] = 255
    blend = Material("veil", (0.5, 0.6, 0.7, 0.5), glass, "BLEND", 0.5, False, 0.5, 0.2)
    return Mesh([
        cylinder_part(),
        leaf_part(),
        empty_part(),
        cylinder_part(n=6, rings=2, radius=0.3, name="veil", material=blend, colored=False),
    ])


@pytest.fixture
def skeleton() -> TreeSkeleton:
    pos = np.array([[0, 0, 0], [0, 1, 0], [0, 2, 0], [0.5, 1.5, 0], [-0.4, 2.5, 0.1]], float)
    parent = np.array([-1, 0, 1, 1, 2])
    radius = np.array([0.1, 0.08, 0.05, 0.03, 0.02])
    order = np.array([0, 0, 0, 1, 0])
    return TreeSkeleton(pos, parent, radius, order)


@pytest.fixture
def make_cylinder():
    """The :func:`cylinder_part` factory."""
    return cylinder_part


@pytest.fixture
def make_leaves():
    """The :func:`leaf_part` factory."""
    return leaf_part
