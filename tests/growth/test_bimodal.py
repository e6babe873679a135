"""Bi-modal growth (seed 003 §4.3–4.4): RBV containment and fill, mask fidelity, orientation."""

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.growth.bimodal import (bimodal_grow, clamp_into, half_centroid, local_thickness, mask_markers,
                                     orient_scaffold, planar_scaffold, resample_scaffold)
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


def _own_mask(species, seed=1):
    from treeform.geometry.tubes import branch_mesh
    from treeform._shared.errors import RenderError
    from treeform.render import Renderer

    p = load_species(species)
    gt = grow(p, seed=seed)
    rbv = RadialBoundingVolume.from_skeleton(gt, level=5)
    h = rbv.physical_height
    cam = _front_camera(h)
    px = 1.2 * h / 512
    try:
        mask = Renderer(cam, samples=1).render(Mesh([branch_mesh(gt, radial_segments=6, min_radius=px)])).mask
    except RenderError:
        pytest.skip("no OpenGL context")
    base = cam.project(np.zeros((1, 3)))[0]
    return p, gt, rbv, cam, mask, (base[0], base[1])


@pytest.mark.parametrize("species", ["maple", "acacia"])
def test_default_growth_from_own_rbv_and_mask_matches_the_original(species):
    from treeform.growth.species import load_marker_density, load_perception_angle
    from treeform.metrics import average_branching_angle, biomass

    p, gt, rbv, cam, mask, base = _own_mask(species)
    target = rbv.at_level(4)
    kw = dict(mask=mask, seed=2, mask_scale=cam.position[2] / cam.focal, mask_base=base,
              perception_angle=load_perception_angle(species), marker_density=load_marker_density(species))
    rec = bimodal_grow(p, target, **kw)
    k = rec.meta["n_scaffold"]
    assert target.contains(rec.positions[1:k]).mean() > 0.99  # the scaffold stays inside
    got = RadialBoundingVolume.from_points(np.maximum(rec.positions, [-np.inf, 0, -np.inf]), level=4)
    assert got.physical_radii.mean() >= 0.9 * target.physical_radii.mean()  # fills the volume
    assert 0.7 <= average_branching_angle(rec) / average_branching_angle(gt) <= 1.3
    assert 0.7 <= biomass(rec) / biomass(gt) <= 1.3
    alone = bimodal_grow(p, target, **{**kw, "marker_density": 0})  # the mask's plane alone fills less
    got0 = RadialBoundingVolume.from_points(np.maximum(alone.positions, [-np.inf, 0, -np.inf]), level=4)
    assert got0.physical_radii.mean() < got.physical_radii.mean()


def test_a_wide_trunk_is_one_tube_not_a_rope():
    # a trunk 11 px wide forking into two limbs 5 px wide: one scaffold chain per branch,
    # with the mask's half-widths (was: parallel 1-px strands, a rope)
    m = np.zeros((200, 160), bool)
    m[100:200, 75:86] = True
    for t in np.linspace(0, 1, 200):
        for side in (-1, 1):
            c, r = 80 + side * 55 * t, 100 - 90 * t
            m[int(r) - 2: int(r) + 3, int(c) - 2: int(c) + 3] = True
    pts, frame = mask_markers(m, scale=0.01, base=(80.5, 200.0))
    thick = local_thickness(m)[m]
    assert abs(np.median(thick[pts[:, 1] < 0.9]) - 6.0) <= 0.6  # (11 + 1) / 2 on the trunk
    sk = planar_scaffold(pts, segment_length=0.01, kill_distance=np.maximum(0.015, (thick + 0.5) * 0.01),
                         perception_angle=90.0, root=np.zeros(3))
    low = 0.2  # 20 px up the trunk
    p, q = sk.positions[1:], sk.positions[sk.parent[1:]]
    crossing = ((p[:, 1] - low) * (q[:, 1] - low) <= 0) & (p[:, 1] != q[:, 1])
    assert crossing.sum() == 1
    tips = sk.tips()
    top = sk.positions[tips][sk.positions[tips, 1] > 1.5]
    assert (top[:, 0] < -0.4).any() and (top[:, 0] > 0.4).any()  # both limbs reach their ends


@pytest.mark.parametrize("species", ["maple", "oak"])
def test_mask_growth_reproduces_the_branch_mask(species):
    from treeform.geometry.tubes import branch_mesh
    from treeform.render import Renderer

    p, gt, rbv, cam, mask, base = _own_mask(species)
    # the tracing stage alone: the planar scaffold at pixel spacing, one crown year, not turned
    rec = bimodal_grow(p, rbv.at_level(4), mask=mask, seed=2, mask_scale=cam.position[2] / cam.focal,
                       mask_base=(base[0], base[1]), orient=False, clamp=False, crown_years=1,
                       spacing=cam.position[2] / cam.focal, marker_density=0)
    wood = Renderer(cam, samples=1).render(Mesh([branch_mesh(rec, radial_segments=6)])).mask
    iou = (mask & wood).sum() / (mask | wood).sum()
    assert iou >= 0.6, iou
    assert rec.meta["n_scaffold"] > 100


