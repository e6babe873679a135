import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.skeleton import force_field
from treeform.skeleton.field import contour_pixels


def _disc(n=61, r=27):
    yy, xx = np.mgrid[:n, :n]
    c = (n - 1) / 2
    return (xx - c) ** 2 + (yy - c) ** 2 <= r * r, c


def test_disc_field_points_to_centre_and_vanishes_there():
    mask, c = _disc()
    f = force_field(mask)
    yy, xx = np.mgrid[:mask.shape[0], :mask.shape[1]]
    r = np.hypot(xx - c, yy - c)
    ring = mask & (r > 5) & (r < 22)
    inward = np.stack([c - xx, c - yy], axis=-1) / np.maximum(r, 1e-9)[..., None]
    mag = np.hypot(f[..., 0], f[..., 1])
    cos = (f * inward).sum(-1)[ring] / mag[ring]
    assert cos.min() > 0.97
    # vanishes near the centre, grows toward the contour
    assert mag[int(c), int(c)] < 1e-9
    assert mag[(r < 3) & mask].max() < 0.15 * mag[(r > 15) & (r < 20) & mask].min()
    assert np.all(f[~mask] == 0)


def _brute(mask, prob):
    w = np.where(mask, prob, 0.0)
    w[contour_pixels(mask)] = 1.0
    sy, sx = np.nonzero(w)
    ws = w[sy, sx]
    out = np.zeros(mask.shape + (2,))
    for y, x in zip(*np.nonzero(mask)):
        dx, dy = x - sx, y - sy
        d3 = np.hypot(dx, dy) ** 3
        ok = d3 > 0
        out[y, x, 0] = np.sum(ws[ok] * dx[ok] / d3[ok])
        out[y, x, 1] = np.sum(ws[ok] * dy[ok] / d3[ok])
    return out


def test_fft_field_equals_brute_force_sum():
    rng = np.random.default_rng(3)
    yy, xx = np.mgrid[:14, :11]
    mask = ((xx - 5) ** 2 / 25 + (yy - 7) ** 2 / 36 <= 1) | ((yy > 9) & (xx < 4))
    prob = rng.random(mask.shape) * 0.8
    for p in (None, prob):
        f = force_field(mask, probability=p, max_side=64)
        ref = _brute(mask, np.zeros(mask.shape) if p is None else p)
        np.testing.assert_allclose(f, ref, atol=1e-9, rtol=1e-9)


def test_probability_line_repels_the_field():
    # a vertical artificial contour line at column 20 of a wide rectangle pushes points right of it to the right
    mask = np.zeros((40, 60), bool)
    mask[5:35, 5:55] = True
    p = np.zeros(mask.shape)
    p[5:35, 20] = 1.0
    f0 = force_field(mask)
    f1 = force_field(mask, probability=p)
    assert f1[20, 23, 0] > f0[20, 23, 0] + 0.3
    assert f1[20, 17, 0] < f0[20, 17, 0] - 0.3


def test_reduced_working_size_keeps_direction():
    mask, c = _disc(301, 130)
    f = force_field(mask, max_side=64)
    assert f.shape == (301, 301, 2)
    assert f[150, 240, 0] < 0 and abs(f[150, 240, 1]) < 0.1 * abs(f[150, 240, 0])
    assert f[60, 150, 1] > 0


def test_empty_mask_gives_zero_field():
    assert not force_field(np.zeros((5, 7), bool)).any()


@pytest.mark.parametrize("kwargs, match", [
    ({"mask": np.zeros((3, 4, 2))}, "mask"),
    ({"mask": np.ones((4, 4)), "probability": np.ones((3, 3))}, "probability"),
    ({"mask": np.ones((4, 4)), "probability": np.full((4, 4), 2.0)}, "probability"),
    ({"mask": np.ones((4, 4)), "max_side": 2}, "max_side"),
])
def test_bad_input_raises(kwargs, match):
    mask = kwargs.pop("mask")
    with pytest.raises(InputError, match=match):
        force_field(mask, **kwargs)
