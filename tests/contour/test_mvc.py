"""Mean value coordinates (Hormann & Floater 2006)."""

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.contour import mean_value_coordinates, mvc_map


def _star(m=20, r0=100.0, r1=40.0):
    t = np.linspace(0, 2 * np.pi, m, endpoint=False)
    r = np.where(np.arange(m) % 2 == 0, r0, r1)
    return np.column_stack([200 + r * np.cos(t), 200 + r * np.sin(t)])  # non-convex, not star-shaped from far


def test_reproduces_linear_functions_inside_and_outside():
    poly = _star()
    rng = np.random.default_rng(0)
    pts = rng.uniform(50, 350, size=(20000, 2))  # > one chunk; many points outside the polygon
    lam = mean_value_coordinates(pts, poly)
    assert np.allclose(lam.sum(1), 1.0, atol=1e-9)
    assert np.allclose(lam @ poly, pts, atol=1e-7)
    f = poly @ np.array([0.3, -1.7]) + 5.0  # any linear function
    assert np.allclose(lam @ f, pts @ np.array([0.3, -1.7]) + 5.0, atol=1e-6)


def test_lagrange_property_and_edges():
    poly = _star()
    assert np.allclose(mean_value_coordinates(poly, poly), np.eye(len(poly)))
    mid = 0.25 * poly[3] + 0.75 * poly[4]
    lam = mean_value_coordinates(mid, poly)[0]
    assert lam[3] == pytest.approx(0.25) and lam[4] == pytest.approx(0.75)


def test_target_vertices_map_onto_source_vertices():
    tgt = _star()
    src = np.stack([_star(r0=90, r1=50) + 7.0, _star(r0=120, r1=30)[::1] * 0.5])
    out = mvc_map(tgt, tgt, src)
    assert np.allclose(out, src, atol=1e-9)
    assert np.allclose(mvc_map(tgt[:3] * 0.999 + 0.2, tgt, tgt), tgt[:3] * 0.999 + 0.2, atol=1e-8)


def test_positive_inside_a_convex_polygon_and_bad_input():
    sq = np.array([[0, 0], [4, 0], [4, 4], [0, 4]], float)
    lam = mean_value_coordinates(np.random.default_rng(1).uniform(0.1, 3.9, (100, 2)), sq)
    assert (lam > 0).all()
    with pytest.raises(InputError):
        mean_value_coordinates([[0, 0]], sq[:2])
    with pytest.raises(InputError):
        mvc_map([[0, 0]], sq, sq[:3])
