"""Meshes built programmatically for the render tests, and the skip when no OpenGL exists."""

from __future__ import annotations

import numpy as np
import pytest

from treeform.structures import Material, MeshPart


def cube_part(center=(0.0, 0.0, 0.0), half=(0.5, 0.5, 0.5), material=None) -> MeshPart:
    """Axis-aligned box: 24 vertices with face normals, counter-clockwise seen from outside."""
    pos, nrm, idx = [], [], []
    half = np.asarray(half, float)
    for ax in range(3):
        for sg in (-1.0, 1.0):
            n = np.zeros(3)
            n[ax] = sg
            u = np.zeros(3)
            u[(ax + 1) % 3] = 1.0
            v = np.cross(n, u)  # u x v = n  ->  (u, v) order is counter-clockwise seen from n
            base = len(pos)
            for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                pos.append(np.asarray(center) + (n + a * u + b * v) * half)
                nrm.append(n)
            idx += [(base, base + 1, base + 2), (base, base + 2, base + 3)]
    pos = np.array(pos)
    return MeshPart(pos, np.array(nrm), np.zeros((len(pos), 2)), None, np.array(idx), material or Material())


def quad_part(*, z=0.0, half=1.0, facing=+1, material=None, colors=None) -> MeshPart:
    """Square in the plane z, facing +Z (``facing=+1``, CCW seen from +Z) or -Z.

    UVs follow glTF: u grows with +X, v = 0 at the top (+Y) edge.
    """
    p = np.array([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], float) * half + [0, 0, z]
    uv = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], float)
    idx = np.array([[0, 1, 2], [0, 2, 3]]) if facing > 0 else np.array([[0, 2, 1], [0, 3, 2]])
    n = np.tile([0.0, 0.0, float(np.sign(facing))], (4, 1))
    return MeshPart(p, n, uv, colors, idx, material or Material())


def uv_sphere(center=(0.0, 0.0, 0.0), radius=1.0, n_lon=64, n_lat=32):
    """Closed UV sphere: positions (V, 3), outward normals (V, 3), faces (F, 3) CCW from outside."""
    th = np.linspace(0, np.pi, n_lat + 1)
    ph = np.linspace(0, 2 * np.pi, n_lon + 1)[:-1]
    t, p = np.meshgrid(th, ph, indexing="ij")
    d = np.stack([np.sin(t) * np.cos(p), np.cos(t), np.sin(t) * np.sin(p)], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(n_lat), np.arange(n_lon), indexing="ij")
    a = i * n_lon + j
    b = i * n_lon + (j + 1) % n_lon
    c = a + n_lon
    e = b + n_lon
    faces = np.concatenate([np.stack([a, c, b], -1).reshape(-1, 3), np.stack([b, c, e], -1).reshape(-1, 3)])
    return d * radius + np.asarray(center, float), d, faces


def box_mesh(center=(0.0, 0.0, 0.0), lo=(-0.5, -0.5, -0.5), hi=(0.5, 0.5, 0.5), subdiv=8):
    """Closed box [lo, hi] + center, each face split into subdiv x subdiv quads: (positions, faces)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    pos, faces = [], []
    g = np.linspace(0, 1, subdiv + 1)
    for ax in range(3):
        for side in (0, 1):
            u_ax, v_ax = (ax + 1) % 3, (ax + 2) % 3
            uu, vv = np.meshgrid(g, g, indexing="ij")
            p = np.zeros((subdiv + 1, subdiv + 1, 3))
            p[..., ax] = hi[ax] if side else lo[ax]
            p[..., u_ax] = lo[u_ax] + uu * (hi[u_ax] - lo[u_ax])
            p[..., v_ax] = lo[v_ax] + vv * (hi[v_ax] - lo[v_ax])
            base = sum(len(x) for x in pos)
            pos.append(p.reshape(-1, 3))
            k = np.arange(subdiv)
            i, j = np.meshgrid(k, k, indexing="ij")
            q = base + i * (subdiv + 1) + j
            faces.append(np.stack([q, q + subdiv + 1, q + subdiv + 2], -1).reshape(-1, 3))
            faces.append(np.stack([q, q + subdiv + 2, q + 1], -1).reshape(-1, 3))
    return np.concatenate(pos) + np.asarray(center, float), np.concatenate(faces)


def leaf_cloud(n=2000, seed=0, material=None) -> MeshPart:
    """Random square leaf cards around (0, 3, 0), double-sided alpha-tested by default."""
    rng = np.random.default_rng(seed)
    c = rng.normal(size=(n, 3)) * [1.5, 1.2, 1.5] + [0, 3, 0]
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    v = np.cross(u, rng.normal(size=(n, 3)))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    s = 0.08
    p = np.stack([c - s * u - s * v, c + s * u - s * v, c + s * u + s * v, c - s * u + s * v], 1).reshape(-1, 3)
    nrm = np.repeat(np.cross(u, v), 4, axis=0)
    uv = np.tile([[0, 1], [1, 1], [1, 0], [0, 0]], (n, 1))
    b = np.arange(n) * 4
    idx = np.stack([np.stack([b, b + 1, b + 2], 1), np.stack([b, b + 2, b + 3], 1)], 1).reshape(-1, 3)
    if material is None:
        tex = np.zeros((32, 32, 4), np.uint8)
        yy, xx = np.mgrid[:32, :32]
        tex[..., 1] = 150
        tex[..., 3] = np.where((xx - 15.5) ** 2 + (yy - 15.5) ** 2 < 15**2, 255, 0)
        material = Material("leaf", (1, 1, 1, 1), tex, "MASK", 0.5, True)
    colors = np.concatenate([rng.uniform(0.6, 1, (4 * n, 3)), np.ones((4 * n, 1))], axis=1)
    return MeshPart(p, nrm, uv, colors, idx, material)


@pytest.fixture(scope="session")
def meshes():
    """The builders above, as a namespace (test files need no import from conftest)."""

    class _M:
        cube = staticmethod(cube_part)
        quad = staticmethod(quad_part)
        sphere = staticmethod(uv_sphere)
        box = staticmethod(box_mesh)
        leaves = staticmethod(leaf_cloud)

    return _M
