import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.crown.envelope import bilaplacian_solve, inflate_envelope, side_profile, silhouette_sets
from treeform.crown.relief import relief_map


def _disc(r=40, pad=10):
    yy, xx = np.mgrid[: 2 * r + 2 * pad, : 2 * r + 2 * pad]
    return (yy - r - pad + 0.5) ** 2 + (xx - r - pad + 0.5) ** 2 < r * r


def test_silhouette_is_8_connected_ring():
    m = _disc(20)
    inner, sil, outer = silhouette_sets(m)
    assert not (inner & sil).any() and not (sil & outer).any() and not (m & outer).any()
    assert np.array_equal(inner | sil, m)
    # every silhouette pixel has an outside 8-neighbour
    import scipy.ndimage as ndi

    assert np.array_equal(sil, m & ndi.binary_dilation(~m, np.ones((3, 3), bool)))


def test_bilaplacian_reproduces_linear_and_quadratic_fields():
    # the 13-point stencil annihilates polynomials of degree <= 3: solving with such a
    # field as boundary data must give the field back exactly (a discretisation check)
    h, w = 30, 34
    yy, xx = np.mgrid[:h, :w].astype(float)
    field = 0.3 * xx - 0.2 * yy + 0.01 * xx * yy + 0.002 * xx**2 - 0.0005 * yy**3
    unknown = np.zeros((h, w), bool)
    unknown[2:-2, 2:-2] = True
    sol = bilaplacian_solve(unknown, field)
    np.testing.assert_allclose(sol[..., 0], field, atol=1e-8)


def test_bilaplacian_needs_known_border():
    with pytest.raises(InputError):
        bilaplacian_solve(np.ones((5, 5), bool), np.zeros((5, 5)))


def test_disc_inflates_to_a_round_closed_crown():
    m = _disc(40)
    env = inflate_envelope(m, grid_size=80)
    z = env.vertices[:, 2]
    depth = z.max() - z.min()
    width = env.vertices[:, 0].max() - env.vertices[:, 0].min()
    assert 0.8 < depth / width < 1.2
    # front and back halves mirror each other
    assert np.isclose(z.max(), -z.min())
    # closed, consistently oriented surface: every edge used exactly twice
    f = env.faces
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    assert np.all(counts == 2)
    # silhouette stays on the input outline: x/y of the front vertices inside the disc (+1 px)
    r = np.hypot(env.vertices[:, 0] - 49.5, env.vertices[:, 1] - 49.5)
    assert r.max() < 41.0
    # the tangent constraint keeps the rim steep: 2 px inside the rim the depth is far above a
    # paraboloid's (1 - (38/40)^2 = 0.0975 of the centre height)
    assert env.front_z[50, 12] > 0.18 * env.front_z[50, 50]


def test_conical_tangent_makes_bottom_fuller_than_top():
    m = _disc(40)
    env = inflate_envelope(m, crown="conical", grid_size=80)
    assert env.front_z[25, 50] < env.front_z[75, 50]
    with pytest.raises(InputError):
        inflate_envelope(m, crown="square")


def test_relief_brighter_is_higher_and_normalised():
    rng = np.random.default_rng(0)
    img = np.zeros((64, 64, 3), np.uint8)
    img[:, 32:] = 180
    img = np.clip(img + rng.integers(0, 30, img.shape), 0, 255).astype(np.uint8)
    m = np.ones((64, 64), bool)
    h = relief_map(img, m, levels=5)
    assert h.min() >= 0 and h.max() <= 1 and h.max() - h.min() > 0.9
    assert h[:, 40:].mean() > h[:, :24].mean() + 0.3


def _diamond(r=40):
    """A rhombus 2r tall, 1.6r wide (not at 45°: a 45° staircase outline inflates flat)."""
    yy, xx = np.mgrid[: 2 * r + 20, : 2 * r + 20]
    return 0.8 * np.abs(yy - r - 10) + np.abs(xx - r - 10) < 0.8 * r


def _side_depth(env):
    """Half-depth of the envelope per input row (its side silhouette), from the vertices."""
    v = env.vertices
    rows = np.round(v[:, 1]).astype(int)
    out = np.zeros(rows.max() + 1)
    np.maximum.at(out, rows, v[:, 2])
    return out


def test_rounded_profile_has_no_ridge_where_the_front_is_widest():
    m = _diamond()
    thin = _side_depth(inflate_envelope(m, k=None, grid_size=80))
    rnd = _side_depth(inflate_envelope(m, k=None, grid_size=80, profile="rounded"))
    mid = 50
    # both as deep at the widest row (depth = width) ...
    assert abs(rnd[mid] - thin[mid]) < 0.1 * thin[mid]
    # ... but the rounded one stays full away from it (a diamond from the side would halve
    # at half the height): a crown, not a ridge
    assert rnd[mid - 20] > 0.6 * rnd[mid] and thin[mid - 20] < rnd[mid - 20] - 0.1 * rnd[mid]
    # still tapering to the top and bottom, and smooth (no kink at the widest row)
    assert rnd[mid - 38] < 0.6 * rnd[mid] and rnd[mid + 38] < 0.6 * rnd[mid]
    second = np.abs(np.diff(rnd[mid - 30:mid + 31], 2))
    assert second.max() < 0.2 * rnd[mid] / 10


def test_side_profile_follows_the_hull_for_conical_crowns():
    m = _diamond()
    hull = side_profile(m, crown="conical")
    rnd = side_profile(m)
    assert np.isclose(hull.max(), 31.5, atol=1.0)
    core = slice(20, 81)  # the rounded blend is fuller than the straight flanks, except at the very ends
    assert (rnd[core] >= hull[core] - 0.05 * hull.max()).all() and rnd[30] > hull[30] + 3
    assert rnd[0] == 0 and hull[0] == 0  # no crown, no depth
    with pytest.raises(InputError):
        inflate_envelope(m, profile="blob")
