import numpy as np
import pytest

from treeform.crown.layout import tree_layout, trunk_pixels
from treeform.crown.sampling import rdm_front_height, sample_rdm_shell, visual_hull_contains
from treeform._shared.errors import InputError
from treeform.structures import Camera, RadialDistanceMap, Segmentation


def test_rdm_front_height_of_a_sphere():
    # camera 50 m away, 1 px = 0.05 m on the plane z = 0; sphere of radius 2 m at the origin
    cam = Camera(200, 200, 2 * np.degrees(np.arctan(100 * 0.05 / 50)), (0, 0, 50), (0, 0, 0))
    rdm = RadialDistanceMap(np.zeros(3), np.full((6, 32, 32), 2.0, np.float32))
    z = rdm_front_height(rdm, cam, 50.0, 0.05, (200, 200), step=2, steps=200)
    assert abs(z[100, 100] * 0.05 - 2.0) < 0.06  # the front pole, 2 m toward the camera
    assert z[100, 100 + 30] < z[100, 100]  # lower toward the rim
    assert z[5, 5] == 0  # rays that miss the sphere


def test_shell_sampling_respects_keep():
    rdm = RadialDistanceMap(np.zeros(3), np.full((6, 8, 8), 1.0, np.float32))
    p = sample_rdm_shell(rdm, 400, keep=lambda q: q[:, 0] > 0, seed=0)
    assert len(p) == 400 and (p[:, 0] > 0).all()


def test_visual_hull_and_trunk_pixels():
    lab = np.zeros((60, 40), np.uint8)
    lab[5:35, 5:35] = 1
    lab[35:58, 17:23] = 2  # trunk
    lab[10:14, 8:12] = 2  # a visible branch inside the crown, not the trunk
    seg = Segmentation(lab)
    lay = tree_layout(seg)
    tp = trunk_pixels(seg, lay)
    assert tp[50, 20] and not tp[12, 10] and not tp[20, 20]
    cam = Camera(40, 60, 60.0, (0, 0, 10), (0, 0, 0))
    assert visual_hull_contains(cam, seg.tree_mask, cam.unproject([20.5], [20.5], [10.0])).all()
    assert not visual_hull_contains(cam, seg.tree_mask, cam.unproject([1.5], [1.5], [10.0])).any()


def test_weighted_columns_keep_their_pixels_and_gather_depth_where_the_weight_is():
    from treeform.crown.sampling import sample_crown_columns

    mask = np.ones((20, 20), bool)
    front = np.full((20, 20), 10.0)
    even = sample_crown_columns(mask, front, 2000, seed=3)
    # a clump in front of the middle plane: every point's pixel as before, its depth drawn toward z = 5
    w = sample_crown_columns(mask, front, 2000, seed=3, weight=lambda c: np.exp(-0.5 * ((c[:, 2] - 5.0) / 1.5) ** 2))
    assert np.array_equal(w[:, :2], even[:, :2])
    assert np.abs(w[:, 2]).max() <= 10.0
    assert np.mean(np.abs(w[:, 2] - 5.0) < 3.0) > 0.7 > np.mean(np.abs(even[:, 2] - 5.0) < 3.0)
    again = sample_crown_columns(mask, front, 2000, seed=3, weight=lambda c: np.exp(-0.5 * ((c[:, 2] - 5.0) / 1.5) ** 2))
    assert np.array_equal(w, again)
    with pytest.raises(InputError, match="candidates"):
        sample_crown_columns(mask, front, 10, weight=lambda c: np.ones(len(c)), candidates=0)


def test_clumps_fill_the_volume_and_thinning_draws_their_density():
    from treeform.crown.sampling import clump_density, foliage_clumps, thinned
    from treeform.growth.sampling import blue_noise_points

    ball = lambda p: np.linalg.norm(p, axis=1) < 2.0  # noqa: E731
    c = foliage_clumps(ball, ([-2] * 3, [2] * 3), 0.8, seed=1)
    assert 30 <= len(c) <= 90 and ball(c).all()  # 33.5 m^3 / 0.512
    assert np.array_equal(c, foliage_clumps(ball, ([-2] * 3, [2] * 3), 0.8, seed=1))
    # points drawn with the clumps' density lie nearer the centres than evenly spread ones
    dens = lambda p: clump_density(p, c, 0.2)  # noqa: E731
    pts = blue_noise_points(thinned(ball, dens, seed=2), ([-2] * 3, [2] * 3), 800, seed=2)
    even = blue_noise_points(ball, ([-2] * 3, [2] * 3), 800, seed=2)
    assert len(pts) == 800 and dens(pts).mean() > 1.5 * dens(even).mean()  # 0.34 against 0.18
    with pytest.raises(InputError):
        foliage_clumps(ball, ([-2] * 3, [2] * 3), 0.0)
