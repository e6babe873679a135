"""The opacity grid of a tree mesh (issue 15 item 7): Beer-Lambert extinction per voxel, round trip, checks."""

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.geometry.opacity import CARD_SHADOW, SOLID_SHADOW, opacity_grid
from treeform.structures import Material, Mesh, MeshPart, OpacityGrid
from treeform.structures.opacity import HALF_COVERAGE


def _card(x0, size=1.0, texture=None, **mat):
    pos = np.array([[x0, 0, 0], [x0 + size, 0, 0], [x0 + size, size, 0], [x0, size, 0]], float)
    uv = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)
    return MeshPart(pos, np.tile([0.0, 0.0, 1.0], (4, 1)), uv, np.ones((4, 4)), np.array([[0, 1, 2], [0, 2, 3]]),
                    Material("leaf", texture=texture, **mat))


def _cube(center, edge):
    """A closed single-sided box of 12 triangles."""
    c = np.asarray(center, float)
    v = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float) * edge / 2 + c
    f = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                  [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return MeshPart(v, np.zeros_like(v), np.zeros((8, 2)), np.ones((8, 4)), f, Material("bark"))


def test_area_is_held_as_shadow_alpha_counted():
    tex = np.zeros((16, 16, 4), np.uint8)
    tex[..., 3] = 255
    tex[:, 8:, 3] = 0  # the right half of the leaf texture is transparent
    half = _card(0.0, texture=tex, alpha_mode="MASK", double_sided=True)
    whole = _card(2.0, double_sided=True)
    box = _cube((5.0, 0.5, 0.0), 1.0)
    pebble = _cube((5.0, 0.5, 0.0), 0.02)  # a solid much smaller than a voxel: its shadow is its area's quarter
    for parts, area in (([half], 0.5 * CARD_SHADOW), ([whole], 1.0 * CARD_SHADOW),
                        ([half, whole, pebble], 1.5 * CARD_SHADOW + 6 * 0.02 ** 2 * SOLID_SHADOW)):
        g = opacity_grid(Mesh(parts), resolution=24)
        assert g.sigma.sum() * g.voxel ** 3 == pytest.approx(area, rel=1e-3)
    # a solid's wall filling much of a voxel is one opaque element: more than its linear share (the ray through
    # the box's middle crosses two walls, each 1/4 of its area in the mean)
    g = opacity_grid(Mesh([half, whole, box]), resolution=24)
    assert g.sigma.sum() * g.voxel ** 3 > 1.5 * CARD_SHADOW + 6.0 * SOLID_SHADOW
    assert g.optical_depth(np.array([[5.0, 0.5, -3.0]]), np.array([[0.0, 0.0, 1.0]]))[0] > 2 * SOLID_SHADOW
    lo, hi = g.bounds()
    pts = np.concatenate([p.positions for p in (half, whole, box)])
    assert (pts.min(0) > lo).all() and (pts.max(0) < hi).all() and np.allclose(hi - lo, g.extent)
    # the transparent half of the first card holds nothing; its opaque half and the second card do
    assert g.sample(np.array([[0.25, 0.5, 0.0]]))[0] > 0 and g.sample(np.array([[0.85, 0.5, 0.0]]))[0] < 1e-6
    assert g.sample(np.array([[2.5, 0.5, 0.0]]))[0] > 0
    # deterministic
    assert np.array_equal(opacity_grid(Mesh([half, whole, box]), resolution=24).sigma, g.sigma)


def test_a_ray_across_a_stack_of_cards_loses_about_what_beer_lambert_says():
    """Many small opaque cards at random in a slab: the share of rays the grid calls blocked
    (optical depth >= ln 2) follows the share that really hit a card."""
    rng = np.random.default_rng(0)
    parts = []
    for _ in range(700):
        c = rng.uniform([0, 0, 0], [4, 4, 2])
        d1, d2 = np.linalg.qr(rng.normal(size=(3, 3)))[0][:, :2].T * 0.15
        pos = np.array([c - d1 - d2, c + d1 - d2, c + d1 + d2, c - d1 + d2])
        parts.append((pos, np.cross(d1, d2)))
    pos = np.concatenate([p for p, _ in parts])
    n = len(parts)
    q = 4 * np.arange(n)
    idx = np.concatenate([np.c_[q, q + 1, q + 2], np.c_[q, q + 2, q + 3]])
    mesh = Mesh([MeshPart(pos, np.zeros_like(pos), np.zeros((4 * n, 2)), np.ones((4 * n, 4)), idx,
                          Material("leaves", double_sided=True))])
    g = opacity_grid(mesh, resolution=16)
    # rays along z through the middle of the slab: coverage predicted from the grid against Beer-Lambert's mean
    xy = rng.uniform(1.0, 3.0, (400, 2))
    tau = g.optical_depth(np.c_[xy, np.full(400, -1.0)], np.tile([0.0, 0.0, 1.0], (400, 1)))
    area_density = n * (0.3 * 0.3) / (4 * 4 * 2)
    expected = CARD_SHADOW * area_density * 2.0  # optical depth across the slab's 2 m
    assert np.median(tau) == pytest.approx(expected, rel=0.25)
    assert HALF_COVERAGE == pytest.approx(np.log(2))


def test_round_trip_and_bad_input(tmp_path):
    g = OpacityGrid(np.arange(27, dtype=np.float32).reshape(3, 3, 3), np.array([1.0, 2.0, 3.0]), 0.5)
    back = OpacityGrid.load(g.save(tmp_path / "o.npz"))
    assert np.array_equal(back.sigma, g.sigma) and np.array_equal(back.origin, g.origin) and back.voxel == 0.5
    with pytest.raises(InputError, match="sigma"):
        OpacityGrid(np.zeros((2, 3, 3)), np.zeros(3), 1.0)
    with pytest.raises(InputError, match="sigma"):
        OpacityGrid(-np.ones((2, 2, 2)), np.zeros(3), 1.0)
    with pytest.raises(InputError, match="voxel"):
        OpacityGrid(np.zeros((2, 2, 2)), np.zeros(3), 0.0)
    with pytest.raises(InputError, match="mesh"):
        opacity_grid("not a mesh")
    with pytest.raises(InputError, match="resolution"):
        opacity_grid(Mesh([_card(0.0)]), resolution=1)
    with pytest.raises(InputError, match="no such file"):
        OpacityGrid.load(tmp_path / "missing.npz")
    np.savez(tmp_path / "other.npz", x=np.zeros(3))
    with pytest.raises(InputError, match="OpacityGrid"):
        OpacityGrid.load(tmp_path / "other.npz")


def _leaning_trunk(n=13, r0=0.08, r1=0.04):
    """A skeleton: a bent trunk 6 m tall tapering from ``r0`` to ``r1``, and a thin side twig."""
    from treeform.structures import TreeSkeleton

    y = np.linspace(0.0, 6.0, n)
    pos = np.c_[0.3 * np.sin(y / 2.0), y, 0.1 * y]
    pos = np.vstack([pos, pos[6] + [0.5, 0.3, 0.0]])
    parent = np.r_[-1, np.arange(n - 1), 6]
    radius = np.r_[np.linspace(r0, r1, n), 0.004]
    return TreeSkeleton(pos, parent, radius, np.r_[np.zeros(n), 1].astype(np.int32))


def test_wood_capsules_follow_the_trunk_and_drop_what_no_distance_shows():
    from treeform.geometry.opacity import WOOD_MIN_RADIUS, wood_capsules
    from treeform.structures.opacity import MAX_WOOD

    sk = _leaning_trunk()
    voxel = 0.2
    caps = wood_capsules(sk, voxel)
    assert caps.shape[1] == 7 and 1 <= len(caps) <= MAX_WOOD
    # one unbroken chain from the root to the top: each piece starts where the last ended
    assert np.allclose(caps[0, :3], sk.positions[0]) and np.allclose(caps[-1, 3:6], sk.positions[12], atol=1e-6)
    assert np.allclose(caps[1:, :3], caps[:-1, 3:6])
    # every trunk node lies within half a voxel of a piece; the radii are the nodes' own
    a, b = caps[:, None, :3].astype(float), caps[:, None, 3:6].astype(float)
    p = sk.positions[None, :13]
    t = np.clip(np.sum((p - a) * (b - a), -1) / np.sum((b - a) ** 2, -1), 0, 1)
    assert np.linalg.norm(p - (a + t[..., None] * (b - a)), axis=-1).min(0).max() <= 0.5 * voxel + 1e-6
    assert 0.04 <= caps[:, 6].min() and caps[:, 6].max() <= 0.08
    # the 4-mm twig is under a tenth of a voxel: it stays in the grid
    assert 0.004 < WOOD_MIN_RADIUS * voxel and len(wood_capsules(sk, voxel, max_capsules=MAX_WOOD)) == len(caps)
    assert len(wood_capsules(sk, voxel, max_capsules=2)) == 2
    assert len(wood_capsules(sk, 2.0)) == 0  # a voxel so large nothing is a tenth of it
    with pytest.raises(InputError, match="skeleton"):
        wood_capsules("trunk", voxel)
    with pytest.raises(InputError, match="voxel"):
        wood_capsules(sk, 0.0)


def test_grid_with_a_skeleton_holds_the_bark_as_capsules_not_as_sigma():
    """The bark the capsules stand for leaves sigma (a far trunk is counted once), the bark colour is the
    mesh's, and a ray across the trunk hits its capsule."""
    from treeform.geometry import branch_mesh
    from treeform.structures import Mesh

    sk = _leaning_trunk(r0=0.06, r1=0.03)
    bark = branch_mesh(sk, radial_segments=8)
    tex = np.zeros((8, 8, 4), np.uint8)
    tex[...] = (200, 100, 50, 255)
    bark.material = Material("bark", texture=tex)
    leaves = _card(-1.0, size=2.0, double_sided=True)
    leaves.positions = leaves.positions + [0.0, 5.0, 0.5]
    mesh = Mesh([bark, leaves])
    plain = opacity_grid(mesh, resolution=32)
    wood = opacity_grid(mesh, resolution=32, skeleton=sk)
    assert len(plain.wood) == 0 and len(wood.wood) >= 1
    assert np.allclose(wood.bark, np.array([200, 100, 50]) / 255, atol=0.01)
    # under the crown the trunk's share is gone but for the 4-mm twig; the leaves' is the same
    low = int((4.5 - plain.origin[1]) / plain.voxel)
    assert wood.sigma[:, :low].sum() < 0.05 * plain.sigma[:, :low].sum()
    high = int((4.95 - plain.origin[1]) / plain.voxel)
    assert np.isclose(wood.sigma[:, high:].sum(), plain.sigma[:, high:].sum(), rtol=0.1)
    o = np.array([[0.3 * np.sin(1.0), 2.0, -10.0]])
    assert np.isfinite(wood.wood_hit(o, np.array([[0.0, 0.0, 1.0]])))[0]
    assert not np.isfinite(wood.wood_hit(o + [1.0, 0, 0], np.array([[0.0, 0.0, 1.0]])))[0]


def test_capsule_hit_is_the_first_point_within_the_radius_of_the_segment():
    from treeform.structures.opacity import capsule_hit

    rng = np.random.default_rng(0)
    a, b, r = np.array([0.2, -0.5, 0.1]), np.array([-0.3, 1.2, 0.4]), 0.25
    o = rng.normal(size=(150, 3))
    o = 5.0 * o / np.linalg.norm(o, axis=1, keepdims=True)  # eyes 5 m from the origin, rays within 8 m
    aim = rng.normal(size=(150, 3)) * 0.6 + 0.5 * (a + b)
    d = (aim - o) / np.linalg.norm(aim - o, axis=1, keepdims=True)
    t = capsule_hit(o, d, a, b, r)
    ts = np.linspace(0, 8, 16001)
    p = o[:, None] + d[:, None] * ts[None, :, None]
    s = np.clip(((p - a) @ (b - a)) / ((b - a) @ (b - a)), 0, 1)
    inside = np.linalg.norm(p - (a + s[..., None] * (b - a)), axis=-1) <= r
    first = np.where(inside.any(1), ts[np.argmax(inside, axis=1)], np.inf)
    assert 20 < np.isfinite(first).sum() < 140  # hits and misses both
    assert np.array_equal(np.isfinite(t), np.isfinite(first))
    hit = np.isfinite(t)
    assert np.abs(t[hit] - first[hit]).max() < 1e-3
    # far away and along the axis (single precision in the shader: solved near the capsule)
    far = capsule_hit(np.array([[0.0, 2000.0, 0.0]]), np.array([[0.0, -1.0, 0.0]]), np.zeros(3), np.array([0, 1.0, 0]),
                      0.1)
    assert abs(far[0] - 1998.9) < 1e-6
    up = capsule_hit(np.array([[0.0, -10.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]), np.zeros(3), np.array([0, 1.0, 0]),
                     0.1)
    assert abs(up[0] - 9.9) < 1e-9


def test_round_trip_keeps_the_capsules_and_reads_grids_without_them(tmp_path):
    w = np.array([[0, 0, 0, 0, 2, 0, 0.1]], np.float32)
    g = OpacityGrid(np.zeros((2, 2, 2), np.float32), np.zeros(3), 0.5, w, np.array([0.5, 0.4, 0.3]))
    back = OpacityGrid.load(g.save(tmp_path / "w.npz"))
    assert np.array_equal(back.wood, w) and np.allclose(back.bark, [0.5, 0.4, 0.3])
    np.savez(tmp_path / "old.npz", __kind__="OpacityGrid", sigma=np.zeros((2, 2, 2), np.float32), origin=np.zeros(3),
             voxel=np.float64(0.5))
    assert len(OpacityGrid.load(tmp_path / "old.npz").wood) == 0
    with pytest.raises(InputError, match="wood"):
        OpacityGrid(np.zeros((2, 2, 2)), np.zeros(3), 0.5, np.zeros((3, 6)))
    with pytest.raises(InputError, match="wood"):
        OpacityGrid(np.zeros((2, 2, 2)), np.zeros(3), 0.5, np.zeros((1, 7)))  # radius 0
    with pytest.raises(InputError, match="bark"):
        OpacityGrid(np.zeros((2, 2, 2)), np.zeros(3), 0.5, None, np.array([2.0, 0, 0]))
