"""Tree-form metrics of seed 003 §6 on hand-built skeletons and leaf cards with known answers."""

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.metrics import (
    METRIC_NAMES,
    average_branching_angle,
    biomass,
    branching_angles,
    leaf_area_index,
    leaf_area_index_triangles,
    max_radial_trunk_distance,
    mesh_metrics,
    metric_vector,
    tree_height,
    tree_metrics,
    trunk_diameter,
)
from treeform.structures import Foliage, TreeSkeleton


def skel(pos, parent, radius=None, order=None):
    return TreeSkeleton(np.asarray(pos, float), np.asarray(parent), None if radius is None else np.asarray(radius, float),
                        None if order is None else np.asarray(order))


def y_tree():
    """Trunk 0-1-2 straight up (1 m segments); a lateral at node 1 at 45° to the trunk."""
    return skel([[0, 0, 0], [0, 1, 0], [0, 2, 0], [1, 2, 0]], [-1, 0, 1, 1], [0.2, 0.15, 0.1, 0.05], [0, 0, 0, 1])


def cards(centres, normals=(0, 1, 0), up=(0, 0, 1), size=1.0):
    m = len(centres)
    n = np.broadcast_to(np.asarray(normals, float), (m, 3))
    u = np.broadcast_to(np.asarray(up, float), (m, 3))
    return Foliage(np.asarray(centres, float), n, u, np.broadcast_to(np.asarray(size, float), (m,)),
                   np.full((m, 3), 0.5))


# --------------------------------------------------------------------------- branching angle
def test_branching_angle_of_a_45_degree_lateral():
    assert average_branching_angle(y_tree()) == pytest.approx(45.0)
    angles, nodes = branching_angles(y_tree())
    assert angles.tolist() == pytest.approx([45.0]) and nodes.tolist() == [1]


def test_branching_angle_is_averaged_over_branching_points():
    # node 1: laterals at 30° and 60° (mean 45°); node 2: one lateral at 90°
    c30, s30 = np.cos(np.radians(30)), np.sin(np.radians(30))
    pos = [[0, 0, 0], [0, 1, 0], [0, 2, 0], [0, 3, 0], [s30, 1 + c30, 0], [-c30, 1 + s30, 0], [0, 2, 1]]
    s = skel(pos, [-1, 0, 1, 2, 1, 1, 2], [0.3, 0.25, 0.2, 0.15, 0.05, 0.05, 0.05], [0, 0, 0, 0, 1, 1, 1])
    angles, nodes = branching_angles(s)
    assert sorted(angles.round(6).tolist()) == [30.0, 60.0, 90.0]
    assert average_branching_angle(s) == pytest.approx((45.0 + 90.0) / 2)  # not (30 + 60 + 90) / 3


def test_branching_angle_at_the_root_and_without_branches():
    # the root forks: continuation straight up (thicker), lateral at 90°
    s = skel([[0, 0, 0], [0, 1, 0], [1, 0, 0]], [-1, 0, 0], [0.2, 0.1, 0.05], [0, 0, 1])
    assert average_branching_angle(s) == pytest.approx(90.0)
    assert np.isnan(average_branching_angle(skel([[0, 0, 0], [0, 1, 0], [0, 2, 0]], [-1, 0, 1])))


# --------------------------------------------------------------------------- height, diameter
def test_tree_height_and_trunk_diameter():
    s = y_tree()
    assert tree_height(s) == pytest.approx(2.0)
    lifted = skel(s.positions + [3, 1.5, -2], s.parent, s.radius, s.order)
    assert tree_height(lifted) == pytest.approx(2.0)
    # leaves on top raise the height: a horizontal 1 m card at y = 2.5, a vertical one reaching 3.0
    f = cards([[0, 2.5, 0], [0, 2.5, 0]], normals=[[0, 1, 0], [1, 0, 0]], up=[[0, 0, 1], [0, 1, 0]])
    assert tree_height(s, foliage=f) == pytest.approx(3.0)
    assert trunk_diameter(s) == pytest.approx(0.4)
    assert trunk_diameter(s, at=0.5) == pytest.approx(2 * 0.175)
    assert trunk_diameter(s, at=1.5) == pytest.approx(2 * 0.125)
    with pytest.raises(InputError, match="at"):
        trunk_diameter(s, at=2.5)
    with pytest.raises(InputError, match="at"):
        trunk_diameter(s, at=-1)


