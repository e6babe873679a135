"""Pin points B, L, R (seed 000 §4.4)."""

import numpy as np

from treeform.contour import crown_baseline, longest_exterior_contour, pin_points


def _tree(trunk=True):
    m = np.zeros((100, 80), bool)
    yy, xx = np.mgrid[:100, :80]
    m |= (xx - 40) ** 2 + (yy - 35) ** 2 < 28 ** 2
    crown = m.copy()
    if trunk:
        m[50:95, 37:44] = True
    return m, crown


def test_pins_on_a_tree_with_a_trunk():
    m, crown = _tree()
    c = longest_exterior_contour(m)
    base = crown_baseline(crown & ~((np.arange(80) >= 37) & (np.arange(80) <= 43))[None, :] | crown)
    pins = pin_points(c, baseline=base)
    assert pins.has_trunk
    b, l, r = c[pins.b], c[pins.l], c[pins.r]
    assert b[1] == 94 and 37 <= b[0] <= 43
    assert l[1] <= base and r[1] <= base
    assert l[0] < b[0] < r[0]  # L on the left, R on the right
    assert sum(pins.segments()) == len(c)


def test_no_trunk_means_l_equals_r_equals_b():
    m, _ = _tree(trunk=False)
    c = longest_exterior_contour(m)
    pins = pin_points(c, baseline=None)
    assert pins.b == pins.l == pins.r and not pins.has_trunk
    # a baseline at (or below) the bottom: no trunk either
    assert not pin_points(c, baseline=float(c[:, 1].max())).has_trunk


def test_b_is_the_median_of_the_lowest_points():
    m = np.zeros((20, 30), bool)
    m[2:15, 5:26] = True
    c = longest_exterior_contour(m)
    pins = pin_points(c, baseline=None)
    assert c[pins.b].tolist() == [15.0, 14.0]


def test_crown_baseline_ignores_specks():
    m = np.zeros((50, 50), bool)
    m[5:20, 10:40] = True
    m[45, 25] = True
    assert crown_baseline(m) == 45
    assert crown_baseline(m, ignore=0.01) == 19
    assert crown_baseline(np.zeros((4, 4), bool)) is None
