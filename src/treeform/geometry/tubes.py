"""Branch geometry: a skeleton as generalized cylinders (one smooth tube per branch chain).

Every chain of :meth:`TreeSkeleton.chains` becomes one tube with a ring of vertices at each
node. Rings are oriented by the average tangent of the two adjacent segments (a mitre, so
consecutive segments join without cracks) and framed by discrete parallel transport
(rotation-minimizing frames, Bishop 1975 / Wang et al. 2008), so tubes do not twist. A side
chain begins at its parent node, i.e. inside the parent tube, so branch joins are closed.
Tips end in a short cone, the root in a flat fan.

Everything is vectorized over all rings of all chains at once; the only sequential step, the
accumulation of frame rotations along a chain, is a segmented parallel prefix scan over
quaternions (``log2(longest chain)`` passes, compiled with numba). The chains themselves come
from a compiled walk (:func:`_chain_arrays`, the same as :meth:`TreeSkeleton.chains`).
"""

from __future__ import annotations

import functools

import numpy as np

from treeform._shared.checks import check_positive
from treeform._shared.errors import InputError
from treeform._shared.noise import periodic_noise
from treeform._shared.rng import as_rng
from treeform.geometry.textures import BARK_TEXTURE_SIZE
from treeform.structures.mesh import Material, MeshPart
from treeform.structures.skeleton import TreeSkeleton

__all__ = ["MIN_RING_RADIUS", "bark_material", "bark_texture", "branch_mesh", "tube_triangle_count"]

MIN_RING_RADIUS = 1e-4
"""Rings thinner than this (metres) are widened to it, so no ring collapses to a point."""

_EPS = 1e-12


# --------------------------------------------------------------------------- texture
def bark_texture(size: int = BARK_TEXTURE_SIZE, *, seed=0) -> np.ndarray:
    """A procedural, tileable bark texture: brown-grey plates split by vertical fissures.

    The texture's vertical axis (rows) runs along the branch (UV ``v``), so the fissures
    follow the grain. It tiles in both directions (built from periodic FFT noise).

    Parameters
    ----------
    size : int
        Edge length in texels (>= 8); default 512
        (:data:`~treeform.geometry.textures.BARK_TEXTURE_SIZE`).
    seed : int or numpy.random.Generator
        Randomness; same seed -> identical texture.

    Returns
    -------
    ndarray, shape (size, size, 4), uint8
        sRGB colour with alpha 255.

    Examples
    --------
    >>> t = bark_texture(32)
    >>> t.shape, t.dtype, int(t[..., 3].min())
    ((32, 32, 4), dtype('uint8'), 255)
    """
    if isinstance(size, bool) or not isinstance(size, (int, np.integer)) or size < 8:
        raise InputError(f"size: expected an integer >= 8, got {size!r}")
    size = int(size)
    rng = as_rng(seed)
    h = w = size
    # Fissures: the zero set of strongly anisotropic noise (long along the grain, short
    # across it) forms a network of cracks that run along the branch, split and rejoin.
    n = periodic_noise(rng, h, w, sigma_y=1.0, sigma_x=9.0)
    n = n + 0.3 * periodic_noise(rng, h, w, sigma_y=2.0, sigma_x=18.0)
    width = np.clip(0.3 * (1.0 + 0.35 * periodic_noise(rng, h, w, sigma_y=4.0, sigma_x=4.0)), 0.03, None)
    a = np.abs(n)
    fissure = 1.0 / (1.0 + np.exp((a - width) / 0.04))  # 1 in a crack, 0 on the plates
    relief = np.tanh(a / 0.6)  # plates bulge between the cracks
    plates = periodic_noise(rng, h, w, sigma_y=5.0, sigma_x=8.0)
    grain = periodic_noise(rng, h, w, sigma_y=25.0, sigma_x=110.0)
    light = np.clip(0.3 + 0.2 * np.tanh(0.8 * plates) + 0.45 * relief, 0.0, 1.0)
    plate_dark = np.array([0.33, 0.28, 0.24])
    plate_light = np.array([0.60, 0.56, 0.51])  # greyer highlights
    fissure_col = np.array([0.13, 0.10, 0.08])
    col = plate_dark + (plate_light - plate_dark) * light[..., None]
    col *= (1.0 + 0.07 * grain)[..., None]
    col = col * (1.0 - fissure[..., None]) + fissure_col * fissure[..., None]
    out = np.empty((size, size, 4), np.uint8)
    out[..., :3] = np.clip(np.rint(col * 255.0), 0, 255).astype(np.uint8)
    out[..., 3] = 255
    return out


