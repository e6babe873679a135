"""RadialBoundingVolume (seed 003 §4.1): fitting, containment, levels, normalisation, io, errors."""

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.structures import Foliage, RadialBoundingVolume, TreeSkeleton
from treeform.structures.rbv import LEVELS, level_size


def cylinder_points(n=40000, r=2.0, h=5.0, seed=0):
    rng = np.random.default_rng(seed)
    a = rng.uniform(0, 2 * np.pi, n)
    y = rng.uniform(0, h, n)
    y[:2] = [0.0, h]
    return np.c_[r * np.cos(a), y, r * np.sin(a)]


def tree_points(seed=1, n=5000):
    rng = np.random.default_rng(seed)
    trunk = np.c_[rng.normal(0, 0.05, 300), rng.uniform(0, 3, 300), rng.normal(0, 0.05, 300)]
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    crown = u * rng.uniform(0, 1, (n, 1)) ** (1 / 3) * [2.5, 2.0, 1.5] + [0.4, 5.0, -0.2]
    return np.concatenate([trunk, crown])


@pytest.mark.parametrize("level", [3, 4, 5])
def test_cylinder_gives_constant_sector_radii(level):
    rbv = RadialBoundingVolume.from_points(cylinder_points(), level=level)
    n = level_size(level)
    assert rbv.radii.shape == (n, n) and rbv.level == level
    np.testing.assert_allclose(rbv.radii, 2.0, rtol=1e-12)
    assert rbv.height == 5.0 and rbv.radius == pytest.approx(2.0)
    assert rbv.volume() == pytest.approx(np.pi * 4 * 5, rel=1e-9)


def test_cone_radii_decrease_with_layers():
    rng = np.random.default_rng(2)
    n, big_r, h = 60000, 3.0, 6.0
    y = rng.uniform(0, h, n)
    a = rng.uniform(0, 2 * np.pi, n)
    r = big_r * (1 - y / h)
    pts = np.c_[r * np.cos(a), y, r * np.sin(a)]
    rbv = RadialBoundingVolume.from_points(pts, level=4)
    assert np.all(np.diff(rbv.radii, axis=0) < 0)  # every sector shrinks going up
    # each layer's radius is the cone's radius at the layer's bottom
    expected = big_r * (1 - np.arange(8) / 8)
    np.testing.assert_allclose(rbv.radii, np.repeat(expected[:, None], 8, axis=1), atol=0.02)


def test_contains_matches_an_analytic_cylinder():
    rng = np.random.default_rng(3)
    origin = np.array([1.0, 0.5, -1.0])
    rbv = RadialBoundingVolume(np.full((4, 4), 2.0), 5.0, origin)
    pts = origin + rng.uniform([-3, -1, -3], [3, 6, 3], (20000, 3))
    local = pts - origin
    expected = (local[:, 1] >= 0) & (local[:, 1] <= 5) & (np.hypot(local[:, 0], local[:, 2]) <= 2)
    np.testing.assert_array_equal(rbv.contains(pts), expected)
    assert rbv.contains(np.zeros((0, 3))).shape == (0,)


def test_contains_matches_the_sector_convention():
    """Sector 0 holds angles [0, π) (z > 0) at level 2, layer 0 the lower half."""
    rng = np.random.default_rng(4)
    radii = np.array([[1.0, 2.0], [3.0, 4.0]])
    rbv = RadialBoundingVolume(radii, 2.0)
    pts = rng.uniform([-5, -0.5, -5], [5, 2.5, 5], (20000, 3))
    layer = (pts[:, 1] >= 1.0).astype(int)
    sector = (pts[:, 2] < 0).astype(int)
    inside = (pts[:, 1] >= 0) & (pts[:, 1] <= 2) & (np.hypot(pts[:, 0], pts[:, 2]) <= radii[layer, sector])
    np.testing.assert_array_equal(rbv.contains(pts), inside)
    lay, sec = rbv.sector_of(np.array([[1.0, 0.5, 0.1], [1.0, 1.5, -0.1], [0, -1, 0], [0, 3, 0]]))
    assert lay.tolist() == [0, 1, -1, -1] and sec.tolist() == [0, 1, -1, -1]


def test_at_level_coarse_is_max_of_fine():
    rng = np.random.default_rng(5)
    fine = RadialBoundingVolume(rng.uniform(0, 3, (16, 16)), 7.0, (0.5, 0, 0.5))
    for k in (1, 2, 3, 4):
        coarse = fine.at_level(k).radii
        n = level_size(k)
        f = 16 // n
        for i in range(n):
            for j in range(n):
                assert coarse[i, j] == fine.radii[i * f:(i + 1) * f, j * f:(j + 1) * f].max()
    # refine then coarsen gives back the same volume; coarsening chains consistently
    mid = fine.at_level(3)
    np.testing.assert_array_equal(mid.at_level(5).at_level(3).radii, mid.radii)
    np.testing.assert_array_equal(fine.at_level(4).at_level(2).radii, fine.at_level(2).radii)
    assert [a.shape for a in fine.levels()] == [(1, 1), (2, 2), (4, 4), (8, 8), (16, 16)]
    assert fine.at_level(2).height == 7.0 and fine.at_level(2).origin.tolist() == [0.5, 0, 0.5]


