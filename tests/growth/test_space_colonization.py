import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.growth import blue_noise_points, branch_orders, pipe_model_radii, space_colonization
from treeform.crown.sampling import sample_crown_columns
from treeform.growth.leaves import attach_leaves, color_leaves
from treeform.structures import TreeSkeleton


def _ball(center, r):
    return lambda p: np.linalg.norm(p - center, axis=1) < r


def test_blue_noise_count_inside_and_spread():
    pts = blue_noise_points(_ball([0, 5, 0], 2), ([-2, 3, -2], [2, 7, 2]), 2000, seed=1)
    assert pts.shape == (2000, 3)
    assert np.all(np.linalg.norm(pts - [0, 5, 0], axis=1) < 2)
    from scipy.spatial import cKDTree

    d, _ = cKDTree(pts).query(pts, k=2)
    white = np.random.default_rng(1).uniform(-2, 2, (20000, 3))
    white = white[np.linalg.norm(white, axis=1) < 2][:2000]
    dw, _ = cKDTree(white).query(white, k=2)
    # jittered sampling avoids the near-coincident pairs white noise has
    assert np.percentile(d[:, 1], 5) > 1.5 * np.percentile(dw[:, 1], 5)
    assert np.array_equal(pts, blue_noise_points(_ball([0, 5, 0], 2), ([-2, 3, -2], [2, 7, 2]), 2000, seed=1))


def test_space_colonization_reaches_the_crown():
    att = blue_noise_points(_ball([0, 6, 0], 2.5), ([-2.5, 3.5, -2.5], [2.5, 8.5, 2.5]), 3000, seed=0)
    trunk = np.stack([np.zeros(6), np.linspace(0, 3.5, 6), np.zeros(6)], 1)
    res = space_colonization(att, trunk, influence_radius=1.5, kill_distance=0.25, segment_length=0.1)
    n = len(res.positions)
    assert n > 200
    assert np.all(res.parent[1:] < np.arange(1, n))
    assert res.attractors_left < 0.05 * len(att)
    seg = np.linalg.norm(res.positions[6:] - res.positions[res.parent[6:]], axis=1)
    np.testing.assert_allclose(seg, 0.1, rtol=1e-9)
    # grown nodes stay near the attractor cloud
    assert np.linalg.norm(res.positions[6:] - [0, 6, 0], axis=1).max() < 2.5 + 0.3
    res2 = space_colonization(att, trunk, influence_radius=1.5, kill_distance=0.25, segment_length=0.1)
    assert np.array_equal(res.positions, res2.positions)


def test_space_colonization_bad_arguments():
    with pytest.raises(InputError):
        space_colonization(np.zeros((3, 3)), np.zeros((1, 3)), influence_radius=-1, kill_distance=1, segment_length=1)
    with pytest.raises(InputError):
        space_colonization(np.zeros((3, 3)), np.zeros((0, 3)), influence_radius=1, kill_distance=1, segment_length=1)
    with pytest.raises(InputError, match="one per attractor"):
        space_colonization(np.zeros((3, 3)), np.zeros((1, 3)), influence_radius=1, kill_distance=[1, 1],
                           segment_length=1)


def _lateral_angles(res, k0):
    """Angle (degrees) to the stem (+y) of the first internode of each lateral grown off the K0 stem nodes."""
    kids = res.parent[k0:]
    on_stem = kids < k0
    d = res.positions[k0:][on_stem] - res.positions[kids[on_stem]]
    return np.degrees(np.arccos(np.clip(d[:, 1] / np.linalg.norm(d, axis=1), -1, 1)))


def test_direction_weight_lets_laterals_leave_at_an_angle_and_bend_toward_their_attractors():
    # a bare stem up to 4 m with a cloud of attractors square to it, at 1.5-2.5 m to its side:
    # Runions's rule sends the laterals straight at them (about 90 degrees to the stem); with the
    # node's own direction weighted 1 they leave at about 45 degrees and still reach the cloud
    rng = np.random.default_rng(0)
    att = np.column_stack([rng.uniform(1.5, 2.5, 400), rng.uniform(1.0, 3.0, 400), rng.uniform(-0.5, 0.5, 400)])
    stem = np.column_stack([np.zeros(41), np.linspace(0.0, 4.0, 41), np.zeros(41)])
    grow = np.zeros(41, bool)
    grow[10:31] = True  # laterals only from the stem's middle, beside the cloud
    kw = dict(influence_radius=3.0, kill_distance=0.25, segment_length=0.1, growable=grow)
    runions = space_colonization(att, stem, **kw)
    bent = space_colonization(att, stem, direction_weight=1.0, **kw)
    a0, a1 = _lateral_angles(runions, 41), _lateral_angles(bent, 41)
    assert len(a0) and len(a1)
    assert np.median(a0) > 75
    assert 35 < np.median(a1) < 60
    assert bent.attractors_left < 0.05 * len(att)
    # the bent laterals turn toward the cloud: their tips reach it, square to the stem
    tips = np.setdiff1d(np.arange(41, len(bent.parent)), bent.parent)
    assert np.percentile(bent.positions[tips, 0], 90) > 1.5
    # weight 0 is Runions's rule, to the node
    same = space_colonization(att, stem, direction_weight=0.0, **kw)
    assert np.array_equal(same.positions, runions.positions)
    with pytest.raises(InputError, match="direction_weight"):
        space_colonization(att, stem, direction_weight=-1.0, **kw)