@functools.lru_cache(maxsize=4)
def _default_bark(size: int, seed: int) -> np.ndarray:
    t = bark_texture(size, seed=seed)
    t.flags.writeable = False
    return t


@functools.lru_cache(maxsize=4)
def _default_bark_normal(size: int, seed: int) -> np.ndarray:
    t = bark_normal_map(_default_bark(size, seed))
    t.flags.writeable = False
    return t


def bark_normal_map(bark: np.ndarray) -> np.ndarray:
    """The tangent-space normal map of a bark texture: its dark fissures sink, its plates stand out.

    :func:`~treeform.geometry.normal_map_from_height` of the texture's luminance, tiling as the
    texture does, with the relief of the synthetic dataset's bark (strength 6 at 256²) at any size.

    Examples
    --------
    >>> n = bark_normal_map(bark_texture(32))
    >>> n.shape, bool(n[..., 2].min() > 128)  # every normal leaves the surface
    ((32, 32, 4), True)
    """
    from treeform.geometry.normal_maps import normal_map_from_height, texture_height

    bark = np.asarray(bark)
    return normal_map_from_height(texture_height(bark), strength=6.0 * bark.shape[1] / 256, wrap=True)


def bark_material(texture=None, normal_texture=None) -> Material:
    """The ``"bark"`` material: opaque, the procedural bark texture (512², seed 0) unless one is given.

    ``normal_texture``: a tangent-space normal map for the texture (the default texture
    comes with its own, :func:`bark_normal_map`).
    """
    if texture is None:
        texture = _default_bark(BARK_TEXTURE_SIZE, 0).copy()
        if normal_texture is None:
            normal_texture = _default_bark_normal(BARK_TEXTURE_SIZE, 0).copy()
    else:
        texture = np.asarray(texture)
        if texture.ndim != 3 or texture.shape[2] != 4 or texture.dtype != np.uint8:
            raise InputError(f"bark_texture: expected an (H, W, 4) uint8 array, got {texture.shape} {texture.dtype}")
    return Material(name="bark", base_color=(1.0, 1.0, 1.0, 1.0), texture=texture, alpha_mode="OPAQUE",
                    alpha_cutoff=0.5, double_sided=False, roughness=0.95, metallic=0.0,
                    normal_texture=None if normal_texture is None else np.asarray(normal_texture))


# --------------------------------------------------------------------------- quaternions
def _qrotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate (..., 3) vectors ``v`` by unit quaternions ``q`` (..., 4)."""
    w = q[..., :1]
    u = q[..., 1:]
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def _any_perpendicular(t: np.ndarray) -> np.ndarray:
    """(K, 3) unit vectors perpendicular to the unit vectors ``t`` (K, 3)."""
    ref = np.zeros_like(t)
    use_x = np.abs(t[:, 0]) < 0.9
    ref[use_x, 0] = 1.0
    ref[~use_x, 2] = 1.0
    p = ref - np.sum(ref * t, axis=1, keepdims=True) * t
    return p / np.linalg.norm(p, axis=1, keepdims=True)


def _min_rotation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(K, 4) shortest-arc unit quaternions taking unit vectors ``a`` onto ``b``."""
    d = np.sum(a * b, axis=1)
    q = np.empty((len(a), 4))
    q[:, 0] = 1.0 + d
    q[:, 1:] = np.cross(a, b)
    flip = q[:, 0] < 1e-9  # (anti)parallel reversal: 180 degrees about any perpendicular axis
    if np.any(flip):
        q[flip, 0] = 0.0
        q[flip, 1:] = _any_perpendicular(a[flip])
    return q / np.linalg.norm(q, axis=1, keepdims=True)


# --------------------------------------------------------------------------- chains
def _chain_arrays(skeleton: TreeSkeleton) -> tuple[np.ndarray, np.ndarray]:
    """``skeleton.chains()`` as two flat arrays, ``(nodes, lengths)``: the same chains in the same order.

    A compiled walk (:func:`treeform.geometry._kernels.chain_layout`), so a large tree's chains
    take well under a millisecond instead of the tens of the Python loop.
    """
    from treeform.geometry._kernels import chain_layout

    return chain_layout(skeleton.parent, skeleton.order, skeleton.radius)


