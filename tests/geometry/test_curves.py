
import numpy as np
import pytest
from scipy.interpolate import BSpline

from treeform._shared.errors import InputError
from treeform.geometry import bspline_skeleton, tree_mesh
from treeform.geometry import tubes
from treeform.structures import TreeSkeleton

from conftest import grown_tree, random_foliage, random_parent_tree, y_tree


def _chain_skeleton(points, radius=None) -> TreeSkeleton:
    points = np.asarray(points, float)
    n = len(points)
    radius = np.linspace(0.1, 0.02, n) if radius is None else radius
    return TreeSkeleton(points, np.arange(-1, n - 1), radius)


def _turning_angles(p: np.ndarray) -> np.ndarray:
    d = np.diff(p, axis=0)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return np.degrees(np.arccos(np.clip((d[1:] * d[:-1]).sum(1), -1, 1)))


def _reference(skeleton: TreeSkeleton, s: int):
    """An independent sequential version with scipy's BSpline: per chain, the expected (position,
    radius) samples, the first control moved to the parent curve at the Greville parameter."""
    chains = skeleton.chains()
    curves, grev = [], []  # per chain: (m, 4) samples; (n,) sample index of each control point
    where = {}  # node -> (chain, local index) of the chain owning it
    for c, ch in enumerate(chains):
        for j, node in enumerate(ch):
            if c == 0 or j > 0:
                where[int(node)] = (c, j)
    for c, ch in enumerate(chains):
        ctrl = np.concatenate([skeleton.positions[ch], skeleton.radius[ch, None]], axis=1)
        if c > 0:
            o, j = where[int(ch[0])]
            assert o < c
            ctrl[0] = curves[o][j * s]
        n = len(ch)
        p = min(3, n - 1)
        knots = np.concatenate([np.zeros(p), np.linspace(0, 1, n - p + 1), np.ones(p)])
        xi = np.array([knots[i + 1:i + p + 1].mean() for i in range(n)])
        u = [xi[j] + k / s * (xi[j + 1] - xi[j]) for j in range(n - 1) for k in range(s)] + [1.0]
        curves.append(BSpline(knots, ctrl, p)(np.array(u)))
    return chains, curves


@pytest.mark.parametrize("s", [1, 3, 5])
def test_valid_skeleton_with_the_expected_node_count(s):
    sk = random_parent_tree(200, seed=3)
    sk.meta["source"] = "test"
    b = bspline_skeleton(sk, samples_per_segment=s)
    assert isinstance(b, TreeSkeleton)
    b.validate()
    assert b.n_nodes == 1 + (sk.n_nodes - 1) * s
    assert np.array_equal(b.positions[0], sk.positions[0]) and b.parent[0] == -1
    assert b.meta == {"source": "test", "bspline_samples_per_segment": s}
    assert "bspline_samples_per_segment" not in sk.meta  # meta copied, not shared
    # one connected tree: every node reaches the root
    depth_ok = np.zeros(b.n_nodes, bool)
    depth_ok[0] = True
    for i in range(1, b.n_nodes):
        depth_ok[i] = depth_ok[b.parent[i]]
    assert depth_ok.all()


@pytest.mark.parametrize("make", [lambda: random_parent_tree(80, seed=1), lambda: grown_tree(150, seed=4), y_tree])
def test_matches_a_sequential_scipy_reference(make):
    sk = make()
    s = 3
    b = bspline_skeleton(sk, samples_per_segment=s)
    chains, curves = _reference(sk, s)
    out = 0
    for c, (ch, cur) in enumerate(zip(chains, curves)):
        own = cur if c == 0 else cur[1:]
        idx = np.arange(out, out + len(own))
        np.testing.assert_allclose(b.positions[idx], own[:, :3], atol=1e-12)
        np.testing.assert_allclose(b.radius[idx], own[:, 3], atol=1e-12)
        np.testing.assert_array_equal(b.parent[idx[1:]], idx[:-1])  # a chain is a path
        if c > 0:
            # the chain starts on its parent's curve: its first node hangs from a sample at cur[0]
            first_parent = b.parent[idx[0]]
            assert first_parent < out
            np.testing.assert_allclose(b.positions[first_parent], cur[0, :3], atol=1e-12)
        out += len(own)
    assert out == b.n_nodes


