"""Bi-modal growth (seed 003 §4.3–4.4): RBV containment and fill, mask fidelity, orientation."""

import numpy as np
import pytest

from treeform.growth.bimodal import bimodal_grow, half_centroid, mask_markers, orient_scaffold
from treeform.growth.phenomenological import grow
from treeform.growth.species import load_species
from treeform.structures import Camera, Mesh, RadialBoundingVolume, TreeSkeleton


@pytest.mark.parametrize("species", ["oak", "pine", "willow"])
def test_grown_tree_lies_inside_its_own_rbv(species):
    sk = grow(load_species(species), seed=3)
    for level in (3, 4, 5):
        assert RadialBoundingVolume.from_skeleton(sk, level=level).contains(sk.positions).all()


def test_growth_inside_a_target_rbv_fills_it():
    p = load_species("oak")
    target = RadialBoundingVolume.from_skeleton(grow(p, seed=1), level=4)
    rec = bimodal_grow(p, target, seed=2)
    assert target.contains(rec.positions).mean() > 0.99
    got = RadialBoundingVolume.from_skeleton(rec, level=4)
    ok = target.physical_radii > 0
    fill = np.minimum(got.physical_radii[ok] / target.physical_radii[ok], 1.0)
    assert fill.mean() >= 0.8, fill.mean()
    again = bimodal_grow(p, target, seed=2)
    assert np.array_equal(rec.positions, again.positions)


def _front_camera(h, size=512):
    dist = 1000 * h
    return Camera(size, size, 2 * np.degrees(np.arctan(0.6 * h / dist)), (0, h / 2, dist), (0, h / 2, 0),
                  near=dist - 3 * h, far=dist + 3 * h)


@pytest.mark.parametrize("species", ["maple", "oak"])
def test_mask_growth_reproduces_the_branch_mask(species):
    from treeform.geometry.tubes import branch_mesh
    from treeform._shared.errors import RenderError
    from treeform.render import Renderer

    p = load_species(species)
    gt = grow(p, seed=1)
    rbv = RadialBoundingVolume.from_skeleton(gt, level=5)
    h = rbv.physical_height
    cam = _front_camera(h)
    px = 1.2 * h / 512
    try:
        # the branch mask a photo would show: the main branches, at least ~2 px wide
        mask = Renderer(cam, samples=1).render(Mesh([branch_mesh(gt, radial_segments=6, min_radius=px)])).mask
    except RenderError:
        pytest.skip("no OpenGL context")
    base = cam.project(np.zeros((1, 3)))[0]
    rec = bimodal_grow(p, rbv.at_level(4), mask=mask, seed=2, mask_scale=cam.position[2] / cam.focal,
                       mask_base=(base[0], base[1]))
    wood = Renderer(cam, samples=1).render(Mesh([branch_mesh(rec, radial_segments=6)])).mask
    iou = (mask & wood).sum() / (mask | wood).sum()
    assert iou >= 0.6, iou
    assert rec.meta["n_scaffold"] > 100


def test_orientation_keeps_the_front_projection_and_turns_toward_fuller_sectors():
    # a planar tree: a trunk continuing up, one branch to +x and one to -x from node 2
    pos = np.array([[0, 0, 0], [0, 1, 0], [0, 2, 0], [1, 2.5, 0], [2, 3, 0], [-1, 2.5, 0], [-2, 3, 0.0],
                    [0, 2.6, 0], [0, 3.2, 0], [0, 3.4, 0.0]])
    parent = np.array([-1, 0, 1, 2, 3, 2, 5, 2, 7, 8])
    sk = TreeSkeleton(pos, parent)
    # RBV whose right half extends toward +z (sectors 0..3 of 8 run from +x toward +z)
    radii = np.zeros((8, 8))
    radii[:, 1] = 3.0  # the +x+z sector is the fullest on the right
    radii[:, 4] = 3.0  # the -x sector on the left
    rbv = RadialBoundingVolume(radii, 3.5)
    out = orient_scaffold(sk, rbv)
    np.testing.assert_allclose(out.positions[:, :2], pos[:, :2])  # front view unchanged
    assert out.positions[4, 2] > 0.5  # right branch now reaches toward +z
    assert out.positions[6, 2] < -0.5  # left branch: its half's only sector lies toward -x-z


def test_half_centroid_of_a_round_layer():
    rbv = RadialBoundingVolume(np.full((16, 16), 2.0), 1.0)
    left, right = half_centroid(rbv, 0, -1), half_centroid(rbv, 0, 1)
    # centroid of a half disc: 4 r / (3 pi) from the centre (sector wedges approximate it)
    assert left[0] == pytest.approx(-4 * 2 / (3 * np.pi), rel=0.03) and abs(left[1]) < 1e-9
    assert right[0] == pytest.approx(4 * 2 / (3 * np.pi), rel=0.03)


def test_mask_markers_frame():
    m = np.zeros((20, 10), bool)
    m[5:20, 4:6] = True
    pts, frame = mask_markers(m, height=7.0)
    assert len(pts) == m.sum() and np.isclose(pts[:, 1].max(), 7.0) and np.isclose(pts[:, 1].min(), 0.0)
    np.testing.assert_allclose(frame.to_pixels(frame.to_world([4.0], [10.0])), [[4.0, 10.0]])