def test_per_attractor_kill_distance():
    # attractors in a band 1 m wide beside a stem: with each one's kill distance reaching the
    # band's far edge, one chain up the band removes them all; with a short one, side shoots
    # grow out to the far edge
    rng = np.random.default_rng(0)
    att = np.column_stack([rng.uniform(-0.5, 0.5, 400), rng.uniform(0.5, 4, 400), np.zeros(400)])
    kw = dict(influence_radius=2.0, segment_length=0.1)
    wide = space_colonization(att, np.zeros((1, 3)), kill_distance=np.full(400, 0.6), **kw)
    short = space_colonization(att, np.zeros((1, 3)), kill_distance=0.15, **kw)
    assert wide.attractors_left == 0
    kids = np.bincount(wide.parent[1:], minlength=len(wide.parent))
    assert (kids > 1).sum() <= 2 < (np.bincount(short.parent[1:]) > 1).sum()


def test_pipe_model_and_orders():
    parent = np.array([-1, 0, 1, 1, 3, 3])
    r = pipe_model_radii(parent, tip_radius=0.01, exponent=2.0)
    for p in range(len(parent)):
        kids = np.flatnonzero(parent == p)
        if len(kids):
            assert np.isclose(r[p] ** 2, (r[kids] ** 2).sum())
    assert np.isclose(r[0], 0.01 * np.sqrt(3))
    o = branch_orders(parent, r)
    assert o[0] == 0 and o.max() >= 1 and o[3] == 0


def test_leaves_hang_on_nearest_twigs_and_are_deterministic():
    att = blue_noise_points(_ball([0, 6, 0], 2.5), ([-2.5, 3.5, -2.5], [2.5, 8.5, 2.5]), 2000, seed=0)
    trunk = np.stack([np.zeros(6), np.linspace(0, 3.5, 6), np.zeros(6)], 1)
    res = space_colonization(att, trunk, influence_radius=1.5, kill_distance=0.25, segment_length=0.1)
    r = pipe_model_radii(res.parent)
    sk = TreeSkeleton(res.positions, res.parent, r, branch_orders(res.parent, r))
    pts = blue_noise_points(_ball([0, 6, 0], 2.4), ([-2.5, 3.5, -2.5], [2.5, 8.5, 2.5]), 500, seed=2)
    f = attach_leaves(sk, pts, size=0.2, center=[0, 6, 0], seed=3)
    assert len(f) == 500 and np.array_equal(f.positions, pts)
    assert np.all(sk.order[f.node] > 0)  # on twigs, not on the trunk
    d = np.linalg.norm(f.positions - sk.positions[f.node], axis=1)
    assert np.percentile(d, 95) < 0.5  # the colonized twigs reach every part of the crown
    assert np.allclose(np.linalg.norm(f.normals, axis=1), 1) and np.allclose((f.normals * f.up).sum(1), 0, atol=1e-9)
    g = attach_leaves(sk, pts, size=0.2, center=[0, 6, 0], seed=3)
    assert np.array_equal(f.normals, g.normals)


def test_column_sampling_covers_the_mask_evenly():
    mask = np.zeros((60, 80), bool)
    mask[10:50, 10:70] = True
    z = np.where(mask, 5.0, 0.0)
    p = sample_crown_columns(mask, z, 2400, seed=0)
    assert mask[p[:, 1].astype(int), p[:, 0].astype(int)].all()
    counts = np.histogram2d(p[:, 1], p[:, 0], bins=(4, 6), range=((10, 50), (10, 70)))[0]
    assert counts.min() >= 0.8 * counts.mean()  # stratified: every block gets its share
    assert np.abs(p[:, 2]).max() <= 5.0 and (p[:, 2] > 0).mean() > 0.4


def test_color_leaves_ignores_sky_in_window():
    img = np.zeros((5, 5, 3), np.uint8)
    img[:, :2] = (0, 0, 255)  # sky
    img[:, 2:] = (0, 200, 0)  # foliage
    fm = np.zeros((5, 5), bool)
    fm[:, 2:] = True
    f = attach_leaves(TreeSkeleton(np.array([[0, 0, 0], [0, 1, 0.]]), np.array([-1, 0])),
                      np.zeros((1, 3)), size=0.1, center=[0, 1, 0])
    c = color_leaves(f, np.array([[2.5, 2.5]]), np.array([True]), img, fm)
    assert c.color[0, 2] == 0 and c.color[0, 1] > 0.7