def test_fitting_at_a_coarse_level_equals_coarsening_a_fine_fit():
    pts = tree_points()
    fine = RadialBoundingVolume.from_points(pts, level=5)
    for k in LEVELS:
        direct = RadialBoundingVolume.from_points(pts, level=k)
        np.testing.assert_array_equal(direct.radii, fine.at_level(k).radii)


@pytest.mark.parametrize("level", [3, 4, 5])
def test_every_point_used_to_build_it_is_contained(level):
    pts = tree_points(seed=level)
    rbv = RadialBoundingVolume.from_points(pts, level=level)
    assert rbv.contains(pts).all()
    # and a coarser level contains them too
    assert rbv.at_level(level - 1).contains(pts).all()
    # points above the top or below the base are outside
    assert not rbv.contains(np.array([[0, rbv.height * 1.01, 0], [0, -0.01, 0]])).any()


def test_from_points_with_an_axis_origin():
    pts = cylinder_points() + [10.0, 2.0, -3.0]
    rbv = RadialBoundingVolume.from_points(pts, level=3, axis_origin=(10.0, 2.0, -3.0))
    np.testing.assert_allclose(rbv.radii, 2.0, rtol=1e-9)
    assert rbv.contains(pts).all()


def _skeleton():
    pos = np.array([[0, 0, 0], [0, 2, 0], [0, 4, 0], [2, 4, 0]], float)
    return TreeSkeleton(pos, np.array([-1, 0, 1, 1]), np.array([0.2, 0.15, 0.1, 0.05]), np.array([0, 0, 0, 1]))


def test_from_skeleton_samples_long_internodes_and_adds_radius():
    s = _skeleton()
    rbv = RadialBoundingVolume.from_skeleton(s, level=3, samples_per_segment=4)
    assert rbv.height == 4.0
    # the lateral 1 -> 3 crosses layer 2 (2 <= y < 3) at x = 0.5 (y = 2.5) with radius 0.125
    assert rbv.radii[2, 0] == pytest.approx(0.5 + 0.125)
    assert rbv.radii[3, 0] == pytest.approx(2.0 + 0.05)
    # without intermediate samples that layer only sees the trunk and the branching node
    coarse = RadialBoundingVolume.from_skeleton(s, level=3, samples_per_segment=1)
    assert coarse.radii[2, 0] == pytest.approx(0.15)
    assert rbv.contains(s.positions).all()
    single = RadialBoundingVolume.from_skeleton(TreeSkeleton(np.array([[0, 0, 0], [0, 1, 0.]]), np.array([-1, 0])),
                                                level=1)
    assert single.radii.tolist() == [[0.01]]


def test_a_branch_hanging_below_the_root_counts_in_the_lowest_layer():
    """A weeping twig 3 cm under the foot (a willow's, from the abs route) is part of the tree, not an error:
    it widens the lowest layer; the points' constructor, given an explicit base, still refuses such points."""
    pos = np.array([[0, 0, 0], [0, 3, 0], [1.5, 1, 0], [1.8, -0.03, 0]], float)
    s = TreeSkeleton(pos, np.array([-1, 0, 1, 2]), np.array([0.2, 0.1, 0.04, 0.02]), np.array([0, 0, 1, 1]))
    rbv = RadialBoundingVolume.from_skeleton(s, level=2, samples_per_segment=2)
    assert rbv.height == 3.0 and rbv.radii[0].max() == pytest.approx(1.8 + 0.02)
    with pytest.raises(InputError, match="below the base"):
        RadialBoundingVolume.from_points(pos, level=2, axis_origin=(0.0, 0.0, 0.0))


def test_save_load_round_trip_is_exact(tmp_path):
    rbv = RadialBoundingVolume.from_points(tree_points(), level=4, axis_origin=(0.1, -0.2, 0.3)).normalized()
    rbv.save(tmp_path / "rbv.npz")
    back = RadialBoundingVolume.load(tmp_path / "rbv.npz")
    np.testing.assert_array_equal(back.radii, rbv.radii)
    np.testing.assert_array_equal(back.origin, rbv.origin)
    assert (back.height, back.radial_scale, back.height_scale) == (rbv.height, rbv.radial_scale, rbv.height_scale)
    assert back.radii.dtype == np.float64 and back.level == 4


