"""The skeleton of visible wood: shortest paths to the base, cut into branches (skeleton/wood.py)."""

import json

import cv2
import numpy as np
import pytest

from treeform._shared.errors import InputError, NoTreeFoundError
from treeform.skeleton import Skeleton2D, draw_skeleton, lift_to_3d, wood_fraction, wood_skeleton


def bare_tree(n=400):
    """A trunk with three limbs (left low, right middle, leader top) and a twig on the right limb.

    Returns the mask and each limb's polyline (x, y) from its attachment to its tip.
    """
    m = np.zeros((n, n), np.uint8)
    trunk = np.array([[200, 390], [200, 60]])
    limbs = {"left": np.array([[200, 300], [120, 230], [60, 200]]),
             "right": np.array([[200, 220], [290, 150], [340, 110]])}
    cv2.polylines(m, [trunk.reshape(-1, 1, 2)], False, 1, 9)
    for poly in limbs.values():
        cv2.polylines(m, [poly.reshape(-1, 1, 2)], False, 1, 5)
    cv2.line(m, (290, 150), (300, 90), 1, 3)  # a short twig on the right limb
    return m.astype(bool), limbs


def _dist(p, poly):
    a, b = poly[:-1].astype(float), poly[1:].astype(float)
    ab = b - a
    t = np.clip(((p - a) * ab).sum(1) / (ab * ab).sum(1), 0, 1)
    return float(np.min(np.hypot(*(a + t[:, None] * ab - p).T)))


@pytest.fixture(scope="module")
def bare():
    return bare_tree()


def test_limbs_are_found_as_first_order_branches(bare):
    m, limbs = bare
    sk = wood_skeleton(m, m, levels=2)
    assert isinstance(sk, Skeleton2D) and sk.meta["mode"] == "wood" and sk.order[0] == 0
    first = [b for b, o in zip(sk.branches, sk.order) if o == 1]
    assert len(first) == 2
    for name, poly in limbs.items():  # each limb is followed, attachment to tip, within a few pixels
        hit = [b for b in first if np.mean([_dist(p, poly) for p in b]) < 4.0]
        assert len(hit) == 1, name
        assert np.hypot(*(hit[0][-1] - poly[-1])) < 8.0 and np.hypot(*(hit[0][0] - poly[0])) < 10.0
    trunk = sk.branches[0]  # the trunk climbs from the base to the top, not into a limb
    assert trunk[0, 1] > 380 and trunk[-1, 1] < 70 and np.abs(trunk[:, 0] - 200).max() < 5
    second = [i for i, o in enumerate(sk.order) if o == 2]  # the twig, on the right limb
    assert len(second) == 1 and _dist(sk.branches[second[0]][-1], np.array([[290, 150], [300, 90]])) < 6
    assert sk.order[sk.parent[second[0]]] == 1
    # parents come first; every pixel of the tree has its nearest first-order area
    assert all(p < i for i, p in enumerate(sk.parent) if p >= 0)
    assert sk.partition.shape == m.shape and (sk.partition[m] >= 0).all() and (sk.partition[~m] == -1).all()
    json.dumps(sk.to_dict())


def test_levels_and_min_length(bare):
    m, _ = bare
    assert set(wood_skeleton(m, m, levels=1).order.tolist()) == {0, 1}
    # both limbs are about half the tree's height long (~175 of ~340 pixels)
    assert int((wood_skeleton(m, m, levels=1, min_length=0.45).order == 1).sum()) == 2
    short = wood_skeleton(m, m, levels=1, min_length=0.7)
    assert int((short.order == 1).sum()) == 0 and len(short.branches) == 1


def test_hidden_limb_is_bridged_through_foliage(bare):
    m, limbs = bare
    wood = m.copy()
    leaves = np.zeros_like(m)
    cv2.circle(leaves.view(np.uint8), (120, 230), 30, 1, -1)  # a leaf clump hides the left limb's middle
    wood &= ~leaves
    sk = wood_skeleton(m | leaves, wood, levels=1, crown_tips=False)
    first = [b for b, o in zip(sk.branches, sk.order) if o == 1]
    assert any(np.mean([_dist(p, limbs["left"]) for p in b]) < 6.0 for b in first)


def test_deterministic_and_scaled(bare):
    m, _ = bare
    a, b = wood_skeleton(m, m), wood_skeleton(m, m)
    assert all(np.array_equal(x, y) for x, y in zip(a.branches, b.branches))
    small = wood_skeleton(m, m, max_side=200)  # a working size under the image's: results in input pixels
    assert small.shape == m.shape and small.meta["work_shape"] == [200, 200]
    assert abs(small.branches[0][0, 1] - a.branches[0][0, 1]) < 4


