"""Chord-length resampling between pins (seed 000 §4.5)."""

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.contour import (
    PinPoints,
    longest_exterior_contour,
    pin_points,
    resample_contour,
    resample_polyline,
    segment_counts,
)


def test_polyline_uniform_arc_length():
    p = resample_polyline([[0, 0], [10, 0], [10, 10]], 20)
    d = np.hypot(*np.diff(p, axis=0).T)
    assert np.allclose(d, 1.0)
    assert resample_polyline([[2, 3], [2, 3]], 3).tolist() == [[2, 3]] * 3


def test_resampled_contour_layout():
    m = np.zeros((100, 80), bool)
    yy, xx = np.mgrid[:100, :80]
    m |= (xx - 40) ** 2 + (yy - 35) ** 2 < 28 ** 2
    m[50:95, 37:44] = True
    c = longest_exterior_contour(m)
    pins = pin_points(c, baseline=62.0)
    cr = resample_contour(c, pins, counts=(200, 1600, 200))
    assert cr.shape == (2000, 2)
    assert np.array_equal(cr[0], c[pins.b])  # first point = bottom pin B
    assert np.array_equal(cr[200], c[pins.r])
    assert np.array_equal(cr[1800], c[pins.l])
    crown = np.hypot(*np.diff(cr[200:1800], axis=0).T)
    assert crown.std() < 0.05 * crown.mean() + 0.05  # uniform by chord length


def test_no_trunk_collapses_the_trunk_segments():
    c = np.array([[0, 0], [5, 0], [5, 5], [0, 5]], float)
    cr = resample_contour(c, PinPoints(2, 2, 2, 4), counts=(2, 8, 2))
    assert np.array_equal(cr[:2], [[5, 5]] * 2) and np.array_equal(cr[-2:], [[5, 5]] * 2)
    assert np.array_equal(cr[2], [5, 5])


def test_bad_counts():
    assert segment_counts(20) == (2, 16, 2)
    c = np.array([[0, 0], [5, 0], [5, 5], [0, 5]], float)
    with pytest.raises(InputError):
        resample_contour(c, PinPoints(0, 0, 0, 4), counts=(0, 8, 2))
    with pytest.raises(InputError):
        resample_contour(c, PinPoints(0, 0, 0, 5))