def _chain_measure(skeleton: TreeSkeleton, chains: list) -> np.ndarray:
    """(C,) thickness of each chain: the largest radius of its own nodes (not the parent node)."""
    if not len(chains):
        return np.zeros(0)
    lens = np.fromiter((len(c) for c in chains), np.int64, len(chains))
    return _chain_measure_flat(skeleton, np.concatenate(chains), lens)


def _chain_measure_flat(skeleton: TreeSkeleton, flat: np.ndarray, lens: np.ndarray) -> np.ndarray:
    """:func:`_chain_measure` of chains given as :func:`_chain_arrays` (``flat`` nodes, ``lens`` per chain)."""
    from treeform.geometry._kernels import chain_max_radius

    if not len(lens):
        return np.zeros(0)
    # a side chain's first node belongs to its parent (compiled: a pine has thousands of chains)
    return chain_max_radius(np.asarray(flat, np.int64), np.asarray(lens, np.int64),
                            np.asarray(skeleton.radius, np.float64))


def tube_triangle_count(chain_lengths, radial_segments: int, *, root_flags=None, cap_starts: bool = False) -> int:
    """Triangles :func:`branch_mesh` emits for chains of the given node counts.

    Per chain of ``R >= 2`` rings: ``2·S·(R-1)`` side triangles, ``S`` for the tip cone and
    ``S`` for a start fan (the root chain, or every chain with ``cap_starts``); 0 if ``R < 2``.

    Parameters
    ----------
    chain_lengths : array_like of int, shape (C,)
    radial_segments : int
        ``S``.
    root_flags : array_like of bool, shape (C,), optional
        Which chains start at the root (default: only the first).
    cap_starts : bool
    """
    lens = np.asarray(chain_lengths, np.int64).reshape(-1)
    if root_flags is None:
        root_flags = np.arange(len(lens)) == 0
    capped = np.ones(len(lens), bool) if cap_starts else np.asarray(root_flags, bool)
    units = np.where(lens >= 2, 2 * (lens - 1) + 1 + capped, 0)
    return int(radial_segments) * int(units.sum())


def _check_segments(radial_segments) -> int:
    if isinstance(radial_segments, bool) or not isinstance(radial_segments, (int, np.integer)) or radial_segments < 3:
        raise InputError(f"radial_segments: expected an integer >= 3, got {radial_segments!r}")
    return int(radial_segments)


# --------------------------------------------------------------------------- mesh
def branch_mesh(skeleton: TreeSkeleton, *, radial_segments: int = 8, min_radius: float = 0.0,
                bark_texture=None, cap_starts: bool = False) -> MeshPart:
    """Mesh the branches of a skeleton as smoothly joined generalized cylinders.

    One tube per chain of ``skeleton.chains()`` with a ring of ``radial_segments + 1``
    vertices at every node (the seam vertex is duplicated so ``u`` runs 0..1). The ring
    plane is perpendicular to the average tangent of the adjacent segments; ring frames are
    parallel-transported along the chain (rotation-minimizing, no twist). A side chain starts
    at its parent node with radius ``min(r_parent, r_child)``, inside the parent tube, so joins
    are closed. The tip of each chain gets a short cone (apex ``r/2`` beyond the tip), the
    root a flat fan. Ring radius is ``max(skeleton.radius, MIN_RING_RADIUS)``.

    UVs: ``u`` around the ring in [0, 1]; ``v`` along the chain, the integral of
    ``ds / (2π·r)`` (arc length in metres over the circumference), so a square texture tile
    is not stretched. Vertex normals are radial, tilted by the taper ``dr/ds``.

    Faces are grouped by chain in chain order (chains with < 2 nodes emit nothing); the
    triangle count is :func:`tube_triangle_count`. A single-node skeleton gives an empty part.

    Parameters
    ----------
    skeleton : TreeSkeleton
        N nodes.
    radial_segments : int
        Sides per ring ``S`` (>= 3).
    min_radius : float
        Chains whose own nodes are all thinner than this (metres) are skipped.
    bark_texture : ndarray, shape (H, W, 4), uint8, optional
        Base-colour texture; default the procedural :func:`bark_texture` (512², seed 0).
    cap_starts : bool
        Also close the start of side chains with a fan (hidden inside the parent; makes every
        tube watertight on its own at the cost of ``S`` triangles per chain).

    Returns
    -------
    MeshPart
        Named ``"bark"``: positions/normals (V, 3), uvs (V, 2), white colours (V, 4),
        indices (F, 3), material ``"bark"`` (OPAQUE, textured).

    Examples
    --------
    >>> s = TreeSkeleton(np.array([[0, 0, 0], [0, 1, 0.]]), np.array([-1, 0]), np.array([0.1, 0.05]))
    >>> branch_mesh(s, radial_segments=6).n_triangles  # 2·6 sides + 6 cone + 6 root fan
    24
    """
    if not isinstance(skeleton, TreeSkeleton):
        raise InputError(f"skeleton: expected a TreeSkeleton, got {type(skeleton).__name__}")
    segs = _check_segments(radial_segments)
    min_radius = check_positive(min_radius, "min_radius", allow_zero=True)
    nodes, lens = _chain_arrays(skeleton)
    root_flags = np.arange(len(lens)) == 0
    if min_radius > 0:
        keep = _chain_measure_flat(skeleton, nodes, lens) >= min_radius
        nodes, lens, root_flags = nodes[np.repeat(keep, lens)], lens[keep], root_flags[keep]
    return _tubes(skeleton, nodes, lens, root_flags, segs, cap_starts=cap_starts,
                  material=bark_material(bark_texture))