def test_perception_cone_limits_what_a_node_sees():
    # attractors only below the start node: an upward cone sees none, so nothing grows
    att = np.random.default_rng(0).uniform(-1, 1, (200, 3)) + [0, -3, 0]
    res = space_colonization(att, np.zeros((1, 3)), influence_radius=10, kill_distance=0.2, segment_length=0.1,
                             perception_angle=60)
    assert len(res.positions) == 1 and res.attractors_left == 200
    # the isotropic version grows down to them
    iso = space_colonization(att, np.zeros((1, 3)), influence_radius=10, kill_distance=0.2, segment_length=0.1)
    assert len(iso.positions) > 20
    # a wide cone toward a crown above grows, and every new segment stays within the cone of its parent's
    att2 = blue_noise_points(_ball([0, 4, 0], 1.5), ([-1.5, 2.5, -1.5], [1.5, 5.5, 1.5]), 1500, seed=0)
    cone = space_colonization(att2, np.zeros((1, 3)), influence_radius=6, kill_distance=0.25, segment_length=0.1,
                              perception_angle=80)
    assert len(cone.positions) > 100 and cone.attractors_left < 0.2 * len(att2)


def test_compiled_nearest_node_search_matches_a_kd_tree():
    # the grid search of space_colonization's update gives what a k-d tree query gives
    from scipy.spatial import cKDTree

    from treeform.growth._point_kernels import nearest_new_node

    rng = np.random.default_rng(3)
    att = rng.uniform(-3, 3, (4000, 3))
    pos = np.concatenate([rng.uniform(-3, 3, (300, 3)), [[10.0, 10.0, 10.0]]])  # one node far outside
    for radius in (0.3, 1.0, 4.0):
        best_d = np.where(rng.random(len(att)) < 0.3, rng.uniform(0, 1, len(att)), np.inf)
        best_n = np.full(len(att), -1, np.int64)
        alive = np.flatnonzero(rng.random(len(att)) < 0.8)
        cand = np.sort(rng.choice(len(pos), 120, replace=False))
        ref_d, ref_n = best_d.copy(), best_n.copy()
        d, j = cKDTree(pos[cand]).query(att[alive], distance_upper_bound=radius)
        better = d < ref_d[alive]
        ref_d[alive[better]], ref_n[alive[better]] = d[better], cand[j[better]]
        nearest_new_node(att, alive, pos, cand, radius, best_d, best_n)
        np.testing.assert_array_equal(best_n, ref_n)
        np.testing.assert_array_equal(best_d, ref_d)


def test_compiled_close_pair_drops_follow_the_closest_pairs_rule():
    from treeform.growth._point_kernels import close_pair_drops

    rng = np.random.default_rng(0)
    partner = rng.integers(0, 50, 50)
    order = rng.permutation(50)
    drop = close_pair_drops(order, partner, 7)
    ref, taken, budget = np.zeros(50, bool), np.zeros(50, bool), 7
    for i in order:  # the rule, written out: one point of each untouched pair, closest pairs first
        if budget == 0:
            break
        if taken[i] or taken[partner[i]]:
            continue
        ref[i] = taken[i] = taken[partner[i]] = True
        budget -= 1
    np.testing.assert_array_equal(drop, ref)
    assert drop.sum() == 7


def test_start_direction_weight_sends_laterals_off_a_leader_at_a_conifers_angle():
    # a conifer's laterals leave its leader almost square to it (the pine preset's 80 degrees)
    # while their own side shoots keep the default's 45: the weight of the start nodes (the
    # leader) is set apart from the grown nodes'
    rng = np.random.default_rng(0)
    att = np.column_stack([rng.uniform(1.5, 2.5, 400), rng.uniform(1.0, 3.0, 400), rng.uniform(-0.5, 0.5, 400)])
    stem = np.column_stack([np.zeros(41), np.linspace(0.0, 4.0, 41), np.zeros(41)])
    grow = np.zeros(41, bool)
    grow[10:31] = True
    kw = dict(influence_radius=3.0, kill_distance=0.25, segment_length=0.1, growable=grow, direction_weight=1.0)
    leader = space_colonization(att, stem, start_direction_weight=0.176, **kw)
    both = space_colonization(att, stem, **kw)
    a_leader, a_both = _lateral_angles(leader, 41), _lateral_angles(both, 41)
    assert 70 < np.median(a_leader) < 88 and 35 < np.median(a_both) < 60
    assert leader.attractors_left < 0.05 * len(att)
    # unset, the start nodes take the grown nodes' weight
    assert np.array_equal(space_colonization(att, stem, start_direction_weight=1.0, **kw).positions, both.positions)
    with pytest.raises(InputError, match="start_direction_weight"):
        space_colonization(att, stem, start_direction_weight=-0.5, **kw)