# --------------------------------------------------------------------------- biomass
def test_biomass_of_a_cylinder_and_a_cone():
    r, h = 0.3, 4.0
    cyl = skel([[0, 0, 0], [0, h, 0]], [-1, 0], [r, r])
    assert biomass(cyl) == pytest.approx(np.pi * r * r * h)
    # split into several segments: same volume
    many = skel([[0, y, 0] for y in np.linspace(0, h, 9)], [-1] + list(range(8)), [r] * 9)
    assert biomass(many) == pytest.approx(np.pi * r * r * h)
    cone = skel([[0, 0, 0], [0, h, 0]], [-1, 0], [r, 0.0])
    assert biomass(cone) == pytest.approx(np.pi * r * r * h / 3)
    assert biomass(skel([[0, 0, 0]], [-1])) == 0.0


def test_biomass_lateral_starts_with_its_own_radius():
    s = y_tree()
    trunk = np.pi / 3 * (0.2 ** 2 + 0.2 * 0.15 + 0.15 ** 2) + np.pi / 3 * (0.15 ** 2 + 0.15 * 0.1 + 0.1 ** 2)
    lateral = np.pi * 0.05 ** 2 * np.sqrt(2)  # a cylinder of radius 0.05, not a cone from 0.15
    assert biomass(s) == pytest.approx(trunk + lateral)


# --------------------------------------------------------------------------- MRT
def test_mrt_per_layer_of_a_known_shape():
    # trunk 0..10 m; at 1, 3, 5, 7, 9 m a branch reaching d_i horizontally (one per 2 m layer)
    d = [0.5, 2.0, 3.0, 1.5, 0.8]
    pos = [[0, y, 0] for y in range(11)]
    parent = [-1] + list(range(10))
    for i, (y, di) in enumerate(zip([1, 3, 5, 7, 9], d)):
        ang = i * 1.3
        pos.append([di * np.cos(ang), y + 0.5, di * np.sin(ang)])
        parent.append(y)
    s = skel(pos, parent)
    np.testing.assert_allclose(max_radial_trunk_distance(s), d)
    np.testing.assert_allclose(max_radial_trunk_distance(s, layers=1), [3.0])
    ten = max_radial_trunk_distance(s, layers=10)
    assert ten.shape == (10,) and ten[0] == 0 and ten[1] == pytest.approx(0.5)
    # the axis passes through the base, wherever the tree stands
    moved = skel(np.asarray(pos) + [5, 0, 5], parent)
    np.testing.assert_allclose(max_radial_trunk_distance(moved), d)
    with pytest.raises(InputError, match="layers"):
        max_radial_trunk_distance(s, layers=0)


def test_mrt_is_measured_from_a_leaning_trunk_not_the_vertical_through_its_base():
    # the same tree with its trunk leaning 8 m over 10 m: the branches keep their distance
    # from the trunk, so the MRT is unchanged (the vertical axis would read up to 8 m more)
    d = [0.5, 2.0, 3.0, 1.5, 0.8]
    lean = 0.8
    pos = [[lean * y, y, 0] for y in range(11)]
    parent = [-1] + list(range(10))
    for i, (y, di) in enumerate(zip([1, 3, 5, 7, 9], d)):
        ang = i * 1.3
        pos.append([lean * (y + 0.5) + di * np.cos(ang), y + 0.5, di * np.sin(ang)])
        parent.append(y)
    np.testing.assert_allclose(max_radial_trunk_distance(skel(pos, parent)), d, atol=1e-9)


# --------------------------------------------------------------------------- LAI
def test_lai_of_horizontal_cards():
    # four 1 m cards tiling a 2 m x 2 m square: one leaf layer
    tiles = [[-0.5, 3, -0.5], [0.5, 3.2, -0.5], [-0.5, 3.4, 0.5], [0.5, 3.6, 0.5]]
    assert leaf_area_index(cards(tiles)) == pytest.approx(1.0)
    # the same tiles stacked twice: two leaf layers
    assert leaf_area_index(cards(tiles + [[x, y + 1, z] for x, y, z in tiles])) == pytest.approx(2.0)
    # two cards 2 m apart: 2 m² of leaves over a 4 m x 1 m crown (hull) or over 2 m² (union)
    apart = cards([[-1.5, 3, 0], [1.5, 3, 0]])
    assert leaf_area_index(apart) == pytest.approx(0.5)
    assert leaf_area_index(apart, footprint="union") == pytest.approx(1.0)
    # the skeleton widens the hull footprint: nodes spanning x in [-2, 6] make it 8 m x 1 m
    sk = skel([[-2, 0, -0.5], [-2, 1, 0.5], [6, 1, 0.5], [6, 1, -0.5]], [-1, 0, 1, 2])
    assert leaf_area_index(apart, sk) == pytest.approx(2.0 / 8.0)
    # texture coverage scales the leaf area
    assert leaf_area_index(cards(tiles), coverage=0.65) == pytest.approx(0.65)
    assert leaf_area_index(Foliage.empty()) == 0.0


