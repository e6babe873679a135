"""Leaf clusters on the twigs: the compiled paths against the plain NumPy / SciPy code they replaced (same bits)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

from treeform._shared.errors import InputError
from treeform._shared.rng import as_rng
from treeform.growth import leaves as L
from treeform.growth._leaf_kernels import nearest_points
from treeform.growth.phenomenological import grow
from treeform.growth.species import load_species, load_species_appearance
from treeform.structures import Foliage, TreeSkeleton


# ----------------------------------------------------------------------------- references (the former code)
def _unit(v):
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def _ref_tips(sk):
    tips = np.zeros(sk.n_nodes)
    tips[sk.tips()] = 1
    for i in range(sk.n_nodes - 1, 0, -1):
        tips[sk.parent[i]] += tips[i]
    return tips


def _ref_twig_nodes(sk, twig_tips=4):
    twigs = np.flatnonzero(_ref_tips(sk) <= twig_tips)
    return twigs[twigs > 0]


def _ref_attach(sk, positions, *, size, center, twig_tips=8, scatter=0.9, seed=None):
    positions = np.asarray(positions, np.float64).reshape(-1, 3)
    n = len(positions)
    rng = as_rng(seed)
    twigs = np.flatnonzero((_ref_tips(sk) <= twig_tips) & (sk.order > 0))
    if len(twigs) == 0:
        twigs = np.arange(1, sk.n_nodes)
    _, j = cKDTree(sk.positions[twigs]).query(positions)
    center = np.asarray(center, np.float64)
    normal = _unit(_unit(positions - center) + float(scatter) * _unit(rng.normal(size=(n, 3))))
    up = _unit(np.cross(normal, _unit(rng.normal(size=(n, 3)))))
    s = size * rng.uniform(0.8, 1.2, n)
    return Foliage(positions, normal, up, s, np.tile(np.float32([0.25, 0.45, 0.15]), (n, 1)), twigs[j])


def _ref_positions(sk, n, *, size, twig_tips=4, seed=None):
    rng = as_rng(seed)
    twigs = _ref_twig_nodes(sk, twig_tips)
    if n <= 0 or len(twigs) == 0:
        return np.zeros((0, 3))
    reps = np.full(len(twigs), n // len(twigs))
    reps[rng.permutation(len(twigs))[: n % len(twigs)]] += 1
    node = np.repeat(twigs, reps)
    a, b = sk.positions[sk.parent[node]], sk.positions[node]
    t = rng.uniform(0.0, 1.0, (len(node), 1))
    pts = a + t * (b - a) + rng.normal(0.0, size / 3.0, (len(node), 3))
    pts[:, 1] = np.maximum(pts[:, 1], size / 2)
    return pts


def _ref_colors(foliage, base_rgb, center, radius, rng):
    m = len(foliage)
    base = np.asarray(base_rgb, np.float32)
    bright = rng.uniform(0.82, 1.18, (m, 1)).astype(np.float32)
    hue = rng.normal(0.0, 0.035, (m, 3)).astype(np.float32)
    hue[:, 1] *= 0.5
    depth = np.linalg.norm(foliage.positions - center, axis=1) / max(radius, 1e-6)
    shade = (0.72 + 0.28 * np.clip(depth, 0.0, 1.0)).astype(np.float32)[:, None]
    return np.clip((base + hue) * bright * shade, 0.0, 1.0)


def _ref_twig_foliage(sk, *, leaf_color, size, leaves=None, leaves_per_twig=3.0, twig_tips=4, seed=None):
    rng = as_rng(seed)
    n = leaves if leaves is not None else int(round(leaves_per_twig * len(_ref_twig_nodes(sk, twig_tips))))
    pts = _ref_positions(sk, n, size=size, twig_tips=twig_tips, seed=rng)
    lo, hi = pts.min(0), pts.max(0)
    center = 0.5 * (lo + hi)
    f = _ref_attach(sk, pts, size=size, center=center, twig_tips=twig_tips, seed=rng)
    return f.with_colors(_ref_colors(f, leaf_color, center, 0.5 * float(np.linalg.norm(hi - lo)), rng))


def _random_tree(n, seed):
    rng = np.random.default_rng(seed)
    parent = np.concatenate([[-1], (rng.random(n - 1) * np.arange(1, n)).astype(np.int64)])
    pos = np.zeros((n, 3))
    step = rng.normal(size=(n, 3)) * 0.3 + [0, 0.4, 0]
    for i in range(1, n):
        pos[i] = pos[parent[i]] + step[i]
    return TreeSkeleton(pos, parent, order=(np.arange(n) > 0) * rng.integers(0, 3, n))


def _same(a: Foliage, b: Foliage, keys=("positions", "normals", "up", "size", "color", "node")):
    for k in keys:
        assert np.array_equal(getattr(a, k), getattr(b, k)), k


def _on_own_twig(sk, f: Foliage, twig_tips: int, size: float):
    """Each cluster's node is a twig, and the cluster lies by that twig's internode (offset σ = size / 3)."""
    assert np.isin(f.node, L.twig_nodes(sk, twig_tips)).all()
    a, b = sk.positions[sk.parent[f.node]], sk.positions[f.node]
    ab = b - a
    t = np.clip(np.einsum("ij,ij->i", f.positions - a, ab) / np.maximum(np.einsum("ij,ij->i", ab, ab), 1e-12), 0, 1)
    d = np.linalg.norm(f.positions - (a + t[:, None] * ab), axis=1)
    assert np.percentile(d, 99) < 5 * size / 3 + size / 2


@pytest.fixture(scope="module")
def oak():
    return grow(load_species("oak"), seed=0), load_species_appearance("oak")


# ----------------------------------------------------------------------------- tests
@pytest.mark.parametrize("seed", range(6))
def test_subtree_tips_and_twigs_match_the_python_loop(seed):
    sk = _random_tree([1, 2, 50, 700, 3000, 40][seed], seed)
    assert np.array_equal(L.subtree_tips(sk), _ref_tips(sk))
    for t in (1, 4, 9):
        assert np.array_equal(L.twig_nodes(sk, t), _ref_twig_nodes(sk, t))


def test_nearest_points_match_ckdtree():
    rng = np.random.default_rng(0)
    for case in range(300):
        k, q = int(rng.integers(1, 400)), int(rng.integers(1, 300))
        scale = rng.uniform(0.01, 10, 3) * (rng.random(3) > 0.25)  # flat, collinear, single-point sets too
        pts = rng.normal(size=(k, 3)) * scale + rng.normal(size=3) * 5
        queries = pts.mean(0) + rng.normal(size=(q, 3)) * scale * rng.uniform(0.3, 4)
        if case % 7 == 0:
            queries[: q // 3] += rng.normal(size=3) * 1e3  # far outside the grid
        d, i = cKDTree(pts).query(queries)
        j = nearest_points(pts, queries)
        dj = np.linalg.norm(queries - pts[j], axis=1)
        assert np.array_equal(d, dj), case  # the same distance, to the bit
        unique = np.sum(np.linalg.norm(queries[:, None] - pts[None], axis=2) == d[:, None], axis=1) == 1
        assert np.array_equal(i[unique], j[unique]), case


def test_nearest_points_ties_go_to_the_lowest_index():
    pts = np.array([[0.0, 0, 0], [1, 0, 0], [0, 0, 0], [1, 0, 0], [-1, 0, 0]])
    q = np.array([[0.0, 0, 0], [1, 0, 0], [0.5, 0, 0], [-0.5, 0, 0], [5, 5, 5]])
    assert nearest_points(pts, q).tolist() == [0, 1, 0, 0, 1]


def test_attach_leaves_matches_the_former_code(oak):
    sk, _ = oak
    rng = np.random.default_rng(1)
    pts = sk.positions[rng.integers(0, sk.n_nodes, 3000)] + rng.normal(0, 0.3, (3000, 3))
    for tips, scatter in ((8, 0.9), (2, 0.0), (4, 2.5)):
        _same(L.attach_leaves(sk, pts, size=0.3, center=[0, 4, 0], twig_tips=tips, scatter=scatter, seed=5),
              _ref_attach(sk, pts, size=0.3, center=[0, 4, 0], twig_tips=tips, scatter=scatter, seed=5))
    with pytest.raises(InputError):
        L.attach_leaves(sk, np.array([[0, np.nan, 0]]), size=0.3, center=[0, 4, 0])


def test_twig_foliage_matches_the_former_code(oak):
    sk, look = oak
    # the same cards as the former code; the node is now the twig each cluster was scattered
    # around (the former code searched for the nearest twig, which only named it differently)
    keys = ("positions", "normals", "up", "size", "color")
    for kw in (dict(leaves_per_twig=3.0, seed=0), dict(leaves=777, seed=3, twig_tips=2), dict(leaves=5, seed=1)):
        f = L.twig_foliage(sk, leaf_color=look.leaf_color, size=look.leaf_size, **kw)
        _same(f, _ref_twig_foliage(sk, leaf_color=look.leaf_color, size=look.leaf_size, **kw), keys)
        _on_own_twig(sk, f, kw.get("twig_tips", 4), look.leaf_size)
    small = _random_tree(300, 4)
    f = L.twig_foliage(small, leaf_color=[0.2, 0.5, 0.1], size=0.2, seed=2)
    _same(f, _ref_twig_foliage(small, leaf_color=[0.2, 0.5, 0.1], size=0.2, seed=2), keys)
    _on_own_twig(small, f, 4, 0.2)
    assert len(L.twig_foliage(TreeSkeleton(np.zeros((1, 3)), [-1]), leaf_color=[0.2, 0.5, 0.1], size=0.2)) == 0


def test_attach_leaves_takes_known_twigs_and_checks_them(oak):
    sk, _ = oak
    pts = sk.positions[[5, 9, 11]] + 0.1
    f = L.attach_leaves(sk, pts, size=0.3, center=[0, 5, 0], nodes=np.array([5, 9, 11]), seed=0)
    assert f.node.tolist() == [5, 9, 11]
    g = L.attach_leaves(sk, pts, size=0.3, center=[0, 5, 0], seed=0)  # same cards, searched twigs
    _same(f, g, ("positions", "normals", "up", "size", "color"))
    for bad in (np.array([5, 9]), np.array([5, 9, sk.n_nodes]), np.array([0.5, 1.0, 2.0])):
        with pytest.raises(InputError, match="nodes"):
            L.attach_leaves(sk, pts, size=0.3, center=[0, 5, 0], nodes=bad)