def test_y_tree_branch_starts_on_the_smoothed_trunk():
    sk = y_tree()  # chains [0, 1, 3] and [1, 2]
    b = bspline_skeleton(sk, samples_per_segment=4)
    p = sk.positions
    # trunk: a quadratic through 0, 1, 3; node 1's Greville parameter 0.5 is trunk sample 4
    assert b.n_nodes == 13
    mid = 0.25 * p[0] + 0.5 * p[1] + 0.25 * p[3]
    np.testing.assert_allclose(b.positions[4], mid, atol=1e-15)
    side = np.flatnonzero(b.parent == 4)
    side = side[side != 5]
    assert side.tolist() == [9]
    # the side chain (two controls) is the straight segment from the trunk point to node 2
    seg = b.positions[[4, 9, 10, 11, 12]]
    np.testing.assert_allclose(seg, mid + np.linspace(0, 1, 5)[:, None] * (p[2] - mid), atol=1e-12)
    # the old attachment node was on the corner; the new one is on the trunk curve, closer to the chord
    assert np.linalg.norm(b.positions[4] - p[1]) > 0.1


def test_endpoints_tips_and_tip_radii_are_kept_exactly():
    sk = grown_tree(800, seed=2)
    b = bspline_skeleton(sk, samples_per_segment=3)
    t0, t1 = sk.tips(), b.tips()
    assert len(t0) == len(t1)
    key0 = np.lexsort(sk.positions[t0].T)
    key1 = np.lexsort(b.positions[t1].T)
    assert np.array_equal(sk.positions[t0][key0], b.positions[t1][key1])  # exact, not close
    assert np.array_equal(sk.radius[t0][key0], b.radius[t1][key1])
    assert np.array_equal(b.positions[0], sk.positions[0]) and b.radius[0] == sk.radius[0]


def test_straight_chain_stays_on_its_line():
    t = np.array([0.0, 0.1, 0.5, 0.6, 1.4, 2.0])
    d = np.array([0.3, 0.9, 0.1])
    sk = _chain_skeleton(t[:, None] * d + [1.0, 0.0, -2.0])
    b = bspline_skeleton(sk, samples_per_segment=5)
    rel = b.positions - [1.0, 0.0, -2.0]
    np.testing.assert_allclose(np.cross(rel, d), 0, atol=1e-12)
    along = rel @ d / (d @ d)
    assert np.all(np.diff(along) > 0)  # monotone, no back-tracking
    assert along[0] == 0 and np.isclose(along[-1], 2.0)


def test_zigzag_becomes_smoother_and_stays_in_the_control_hull():
    x = np.arange(8, dtype=float)
    pts = np.stack([x * 0.3, x, np.where(x % 2 == 0, 0.0, 0.4)], 1)  # a zig-zag up the Y axis
    sk = _chain_skeleton(pts)
    b = bspline_skeleton(sk, samples_per_segment=6)
    assert _turning_angles(b.positions).max() < 0.5 * _turning_angles(pts).max()
    lo, hi = pts.min(0), pts.max(0)
    assert np.all(b.positions >= lo - 1e-12) and np.all(b.positions <= hi + 1e-12)
    # the inner corners are cut: no sample reaches the zig-zag's extreme z values inside the chain
    assert b.positions[1:-1, 2].max() < 0.4 and b.positions[6:-6, 2].min() > 0.0


def test_radii_stay_positive_and_within_the_input_range():
    sk = grown_tree(600, seed=5)
    b = bspline_skeleton(sk, samples_per_segment=4)
    assert np.all(b.radius > 0)
    assert b.radius.min() >= sk.radius.min() - 1e-15 and b.radius.max() <= sk.radius.max() + 1e-15
    # order and age come from the chain's own control points
    assert set(np.unique(b.order)) == set(np.unique(sk.order))
    assert b.age.min() >= sk.age.min() and b.age.max() <= sk.age.max()


def test_order_of_a_side_branch_is_its_own():
    pos = np.array([[0, 0, 0], [0, 1, 0], [0, 2, 0], [0, 3, 0], [1, 1.5, 0], [2, 2, 0]], float)
    sk = TreeSkeleton(pos, np.array([-1, 0, 1, 2, 1, 4]), np.array([0.1, 0.08, 0.06, 0.04, 0.03, 0.02]),
                      np.array([0, 0, 0, 0, 1, 1]))
    b = bspline_skeleton(sk, samples_per_segment=4)
    side = b.positions[:, 0] > 1e-9
    assert np.all(b.order[side] == 1) and np.all(b.order[~side] == 0)