def _empty_part(material: Material, name: str) -> MeshPart:
    z3 = np.zeros((0, 3), np.float32)
    return MeshPart(z3, z3, np.zeros((0, 2), np.float32), np.zeros((0, 4), np.float32),
                    np.zeros((0, 3), np.uint32), material, name)


def _tubes(skeleton: TreeSkeleton, nodes: np.ndarray, lens: np.ndarray, root_flags: np.ndarray, segs: int, *,
           cap_starts: bool, material: Material) -> MeshPart:
    """Mesh the given chains, as :func:`_chain_arrays` gives them (``nodes`` concatenated, ``lens`` per chain);
    ``root_flags`` marks root chains."""
    lens = np.asarray(lens, np.int64)
    root_flags = np.asarray(root_flags, bool)
    use = lens >= 2
    if not np.all(use):
        nodes, lens, root_flags = nodes[np.repeat(use, lens)], lens[use], root_flags[use]
    if not len(lens):
        return _empty_part(material, "bark")

    from treeform.geometry._kernels import tube_frames, tube_geometry

    n_rings = len(nodes)
    start = np.cumsum(lens) - lens
    pos_in = np.arange(n_rings) - np.repeat(start, lens)
    P = np.ascontiguousarray(skeleton.positions[nodes], np.float64)
    # ---- ring radii: side chains start (at the parent node) with the child's radius
    r = np.maximum(skeleton.radius[nodes], MIN_RING_RADIUS).astype(np.float64)
    side_first = start[~root_flags]
    r[side_first] = np.minimum(r[side_first], r[side_first + 1])
    # ---- ring frames (compiled): tangents from the adjacent segments (zero-length ones take the
    # chain's nearest valid direction), frames parallel-transported along each chain (shortest-arc
    # rotations, prefix-multiplied), taper slope dr/ds for the normals, v = ∫ ds / (2π r)
    T, U, V, slope, vcoord = tube_frames(P, r, start, lens, pos_in, MIN_RING_RADIUS)
    # ---- ring vertices (S + 1 a ring, the seam repeated exactly), a cone apex per chain, a fan
    # per capped chain (root chains, or all with cap_starts); faces ring by ring, grouped by chain
    theta = 2.0 * np.pi * np.arange(segs + 1) / segs
    cs, sn = np.cos(theta), np.sin(theta)
    cs[-1], sn[-1] = cs[0], sn[0]
    capped = np.ones(len(lens), bool) if cap_starts else root_flags.copy()
    positions, normals, uvs, faces = tube_geometry(P, r, T, U, V, slope, vcoord, cs, sn, start, lens, capped)

    colors = np.ones((len(positions), 4), np.float32)
    return MeshPart(positions, normals, uvs, colors, faces, material, "bark")