def test_lai_counts_projected_area():
    # a card tilted 60° from horizontal projects to half its area; an upright card to none
    n60 = [0, np.cos(np.radians(60)), np.sin(np.radians(60))]
    f = cards([[0, 3, 0], [0, 4, 0], [0, 5, 0]], normals=[[0, 1, 0], n60, [1, 0, 0]],
              up=[[0, 0, 1], [0, -n60[2], n60[1]], [0, 1, 0]], size=1.0)
    m = tree_metrics(skel([[0, 0, 0], [0, 5, 0]], [-1, 0]), f, lai_cell=0.005)
    assert m["projected_leaf_area_m2"] == pytest.approx(1.5, rel=0.01)
    assert m["crown_projection_area_m2"] == pytest.approx(1.0, rel=0.01)
    assert m["leaf_area_index"] == pytest.approx(1.5, rel=0.02)


def test_lai_of_many_random_cards_matches_the_analytic_projected_area():
    rng = np.random.default_rng(0)
    m = 2000
    n = rng.normal(size=(m, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    up = rng.normal(size=(m, 3))
    size = rng.uniform(0.2, 0.5, m)
    f = Foliage(rng.normal(size=(m, 3)) * [2, 1, 2] + [0, 5, 0], n, up - (up * n).sum(1, keepdims=True) * n, size,
                np.full((m, 3), 0.5))
    res = tree_metrics(skel([[0, 0, 0], [0, 5, 0]], [-1, 0]), f)
    assert res["projected_leaf_area_m2"] == pytest.approx(np.sum(size ** 2 * np.abs(n[:, 1])), rel=0.005)


def test_lai_of_triangles_and_errors():
    tri = np.array([[[0, 1, 0], [1, 1, 0], [1, 1, 1]], [[0, 1, 0], [1, 1, 1], [0, 1, 1]]], float)
    assert leaf_area_index_triangles(tri) == pytest.approx(1.0)
    assert leaf_area_index_triangles(np.concatenate([tri, tri[:, ::-1]])) == pytest.approx(2.0)  # either winding
    assert leaf_area_index_triangles(np.zeros((0, 3, 3))) == 0.0
    with pytest.raises(InputError, match="triangles"):
        leaf_area_index_triangles(np.zeros((2, 3)))
    with pytest.raises(InputError, match="footprint"):
        leaf_area_index(cards([[0, 1, 0]]), footprint="disk")
    with pytest.raises(InputError, match="coverage"):
        leaf_area_index(cards([[0, 1, 0]]), coverage=0)
    with pytest.raises(InputError, match="cell"):
        leaf_area_index(cards([[0, 1, 0]]), cell=-1)
    with pytest.raises(InputError, match="foliage"):
        leaf_area_index(np.zeros((3, 3)))


# --------------------------------------------------------------------------- summaries
def test_metric_vector_and_tree_metrics():
    s = y_tree()
    f = cards([[0.5, 2.2, 0], [-0.5, 2.1, 0]], size=0.5)
    v = metric_vector(s, f)
    assert v.shape == (10,) and v.dtype == np.float64 and np.all(np.isfinite(v))
    assert len(METRIC_NAMES) == 10 and METRIC_NAMES[:5] == ("branching_angle_deg", "tree_height_m", "trunk_diameter_m",
                                                            "leaf_area_index", "biomass_m3")
    m = tree_metrics(s, f)
    np.testing.assert_allclose(v, [m["branching_angle_deg"], m["tree_height_m"], m["trunk_diameter_m"],
                                   m["leaf_area_index"], m["biomass_m3"], *m["mrt_m"]])
    assert v[0] == pytest.approx(45.0) and v[2] == pytest.approx(0.4)
    assert m["n_leaves"] == 2 and m["n_branching_points"] == 1 and m["n_nodes"] == 4
    assert m["max_radial_extent_m"] == pytest.approx(1.0) and m["crown_extent_x_m"] == pytest.approx(1.0)
    # without foliage the LAI is unknown (NaN), everything else is there
    v0 = metric_vector(s)
    assert np.isnan(v0[3]) and np.all(np.isfinite(np.delete(v0, 3)))
    with pytest.raises(InputError, match="skeleton"):
        metric_vector(np.zeros((3, 3)))


def test_mesh_metrics():
    verts = np.array([[-1, 0, -2], [1, 0, 0], [0, 3, 2], [0.5, 1, 0]], float)
    m = mesh_metrics(verts)
    assert m["tree_height_m"] == 3.0 and m["crown_extent_x_m"] == 2.0 and m["crown_extent_z_m"] == 4.0
    assert m["max_radial_extent_m"] == pytest.approx(np.hypot(1, 2)) and np.isnan(m["leaf_area_index"])
    with pytest.raises(InputError, match="positions"):
        mesh_metrics(np.zeros((0, 3)))