def test_samples_per_segment_one_keeps_the_node_count():
    sk = random_parent_tree(120, seed=7)
    b = bspline_skeleton(sk, samples_per_segment=1)
    assert b.n_nodes == sk.n_nodes and len(b.tips()) == len(sk.tips())
    assert np.array_equal(b.child_counts()[0], sk.child_counts()[0])


def test_small_skeletons():
    one = TreeSkeleton(np.zeros((1, 3)), np.array([-1]))
    b = bspline_skeleton(one)
    assert b.n_nodes == 1 and b.meta["bspline_samples_per_segment"] == 3
    two = TreeSkeleton(np.array([[0, 0, 0], [0, 3, 0.]]), np.array([-1, 0]), np.array([0.2, 0.05]))
    b = bspline_skeleton(two, samples_per_segment=3)
    np.testing.assert_allclose(b.positions[:, 1], [0, 1, 2, 3], atol=1e-15)
    np.testing.assert_allclose(b.radius, [0.2, 0.15, 0.1, 0.05], atol=1e-15)


def test_deterministic():
    sk = grown_tree(500, seed=8)
    a, b = bspline_skeleton(sk), bspline_skeleton(sk)
    assert a.to_json() == b.to_json()


@pytest.mark.parametrize("kwargs", [{"samples_per_segment": 0}, {"samples_per_segment": 33},
                                    {"samples_per_segment": 2.0}, {"samples_per_segment": True},
                                    {"samples_per_segment": "3"}])
def test_bad_samples_per_segment(kwargs):
    with pytest.raises(InputError, match="samples_per_segment"):
        bspline_skeleton(y_tree(), **kwargs)


def test_not_a_skeleton():
    with pytest.raises(InputError, match="skeleton: expected a TreeSkeleton, got ndarray"):
        bspline_skeleton(np.zeros((3, 3)))


def test_chains_out_of_parent_order_are_sorted(monkeypatch):
    sk = random_parent_tree(150, seed=9)
    want = bspline_skeleton(sk)
    flat, lens = tubes._chain_arrays(sk)
    start = np.cumsum(lens) - lens
    perm = np.concatenate([[0], np.arange(1, len(lens))[::-1]])  # children before their parents
    shuffled = (np.concatenate([flat[start[c]:start[c] + lens[c]] for c in perm]), lens[perm])
    monkeypatch.setattr(tubes, "_chain_arrays", lambda s: shuffled)
    got = bspline_skeleton(sk)
    got.validate()
    assert got.n_nodes == want.n_nodes and len(got.tips()) == len(want.tips())
    a = want.positions[np.lexsort(want.positions.T)]
    b = got.positions[np.lexsort(got.positions.T)]
    np.testing.assert_allclose(a, b, atol=1e-12)


def test_space_colonization_tree_meshes_after_smoothing():
    from treeform.growth import blue_noise_points, branch_orders, pipe_model_radii, space_colonization

    inside = lambda p: np.linalg.norm(p - [0, 4, 0], axis=1) < 1.5  # noqa: E731
    att = blue_noise_points(inside, ([-1.5, 2.5, -1.5], [1.5, 5.5, 1.5]), 600, seed=0)
    trunk = np.stack([np.zeros(4), np.linspace(0, 2.5, 4), np.zeros(4)], 1)
    res = space_colonization(att, trunk, influence_radius=1.2, kill_distance=0.25, segment_length=0.25)
    r = pipe_model_radii(res.parent)
    sk = TreeSkeleton(res.positions, res.parent, r, branch_orders(res.parent, r))
    assert sk.n_nodes > 30
    b = bspline_skeleton(sk, samples_per_segment=3)
    assert len(b.tips()) == len(sk.tips())
    mesh = tree_mesh(b, random_foliage(b, 50, seed=1), max_triangles=40_000)
    assert 0 < mesh.n_triangles <= 40_000
    bark = [p for p in mesh.parts if p.name == "bark"][0]
    assert np.all(np.isfinite(bark.positions))
    # the bark reaches the smoothed tips
    assert np.linalg.norm(bark.positions - b.positions[b.tips()[0]], axis=1).min() < 0.05