def test_orientation_rotates_branches_toward_fuller_sectors():
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
    np.testing.assert_allclose(out.positions[:, 1], pos[:, 1])  # heights unchanged
    # a rotation about the branching point: horizontal distances from it are kept
    d0 = np.hypot(pos[[3, 4, 5, 6], 0] - 0, pos[[3, 4, 5, 6], 2])
    d1 = np.hypot(out.positions[[3, 4, 5, 6], 0], out.positions[[3, 4, 5, 6], 2])
    np.testing.assert_allclose(d1, d0)
    ang_r = np.degrees(np.arctan2(out.positions[4, 2], out.positions[4, 0]))
    ang_l = np.degrees(np.arctan2(out.positions[6, 2], out.positions[6, 0])) % 360
    assert 45 <= ang_r <= 90  # toward the centre of the full +x+z sector
    assert 180 <= ang_l <= 225  # toward the only sector of the left half
    np.testing.assert_allclose(out.positions[[7, 8, 9]], pos[[7, 8, 9]])  # the main stem stays


def test_resample_and_clamp():
    n = 41
    pos = np.zeros((n, 3))
    pos[:, 1] = np.linspace(0, 4, n)  # a 4 m stem, 0.1 m apart
    sk = TreeSkeleton(pos, np.arange(n) - 1)
    out, kept = resample_scaffold(sk, 0.5)
    assert kept[0] == 0 and kept[-1] == n - 1 and len(kept) == 9
    assert np.allclose(np.diff(out.positions[:, 1]), 0.5)
    rbv = RadialBoundingVolume(np.full((4, 4), 1.0), 4.0)
    p = clamp_into(rbv, np.array([[3.0, 1.0, 0.0], [0.5, 1.0, 0.0], [0, 9.0, 0]]))
    assert np.isclose(np.hypot(p[0, 0], p[0, 2]), 0.98) and np.allclose(p[1], [0.5, 1, 0]) and p[2, 1] == 4.0


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


def test_a_branch_mask_out_of_reach_of_the_base_is_ignored_not_a_bare_stump():
    # wood pixels only high in the crown, the trunk hidden: the mask's scaffold cannot leave
    # the base, so the tree grows from the volume alone (was: a one-node tree, empty mesh)
    p, gt, rbv, cam, mask, base = _own_mask("maple")
    far = np.zeros_like(mask)
    far[: mask.shape[0] // 4, mask.shape[1] // 3: mask.shape[1] // 3 + 3] = True
    target = rbv.at_level(4)
    rec = bimodal_grow(p, target, mask=far, seed=2, mask_scale=cam.position[2] / cam.focal, mask_base=base)
    free = bimodal_grow(p, target, seed=2)
    assert "branch mask ignored" in rec.meta["mask_note"]
    assert rec.n_nodes > 100 and rec.n_nodes == free.n_nodes


def test_the_bole_keeps_one_stem_where_only_the_trunks_foot_shows():
    # a crown down to the ground and only the trunk's foot in the wood mask (leaves hide the rest): the
    # volume's limbs sprouted from the foot's top, 3 % up, and crossed the 5 % plane as a bush of stems
    from treeform.metrics.treeform_metrics import stems_at

    p = load_species("oak")
    rbv = RadialBoundingVolume(np.full((8, 8), 3.0), 10.0)
    mask = np.zeros((200, 160), bool)
    mask[194:200, 76:84] = True  # 5 cm pixels: 0.3 m of a 0.4 m trunk
    kw = dict(mask=mask, mask_scale=0.05, mask_base=(80.0, 200.0), seed=1)
    bush = bimodal_grow(p, rbv, **kw)
    tree = bimodal_grow(p, rbv, bole=0.1, **kw)
    assert stems_at(bush, fraction=0.05) > 3
    assert stems_at(tree, fraction=0.05) == 1
    low = tree.positions[:, 1] < 0.99  # below the bole (1 m): the stem alone, straight up from the base
    assert np.abs(tree.positions[low][:, [0, 2]]).max() < 0.1
    with pytest.raises(InputError, match="bole"):
        bimodal_grow(p, rbv, bole=0.9, **kw)


def test_the_stem_follows_the_photos_trunk_as_one_tube():
    # a leaning trunk 10 px (0.5 m) wide up to 40 % of the height, then two limbs; the trunk's traced centre
    # line is the stem: one tube of the trunk's width along it, the limbs from its top
    from treeform.metrics.treeform_metrics import stems_at

    p = load_species("oak")
    radii = np.full((8, 8), 3.0)
    radii[:3] = 0.6
    rbv = RadialBoundingVolume(radii, 10.0)
    mask = np.zeros((200, 160), bool)
    rows = np.arange(120, 200)
    centre = 80 - (200 - rows) * 10 / 80  # leans 10 px (0.5 m) to the left over 4 m
    for r, c in zip(rows, centre):
        mask[r, int(round(c)) - 5:int(round(c)) + 5] = True
    for k in range(60):
        mask[120 - k, 70 - k:72 - k] = True
        mask[120 - k, 68 + k:70 + k] = True
    path = np.array([[80.0, 200.0], [70.0, 120.0]])
    sk = bimodal_grow(p, rbv, mask=mask, mask_scale=0.05, mask_base=(80.0, 200.0), seed=1, bole=0.1,
                      trunk_path=path, orient=False)
    stem = (sk.order == 0) & (sk.positions[:, 1] < 3.9)
    y, x = sk.positions[stem, 1], sk.positions[stem, 0]
    assert len(y) >= 4 and np.allclose(x, -0.5 * y / 4.0, atol=0.05)  # on the traced line
    assert np.all((sk.radius[stem] > 0.17) & (sk.radius[stem] < 0.26))  # the trunk's half-width, tapering
    assert np.all(np.diff(sk.radius[stem][np.argsort(y)]) <= 1e-9)
    assert stems_at(sk, fraction=0.05) == stems_at(sk, fraction=0.2) == 1