def test_given_trunk_roots_the_paths(bare):
    m, _ = bare
    sk = wood_skeleton(m, m, trunk=np.array([[200.0, 385.0], [200.0, 100.0]]))
    assert np.hypot(*(sk.branches[0][0] - [200, 385])) < 3


def test_the_root_is_the_trunks_foot_not_a_lower_twig(bare):
    from treeform.crown.layout import tree_layout
    from treeform.skeleton import trunk_foot
    from treeform.structures import Segmentation

    m, limbs = bare
    low = m.view(np.uint8).copy()
    cv2.line(low, (60, 200), (45, 399), 1, 2)  # a drooping twig from the left limb, below the trunk's foot
    low[398:, 330:333] = 1  # and a speck the mask cut off, lower still
    low = low.astype(bool)
    assert low[399].any() and not low[395:, 195:206].all()
    foot = trunk_foot(low, low)
    assert abs(foot[0] - 200) <= 1 and 392 <= foot[1] <= 395  # the trunk is 9 px wide, its foot on row ~394
    sk = wood_skeleton(low, low, levels=1)
    assert np.hypot(*(sk.branches[0][0] - [200, 394])) < 4 and sk.branches[0][-1, 1] < 70
    first = [b for b, o in zip(sk.branches, sk.order) if o == 1]
    for name, poly in limbs.items():  # the limbs are still found from the right root
        assert any(np.mean([_dist(p, poly[:, :]) for p in b[: len(b) // 2]]) < 6.0 for b in first), name
    lab = np.where(low, 2, 0).astype(np.uint8)
    assert abs(tree_layout(Segmentation(lab)).base[0] - 200.5) <= 1  # the route's trunk base too


def test_draw_and_lift(bare):
    m, _ = bare
    sk = wood_skeleton(m, m)
    img = draw_skeleton(m, sk)
    assert img.shape == (400, 400, 3)
    polys, radius = lift_to_3d(sk, base=(200, 390), metres_per_pixel=0.02, seed=0)
    assert len(polys) == len(sk.branches) and all(p.shape[1] == 3 for p in polys)


def test_wood_fraction(bare):
    m, _ = bare
    assert wood_fraction(m, m) == 1.0 and wood_fraction(m, np.zeros_like(m)) == 0.0
    assert wood_fraction(np.zeros_like(m), m) == 0.0


@pytest.mark.parametrize("kwargs, err, match", [
    (dict(mask=np.zeros((50, 50), bool), wood=np.zeros((50, 50), bool)), NoTreeFoundError, "tree pixels"),
    (dict(wood=np.ones((20, 20), bool)), InputError, "wood"),
    (dict(levels=0), InputError, "levels"),
    (dict(foliage_cost=0.5), InputError, "foliage_cost"),
    (dict(min_length=1.0), InputError, "min_length"),
    (dict(max_side=10), InputError, "max_side"),
    (dict(trunk=[[1, 2, 3]]), InputError, "trunk"),
])
def test_bad_input(bare, kwargs, err, match):
    m, _ = bare
    args = {"mask": m, "wood": m, **kwargs}
    with pytest.raises(err, match=match):
        wood_skeleton(args.pop("mask"), args.pop("wood"), **args)


def test_a_branch_keeps_its_own_way_to_the_trunk():
    """A limb whose tip touches a lower limb in the image (two limbs crossing in projection).

    The tip's shortest way to the foot runs down the lower limb on a diagonal; the limb itself
    (up to the trunk, then down it) is longer. With the trunk cheaper up to its first contested
    fork (the second pass), the tip's path follows its own limb to the trunk.
    """
    m = np.zeros((400, 400), np.uint8)
    cv2.line(m, (200, 390), (200, 60), 1, 9)  # trunk
    cv2.line(m, (200, 150), (330, 150), 1, 5)  # the upper limb, to the right
    cv2.line(m, (200, 330), (320, 152), 1, 5)  # a lower limb rising to touch it near its tip
    m = m.astype(bool)
    sk = wood_skeleton(m, m, levels=1, crown_tips=False)
    limb = np.array([[200, 150], [330, 150]])
    first = [b for b, o in zip(sk.branches, sk.order) if o == 1]
    hit = [b for b in first if np.mean([_dist(p, limb) for p in b]) < 4.0]
    assert len(hit) == 1
    assert np.hypot(*(hit[0][0] - limb[0])) < 10.0 and np.hypot(*(hit[0][-1] - limb[-1])) < 8.0
