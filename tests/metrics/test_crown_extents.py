"""The one definition of crown extents and width (issue 18: grow and `treeform metrics` disagreed)."""

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.metrics.treeform_metrics import crown_extents, mesh_metrics, tree_metrics
from treeform.structures import TreeSkeleton


def test_extents_are_drip_line_to_drip_line_and_width_their_mean():
    # one long branch to +X: counted in full (no trimming), as a forester's tape would
    pos = np.array([[0, 0, 0], [0, 3, 0], [6, 4, 0], [-1, 5, 1], [0, 6, -2.]])
    sk = TreeSkeleton(pos, np.array([-1, 0, 1, 1, 1]))
    m = crown_extents(sk)
    assert m["crown_extent_x_m"] == 7.0 and m["crown_extent_z_m"] == 3.0 and m["crown_width_m"] == 5.0
    assert m["max_radial_extent_m"] == 6.0
    assert crown_extents(pos) == m  # the same numbers from the points themselves
    # tree_metrics and mesh_metrics report exactly these
    t = tree_metrics(sk)
    assert {k: t[k] for k in m} == m
    mm = mesh_metrics(pos)
    assert {k: mm[k] for k in m} == m


def test_radial_extent_is_about_the_skeletons_own_base():
    pos = np.array([[10, 0, 10], [10, 3, 10], [12, 4, 10.]])
    m = crown_extents(TreeSkeleton(pos, np.array([-1, 0, 1])))
    assert m["max_radial_extent_m"] == pytest.approx(2.0)
    assert crown_extents(pos)["max_radial_extent_m"] == pytest.approx(np.hypot(12, 10))  # points: about the Y axis


def test_bad_points():
    with pytest.raises(InputError, match="points"):
        crown_extents(np.zeros((0, 3)))
    with pytest.raises(InputError, match="points"):
        crown_extents(np.zeros((4, 2)))
    with pytest.raises(InputError, match="NaN"):
        crown_extents(np.array([[0, 0, np.inf]]))


def test_leaf_count_comes_from_the_foliage_or_the_skeletons_record():
    from treeform.structures import Foliage

    sk = TreeSkeleton(np.array([[0, 0, 0], [0, 2, 0.]]), np.array([-1, 0]))
    assert tree_metrics(sk)["n_leaves"] is None
    sk.meta["n_leaves"] = 12
    assert tree_metrics(sk)["n_leaves"] == 12
    tri = np.array([[[0, 2, 0], [1, 2, 0], [0, 2, 1.]]])
    assert tree_metrics(sk, leaf_triangles=tri)["n_leaves"] == 12
    f = Foliage(np.array([[0, 2, 0.]] * 3), np.array([[0, 1, 0.]] * 3), np.array([[0, 0, 1.]] * 3), np.ones(3),
                np.full((3, 3), 0.5))
    assert tree_metrics(sk, f)["n_leaves"] == 3  # the foliage in hand wins
    sk.meta["n_leaves"] = "many"
    assert tree_metrics(sk)["n_leaves"] is None
