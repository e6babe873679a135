"""render_radial_cubemap: radii, face / texel layout shared with structures.rdm, rotations, values."""

from __future__ import annotations

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.render import render_radial_cubemap
from treeform.structures import RadialDistanceMap
from treeform.structures.rdm import texel_directions

C = np.array([0.3, 1.2, -0.4])


def far_hit(dirs: np.ndarray, origin, center, radius) -> np.ndarray:
    """Distance from ``origin`` along unit ``dirs`` to the far side of a sphere containing it."""
    oc = np.asarray(origin) - np.asarray(center)
    b = dirs @ oc
    return -b + np.sqrt(b * b - (oc @ oc - radius**2))


def test_sphere_about_its_centre_has_constant_radius(gl, meshes):
    pos, _, faces = meshes.sphere(C, 2.0, 64, 32)
    radii = render_radial_cubemap(pos, faces, C, resolution=64)
    assert radii.shape == (6, 64, 64) and radii.dtype == np.float32
    assert np.all(np.abs(radii - 2.0) <= 0.02 * 2.0)


def test_off_centre_sphere_matches_analytic_per_texel_and_contains(gl, meshes):
    s, radius = C + [0.5, -0.3, 0.2], 1.5  # C lies inside, the offsets break every symmetry
    pos, _, faces = meshes.sphere(s, radius, 96, 48)
    res = 48
    radii = render_radial_cubemap(pos, faces, C, resolution=res)
    # texel [f, row, col] holds the radius along texel_directions(res)[f, row, col]
    expect = far_hit(texel_directions(res).reshape(-1, 3), C, s, radius).reshape(6, res, res)
    assert np.all(np.abs(radii - expect) <= 0.02 * expect)
    rdm = RadialDistanceMap(C, radii)
    pts = np.random.default_rng(0).uniform(-1, 1, (20000, 3)) * 2.2 + s
    truth = np.linalg.norm(pts - s, axis=1) <= radius
    assert (rdm.contains(pts) == truth).mean() >= 0.99


def test_rotated_copies_keep_the_maximum(gl, meshes):
    pos, faces = meshes.box(C, lo=(-0.5, -0.4, -0.3), hi=(2.0, 0.4, 0.3), subdiv=6)
    res = 32
    single = render_radial_cubemap(pos, faces, C, resolution=res)
    both = render_radial_cubemap(pos, faces, C, resolution=res, rotations_deg=[90.0])
    # the same copy rotated in numpy: +90 deg about +Y (right-handed) maps +X to -Z
    a = np.radians(90.0)
    rot = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    turned = render_radial_cubemap((pos - C) @ rot.T + C, faces, C, resolution=res)
    assert np.allclose(both, np.maximum(single, turned), rtol=1e-5, atol=1e-6)
    rdm = RadialDistanceMap(C, both)
    far = rdm.lookup(np.array([[1.0, 0, 0], [0, 0, -1.0], [0, 0, 1.0], [-1.0, 0, 0]]))
    assert far[0] == pytest.approx(2.0, rel=0.02) and far[1] == pytest.approx(2.0, rel=0.02)
    assert far[2] == pytest.approx(0.5, rel=0.02) and far[3] == pytest.approx(0.5, rel=0.02)


def test_values_scale_the_radius(gl, meshes):
    pos, _, faces = meshes.sphere(C, 2.0, 64, 32)
    hi = render_radial_cubemap(pos, faces, C, values=np.ones(len(pos)), rho=0.5, resolution=16)
    lo = render_radial_cubemap(pos, faces, C, values=np.zeros(len(pos)), rho=0.5, resolution=16)
    assert np.all(np.abs(hi - 2.5) <= 0.05) and np.all(np.abs(lo - 1.5) <= 0.03)
    # values vary with height: upward texels (+Y face) get the larger factor
    h = (pos[:, 1] - pos[:, 1].min()) / np.ptp(pos[:, 1])
    var = render_radial_cubemap(pos, faces, C, values=h, rho=0.5, resolution=16)
    assert var[2].mean() > 2.3 and var[3].mean() < 1.7


def test_unreached_texels_are_zero(gl, meshes):
    # an open patch that only covers part of the +X face
    pos = np.array([[1.0, -0.2, -0.2], [1.0, -0.2, 0.2], [1.0, 0.2, 0.2], [1.0, 0.2, -0.2]]) + C
    radii = render_radial_cubemap(pos, [[0, 1, 2], [0, 2, 3]], C, resolution=20)
    assert np.all(radii[1:] == 0)
    d = texel_directions(20)[0]
    covered = (np.abs(d[..., 1] / d[..., 0]) < 0.2) & (np.abs(d[..., 2] / d[..., 0]) < 0.2)
    assert covered.sum() == 16 and np.array_equal(radii[0] > 0, covered)
    assert np.allclose(radii[0][covered], 1.0 / d[..., 0][covered], rtol=1e-5)
    assert not render_radial_cubemap(np.zeros((0, 3)), np.zeros((0, 3), int), C, resolution=4).any()


def test_odd_resolutions(gl, meshes):
    pos, _, faces = meshes.sphere(C, 1.0, 32, 16)
    for res in (1, 7):
        radii = render_radial_cubemap(pos, faces, C, resolution=res)
        assert radii.shape == (6, res, res) and np.all(np.abs(radii - 1) < 0.03)


def test_cubemap_bad_inputs():
    pos, faces = np.zeros((3, 3)), np.array([[0, 1, 2]])
    with pytest.raises(InputError, match="positions"):
        render_radial_cubemap(np.zeros((3, 2)), faces, (0, 0, 0))
    with pytest.raises(InputError, match="faces"):
        render_radial_cubemap(pos, [[0, 1, 5]], (0, 0, 0))
    with pytest.raises(InputError, match="center"):
        render_radial_cubemap(pos, faces, (0, 0))
    with pytest.raises(InputError, match="values"):
        render_radial_cubemap(pos, faces, (0, 0, 0), values=[0.0, 2.0, 0.5])
    with pytest.raises(InputError, match="resolution"):
        render_radial_cubemap(pos, faces, (0, 0, 0), resolution=0)
