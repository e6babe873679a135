"""branch_mesh: counts, geometry of the rings, frames, caps, UVs, the bark texture."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import grown_tree, random_parent_tree, y_tree

from treeform._shared.errors import InputError
from treeform.geometry import MIN_RING_RADIUS, bark_texture, branch_mesh, tube_triangle_count
from treeform.structures import TreeSkeleton

trimesh = pytest.importorskip("trimesh")


def two_node() -> TreeSkeleton:
    return TreeSkeleton(np.array([[0, 0, 0], [0.1, 1, 0.]]), np.array([-1, 0]), np.array([0.1, 0.05]))


def one_node() -> TreeSkeleton:
    return TreeSkeleton(np.zeros((1, 3)), np.array([-1]), np.array([0.1]))


SKELETONS = {"y": y_tree, "random": random_parent_tree, "two": two_node, "grown": lambda: grown_tree(400)}


def chain_layout(s: TreeSkeleton):
    """Ring nodes in mesh order, per-chain lengths, and the expected ring radius."""
    chains = s.chains()
    lens = np.array([len(c) for c in chains])
    nodes = np.concatenate(chains)
    start = np.cumsum(lens) - lens
    r = np.maximum(s.radius[nodes], MIN_RING_RADIUS)
    side = start[1:]
    r[side] = np.minimum(r[side], r[side + 1])
    return chains, lens, nodes, start, r


def merged(positions, faces):
    u, inv = np.unique(positions, axis=0, return_inverse=True)
    return trimesh.Trimesh(u, inv.reshape(-1)[faces], process=False)


@pytest.mark.parametrize("name", list(SKELETONS))
@pytest.mark.parametrize("segs", [3, 5, 8])
def test_triangle_count_formula(name, segs):
    s = SKELETONS[name]()
    lens = np.array([len(c) for c in s.chains()])
    m = branch_mesh(s, radial_segments=segs)
    # per chain: 2·S·(R-1) sides + S cone; + S for the root fan
    assert m.n_triangles == segs * (int(np.sum(2 * (lens - 1) + 1)) + 1)
    assert m.n_triangles == tube_triangle_count(lens, segs)
    assert m.n_vertices == lens.sum() * (segs + 1) + len(lens) + (segs + 2)
    mc = branch_mesh(s, radial_segments=segs, cap_starts=True)
    assert mc.n_triangles == m.n_triangles + segs * (len(lens) - 1)


def test_y_tree_counts_by_hand():
    m = branch_mesh(y_tree(), radial_segments=6)
    # chains [0,1,2] and [1,3]: (2·6·2 + 6 + 6) + (2·6·1 + 6)
    assert m.n_triangles == 36 + 18
    assert m.material.name == "bark" and m.material.alpha_mode == "OPAQUE"
    assert m.material.texture.shape[2] == 4 and m.material.texture.dtype == np.uint8


def test_single_node_gives_empty_part():
    m = branch_mesh(one_node())
    assert m.n_vertices == 0 and m.n_triangles == 0
    m.validate()


@pytest.mark.parametrize("name", list(SKELETONS))
def test_finite_unit_normals(name):
    m = branch_mesh(SKELETONS[name]())
    for a in (m.positions, m.normals, m.uvs, m.colors):
        assert np.all(np.isfinite(a))
    assert np.allclose(np.linalg.norm(m.normals, axis=1), 1.0, atol=1e-5)
    assert m.uvs[:, 0].min() >= 0 and m.uvs[:, 0].max() <= 1
    assert m.indices.max() < m.n_vertices


@pytest.mark.parametrize("name", ["y", "random", "two", "grown"])
def test_ring_vertices_at_radius_and_mitred(name):
    s = SKELETONS[name]()
    segs = 7
    chains, lens, nodes, start, r = chain_layout(s)
    m = branch_mesh(s, radial_segments=segs)
    ring = m.positions[: len(nodes) * (segs + 1)].reshape(len(nodes), segs + 1, 3).astype(np.float64)
    off = ring - s.positions[nodes][:, None, :]
    dist = np.linalg.norm(off, axis=2)
    assert np.allclose(dist, r[:, None], rtol=1e-4, atol=2e-6)
    # seam vertex duplicates the first one (u = 0 and u = 1)
    assert np.array_equal(ring[:, 0], ring[:, -1])
    # interior rings lie in the plane normal to the mean of the adjacent segment directions
    for c, k in zip(chains, start):
        p = s.positions[c]
        d = np.diff(p, axis=0)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        t = d[:-1] + d[1:]
        ok = np.linalg.norm(t, axis=1) > 1e-3
        t = t[ok] / np.linalg.norm(t[ok], axis=1, keepdims=True)
        o = off[k + 1: k + len(c) - 1][ok]
        assert np.allclose(np.einsum("rsj,rj->rs", o, t), 0.0, atol=1e-5)


def test_vertices_within_radius_of_segments():
    s = random_parent_tree(200, seed=3)
    m = branch_mesh(s, radial_segments=6)
    seg_a = s.positions[s.parent[1:]]
    seg_b = s.positions[1:]
    rmax = np.maximum(s.radius[s.parent[1:]], s.radius[1:]).max()
    # distance of every vertex to the nearest segment (brute force on a small tree)
    p = m.positions.astype(np.float64)[:, None, :]
    ab = seg_b - seg_a
    t = np.clip(np.sum((p - seg_a) * ab, axis=2) / np.maximum(np.sum(ab * ab, axis=1), 1e-12), 0, 1)
    d = np.linalg.norm(p - (seg_a + t[..., None] * ab), axis=2).min(axis=1)
    assert d.max() <= max(rmax, MIN_RING_RADIUS) * (1 + 1e-4) + 1e-6


@pytest.mark.parametrize("name", ["y", "random", "grown", "two"])
def test_every_tube_watertight_when_capped(name):
    s = SKELETONS[name]()
    segs = 6
    lens = np.array([len(c) for c in s.chains()])
    m = branch_mesh(s, radial_segments=segs, cap_starts=True)
    per_chain = segs * (2 * (lens - 1) + 2)
    edges = np.concatenate([[0], np.cumsum(per_chain)])
    assert edges[-1] == m.n_triangles
    for i in range(len(lens)):
        f = m.indices[edges[i]:edges[i + 1]].astype(np.int64)
        tm = merged(m.positions, f)
        assert tm.is_watertight, f"chain {i}"
        assert tm.is_winding_consistent
        assert tm.volume > 0  # outward-facing
    # the whole mesh too: every edge shared by exactly two faces
    tm = merged(m.positions, m.indices.astype(np.int64))
    assert tm.is_watertight


def test_uncapped_side_tubes_open_only_inside_parent():
    s = y_tree()
    segs = 8
    m = branch_mesh(s, radial_segments=segs)
    lens = np.array([len(c) for c in s.chains()])
    n0 = segs * (2 * (lens[0] - 1) + 2)
    assert merged(m.positions, m.indices[:n0].astype(np.int64)).is_watertight  # trunk chain: capped
    side = merged(m.positions, m.indices[n0:].astype(np.int64))
    boundary = side.edges_sorted[trimesh.grouping.group_rows(side.edges_sorted, require_count=1)]
    assert len(boundary) == segs
    # the open ring sits at the parent node (node 1), inside the parent tube (radius 0.08),
    # with the side child's radius (node 2: 0.03; node 3, the thicker, continues the trunk)
    verts = side.vertices[np.unique(boundary)]
    assert np.allclose(np.linalg.norm(verts - s.positions[1], axis=1), 0.03, atol=1e-6)


def test_parallel_transport_does_not_twist():
    # a planar arc in the XY plane: the transported frame keeps a constant Z component
    a = np.linspace(0, np.pi * 0.8, 40)
    pos = np.stack([np.sin(a), 1 - np.cos(a), np.zeros_like(a)], axis=1) * 2
    s = TreeSkeleton(pos, np.arange(-1, 39), np.full(40, 0.05))
    m = branch_mesh(s, radial_segments=8)
    ring = m.positions[: 40 * 9].reshape(40, 9, 3).astype(np.float64)
    z = (ring[:, :, 2] - pos[:, None, 2]) / 0.05
    assert np.allclose(z, z[0][None, :], atol=1e-4)
    # a straight line: every ring is a translate of the first
    s2 = TreeSkeleton(np.outer(np.arange(30), [0.1, 1.0, 0.2]), np.arange(-1, 29), np.full(30, 0.05))
    m2 = branch_mesh(s2, radial_segments=5)
    ring2 = m2.positions[: 30 * 6].reshape(30, 6, 3) - s2.positions[:, None, :]
    assert np.allclose(ring2, ring2[0][None], atol=1e-5)


def test_uv_v_is_length_over_circumference():
    s = two_node()
    m = branch_mesh(s, radial_segments=4)
    v = m.uvs[:10, 1].reshape(2, 5)
    length = np.linalg.norm(s.positions[1] - s.positions[0])
    assert np.allclose(v[0], 0.0)
    assert np.allclose(v[1], length / (2 * np.pi * 0.075), rtol=1e-5)
    u = m.uvs[:5, 0]
    assert np.allclose(u, [0, 0.25, 0.5, 0.75, 1.0])
    # along every chain of a random tree, v never decreases
    s = random_parent_tree(300)
    _, lens, nodes, start, _ = chain_layout(s)
    mm = branch_mesh(s, radial_segments=3)
    vv = mm.uvs[: len(nodes) * 4, 1].reshape(len(nodes), 4)[:, 0]
    dv = np.diff(vv)
    inside = np.ones(len(nodes) - 1, bool)
    inside[start[1:] - 1] = False
    assert np.all(dv[inside] >= 0) and np.all(np.isfinite(mm.uvs))


def test_min_radius_skips_thin_chains():
    s = random_parent_tree(300)
    chains = s.chains()
    thick = [c for i, c in enumerate(chains) if s.radius[c if i == 0 else c[1:]].max() >= 0.01]
    m = branch_mesh(s, radial_segments=4, min_radius=0.01)
    lens = np.array([len(c) for c in thick])
    assert 0 < len(thick) < len(chains)
    assert m.n_triangles == tube_triangle_count(lens, 4)
    assert branch_mesh(s, min_radius=10.0).n_triangles == 0


def test_zero_radius_and_zero_length_segments():
    pos = np.array([[0, 0, 0], [0, 1, 0], [0, 1, 0], [0, 2, 0], [1, 2, 0]], float)
    s = TreeSkeleton(pos, np.array([-1, 0, 1, 2, 1]), np.array([0.1, 0.05, 0.05, 0.0, 0.0]))
    m = branch_mesh(s)
    assert np.all(np.isfinite(m.normals)) and np.allclose(np.linalg.norm(m.normals, axis=1), 1, atol=1e-5)
    assert np.all(np.isfinite(m.uvs))


def test_deterministic_and_bad_input():
    s = random_parent_tree(200)
    a, b = branch_mesh(s), branch_mesh(s)
    for k in ("positions", "normals", "uvs", "indices"):
        assert np.array_equal(getattr(a, k), getattr(b, k))
    with pytest.raises(InputError, match="radial_segments"):
        branch_mesh(s, radial_segments=2)
    with pytest.raises(InputError, match="min_radius"):
        branch_mesh(s, min_radius=-1)
    with pytest.raises(InputError, match="skeleton"):
        branch_mesh(np.zeros((3, 3)))
    with pytest.raises(InputError, match="bark_texture"):
        branch_mesh(s, bark_texture=np.zeros((4, 4, 3), np.uint8))


def test_bark_texture():
    t = bark_texture(128, seed=3)
    assert t.shape == (128, 128, 4) and t.dtype == np.uint8
    assert np.all(t[..., 3] == 255)
    assert np.array_equal(t, bark_texture(128, seed=3))
    assert not np.array_equal(t, bark_texture(128, seed=4))
    rgb = t[..., :3].astype(float)
    assert rgb[..., 0].mean() > rgb[..., 2].mean()  # brown-grey: red over blue
    # tileable: the jump across the wrap-around is like the jump between neighbours
    inner_x = np.abs(np.diff(rgb, axis=1)).mean()
    wrap_x = np.abs(rgb[:, 0] - rgb[:, -1]).mean()
    inner_y = np.abs(np.diff(rgb, axis=0)).mean()
    wrap_y = np.abs(rgb[0] - rgb[-1]).mean()
    assert wrap_x < 2 * inner_x and wrap_y < 2 * inner_y
    # fissures run along the grain (rows): vertical neighbours are more alike
    assert inner_y < inner_x
    with pytest.raises(InputError, match="size"):
        bark_texture(4)


@pytest.mark.parametrize("seed", range(8))
def test_compiled_chains_are_skeleton_chains(seed):
    """tubes._chain_arrays (compiled) = TreeSkeleton.chains() (the Python walk): same chains, same order."""
    from treeform.geometry.tubes import _chain_arrays

    rng = np.random.default_rng(seed)
    n = [1, 2, 7, 60, 500, 3000, 40, 900][seed]
    parent = np.concatenate([[-1], (rng.random(n - 1) * np.arange(1, n)).astype(np.int64)])
    # few distinct radii and orders: ties decide the main child
    s = TreeSkeleton(rng.normal(size=(n, 3)), parent, rng.integers(0, 3, n) * 0.01, rng.integers(0, 2, n))
    for sk in (s, grown_tree(300 + 100 * seed, seed=seed)):
        chains = sk.chains()
        nodes, lens = _chain_arrays(sk)
        assert lens.tolist() == [len(c) for c in chains]
        assert np.array_equal(nodes, np.concatenate(chains))


def test_compiled_rotation_scan_is_the_numpy_scan():
    """_kernels.prefix_rotations = the former vectorized Hillis-Steele passes, to the bit."""
    from treeform.geometry._kernels import prefix_rotations

    def qmul(a, b):
        aw, ax, ay, az = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
        bw, bx, by, bz = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
        return np.stack([aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                         aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw], axis=-1)

    rng = np.random.default_rng(0)
    lens = rng.integers(1, 70, 300)
    start = np.cumsum(lens) - lens
    pos_in = np.arange(lens.sum()) - np.repeat(start, lens)
    q = rng.normal(size=(lens.sum(), 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    ref, step = q.copy(), 1
    while step < lens.max():
        m = np.flatnonzero(pos_in >= step)
        nxt = ref.copy()
        nxt[m] = qmul(ref[m], ref[m - step])
        nxt[m] /= np.linalg.norm(nxt[m], axis=1, keepdims=True)
        ref, step = nxt, step * 2
    prefix_rotations(q, pos_in, int(lens.max()))
    assert np.array_equal(q, ref)


def _numpy_frames(P, r, start, lens, pos_in):
    """The former vectorized frame code of _tubes (tangents, parallel transport, slope, v), kept as
    the reference the compiled tube_frames must equal to the bit."""
    from treeform.geometry._kernels import prefix_rotations

    def cross(a, b):
        return np.cross(a, b)

    def any_perp(t):
        ref = np.zeros_like(t)
        use_x = np.abs(t[:, 0]) < 0.9
        ref[use_x, 0], ref[~use_x, 2] = 1.0, 1.0
        p = ref - np.sum(ref * t, axis=1, keepdims=True) * t
        return p / np.linalg.norm(p, axis=1, keepdims=True)

    n = len(P)
    chain_of = np.repeat(np.arange(len(lens)), lens)
    first, last = pos_in == 0, pos_in == (lens - 1)[chain_of]
    seg = np.zeros((n, 3))
    seg[:-1] = P[1:] - P[:-1]
    seg_len = np.linalg.norm(seg, axis=1)
    has_seg = ~last
    valid = has_seg & (seg_len > 1e-9)
    D = np.zeros((n, 3))
    D[valid] = seg[valid] / seg_len[valid, None]
    if not np.all(valid[has_seg]):
        idx = np.arange(n)
        fwd = np.maximum.accumulate(np.where(valid, idx, -1))
        bwd = np.minimum.accumulate(np.where(valid, idx, n)[::-1])[::-1]
        ok_f = (fwd >= 0) & (chain_of[np.clip(fwd, 0, None)] == chain_of)
        ok_b = (bwd < n) & (chain_of[np.clip(bwd, None, n - 1)] == chain_of)
        src = np.where(ok_f, fwd, np.where(ok_b, bwd, -1))
        fill = has_seg & ~valid
        D[fill & (src >= 0)] = D[src[fill & (src >= 0)]]
        D[fill & (src < 0)] = (0.0, 1.0, 0.0)
    D_prev = np.zeros_like(D)
    D_prev[1:] = D[:-1]
    T = np.where(first[:, None], D, np.where(last[:, None], D_prev, D + D_prev))
    bad = np.linalg.norm(T, axis=1) < 1e-6
    T[bad] = D[bad]
    T /= np.linalg.norm(T, axis=1, keepdims=True)
    Q = np.zeros((n, 4))
    Q[:, 0] = 1.0
    nf = ~first
    a, b = T[np.flatnonzero(nf) - 1], T[nf]
    q = np.empty((len(a), 4))
    q[:, 0] = 1.0 + np.sum(a * b, axis=1)
    q[:, 1:] = cross(a, b)
    flip = q[:, 0] < 1e-9
    q[flip, 0] = 0.0
    q[flip, 1:] = any_perp(a[flip]) if flip.any() else q[flip, 1:]
    Q[nf] = q / np.linalg.norm(q, axis=1, keepdims=True)
    prefix_rotations(Q, pos_in, int(lens.max()))
    U0 = any_perp(T[start])[chain_of]
    w, u = Q[:, :1], Q[:, 1:]
    t = 2.0 * cross(u, U0)
    U = U0 + w * t + cross(u, t)
    U -= np.sum(U * T, axis=1, keepdims=True) * T
    U /= np.linalg.norm(U, axis=1, keepdims=True)
    V = cross(T, U)
    seg_r_mean = np.zeros(n)
    seg_r_mean[:-1] = 0.5 * (r[:-1] + r[1:])
    slope_seg = np.zeros(n)
    slope_seg[:-1] = (r[1:] - r[:-1]) / np.maximum(seg_len[:-1], 1e-9)
    slope_seg = np.where(valid, np.clip(slope_seg, -1.0, 1.0), 0.0)
    slope_prev = np.zeros(n)
    slope_prev[1:] = slope_seg[:-1]
    slope = np.where(first, slope_seg, np.where(last, slope_prev, 0.5 * (slope_seg + slope_prev)))
    dv = np.where(has_seg, seg_len / (2.0 * np.pi * np.maximum(seg_r_mean, MIN_RING_RADIUS)), 0.0)
    cum = np.concatenate([[0.0], np.cumsum(dv[:-1])])
    return T, U, V, slope, cum - cum[start][chain_of]


@pytest.mark.parametrize("name", ["y", "random", "grown", "degenerate"])
def test_compiled_tube_frames_are_the_numpy_frames(name):
    """tube_frames (compiled) = the former vectorized frames, to the bit, zero-length segments included."""
    from treeform.geometry._kernels import tube_frames

    if name == "degenerate":  # a repeated node (zero-length segment) and a reversal
        pos = np.array([[0, 0, 0], [0, 1, 0], [0, 1, 0], [0, 2, 0], [0, 1.5, 0], [1, 2, 0], [1, 2, 0]], float)
        s = TreeSkeleton(pos, np.array([-1, 0, 1, 2, 3, 1, 5]), np.array([0.2, 0.1, 0.1, 0.05, 0.04, 0.05, 0.03]))
    else:
        s = SKELETONS[name]()
    _, lens, nodes, start, r = chain_layout(s)
    keep = lens >= 2
    nodes, lens = nodes[np.repeat(keep, lens)], lens[keep]
    start = np.cumsum(lens) - lens
    r = np.maximum(s.radius[nodes], MIN_RING_RADIUS)
    r[start[1:]] = np.minimum(r[start[1:]], r[start[1:] + 1])
    pos_in = np.arange(len(nodes)) - np.repeat(start, lens)
    P = s.positions[nodes].astype(np.float64)
    got = tube_frames(P, r, start, lens, pos_in, MIN_RING_RADIUS)
    for g, want in zip(got, _numpy_frames(P, r, start, lens, pos_in)):
        assert np.array_equal(g, want, equal_nan=True)
