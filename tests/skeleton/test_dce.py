import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.skeleton import dce
from treeform.skeleton.dce import inward_vertices, outer_contour


def _noisy_square(seed=0, side=100.0, per_side=25, noise=0.8):
    rng = np.random.default_rng(seed)
    t = np.linspace(0, 1, per_side, endpoint=False)
    corners = np.array([[0, 0], [side, 0], [side, side], [0, side]], float)
    pts, corner_idx = [], []
    for k in range(4):
        a, b = corners[k], corners[(k + 1) % 4]
        edge = a + t[:, None] * (b - a)
        edge[1:] += rng.normal(0, noise, (per_side - 1, 2))  # collinear-ish points with noise
        corner_idx.append(len(pts))
        pts.extend(edge)
    return np.array(pts), corner_idx


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_dce_of_noisy_square_keeps_the_corners(seed):
    poly, corners = _noisy_square(seed)
    assert dce(poly, 4).tolist() == corners


def test_dce_collinear_points_go_first_and_count_is_kept():
    poly, corners = _noisy_square(0, noise=0.0)
    keep = dce(poly, 4)
    assert keep.tolist() == corners
    for n in (3, 5, 10, 37, len(poly) - 1, len(poly), len(poly) + 5):
        k = dce(poly, n)
        assert len(k) == min(n, len(poly))
        assert np.all(np.diff(k) > 0)


def test_dce_on_a_contour_finds_the_notch():
    # a "U" shape: the inward vertices of its 8-vertex DCE polygon are the two inner corners
    m = np.zeros((60, 60), bool)
    m[10:50, 10:50] = True
    m[10:35, 25:35] = False
    poly = outer_contour(m)
    p8 = poly[dce(poly, 8)]
    idx, alpha = inward_vertices(p8)
    assert len(idx) == 2
    assert np.allclose(alpha, np.pi / 2, atol=0.2)
    assert np.all(p8[idx, 1] > 30)  # the bottom of the notch


@pytest.mark.parametrize("poly, n, match", [
    (np.zeros((2, 2)), 3, "polygon"),
    (np.zeros((5, 3)), 3, "polygon"),
    (np.zeros((5, 2)), 2, "n_vertices"),
    (np.zeros((5, 2)), 3.5, "n_vertices"),
    (np.array([[0, 0], [1, np.nan], [2, 0]]), 3, "polygon"),
])
def test_dce_bad_input(poly, n, match):
    with pytest.raises(InputError, match=match):
        dce(poly, n)
