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