def test_load_rejects_other_files(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        RadialBoundingVolume.load(tmp_path / "missing.npz")
    Foliage.empty().save(tmp_path / "f.npz")
    with pytest.raises(InputError, match="RadialBoundingVolume"):
        RadialBoundingVolume.load(tmp_path / "f.npz")
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(InputError):
        RadialBoundingVolume.load(tmp_path / "junk.npz")


def test_normalized_round_trip():
    pts = tree_points()
    rbv = RadialBoundingVolume.from_points(pts, level=4)
    n = rbv.normalized()
    assert n.height == pytest.approx(1.0) and n.height_scale == rbv.height and n.radial_scale == rbv.height
    np.testing.assert_allclose(n.radii, rbv.radii / rbv.height)
    # a per-species normalisation with separate factors
    sp = rbv.normalized(height_scale=10.0, radial_scale=4.0)
    np.testing.assert_allclose(sp.radii, rbv.radii / 4.0)
    assert sp.height == pytest.approx(rbv.height / 10.0)
    # the inverse
    for m in (n, sp, sp.normalized()):
        back = m.denormalized()
        np.testing.assert_allclose(back.radii, rbv.radii, rtol=1e-14)
        assert back.height == pytest.approx(rbv.height, rel=1e-14)
        assert back.radial_scale == back.height_scale == 1.0
    # the physical volume is unchanged: the same points are inside
    rng = np.random.default_rng(6)
    probe = rng.uniform([-3, -1, -3], [3, 8, 3], (5000, 3))
    np.testing.assert_array_equal(n.contains(probe), rbv.contains(probe))
    np.testing.assert_array_equal(sp.contains(probe), rbv.contains(probe))


@pytest.mark.parametrize("points", [np.zeros((5, 2)), np.zeros((0, 3)), np.array([[0, 1, np.nan]]), "abc",
                                    np.array([[0, 1, 0], [0, -1, 0.]]), np.array([[1, 0, 0], [0, 0, 1.]])])
def test_from_points_rejects_bad_points(points):
    with pytest.raises(InputError, match="points"):
        RadialBoundingVolume.from_points(points)


@pytest.mark.parametrize("level", [0, 6, 2.5, True, "3"])
def test_bad_levels(level):
    with pytest.raises(InputError, match="level"):
        RadialBoundingVolume.from_points(cylinder_points(100), level=level)
    with pytest.raises(InputError, match="level"):
        RadialBoundingVolume(np.ones((2, 2)), 1.0).at_level(level)


@pytest.mark.parametrize("kwargs", [
    {"radii": np.ones((3, 3)), "height": 1.0},
    {"radii": np.ones((2, 4)), "height": 1.0},
    {"radii": np.ones(4), "height": 1.0},
    {"radii": -np.ones((2, 2)), "height": 1.0},
    {"radii": np.full((2, 2), np.inf), "height": 1.0},
    {"radii": np.ones((2, 2)), "height": 0.0},
    {"radii": np.ones((2, 2)), "height": "tall"},
    {"radii": np.ones((2, 2)), "height": 1.0, "origin": (0, 0)},
    {"radii": np.ones((2, 2)), "height": 1.0, "radial_scale": -1.0},
])
def test_constructor_validates(kwargs):
    with pytest.raises(InputError):
        RadialBoundingVolume(**kwargs)


def test_other_bad_arguments():
    rbv = RadialBoundingVolume(np.ones((2, 2)), 1.0)
    with pytest.raises(InputError, match="height_scale"):
        rbv.normalized(height_scale=0)
    with pytest.raises(InputError, match="axis_origin"):
        RadialBoundingVolume.from_points(cylinder_points(100), axis_origin=(0, 0))
    with pytest.raises(InputError, match="skeleton"):
        RadialBoundingVolume.from_skeleton(np.zeros((3, 3)))
    with pytest.raises(InputError, match="samples_per_segment"):
        RadialBoundingVolume.from_skeleton(_skeleton(), samples_per_segment=0)
    with pytest.raises(InputError, match="points"):
        rbv.contains(np.zeros((3, 2)))
    # validate() catches a corrupted field
    rbv.radii[0, 0] = -1
    with pytest.raises(InputError):
        rbv.validate()


def test_plot_rbv_draws_top_and_side():
    # the picture lives in treeform.report.rbv_plot; a smoke test next to the structure it draws
    from treeform.report.rbv_plot import plot_rbv, plot_rbv_levels

    rbv = RadialBoundingVolume.from_points(tree_points(), level=5)
    img = plot_rbv(rbv, size=128)
    assert img.dtype == np.uint8 and img.ndim == 3 and img.shape[1] == 256 and img.shape[2] == 3
    assert (img < 250).any(axis=2).mean() > 0.05  # something is drawn
    one = plot_rbv(rbv.at_level(1), size=64, layer=0)
    assert one.shape[1] == 128
    grid = plot_rbv_levels(rbv, levels=(2, 3), size=64)
    assert grid.shape[1] == 128 and grid.shape[0] > 2 * 64
    with pytest.raises(InputError):
        plot_rbv(rbv, layer=16)
    with pytest.raises(InputError):
        plot_rbv("rbv")
