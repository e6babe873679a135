"""Region fill robust to self-intersections (§5.1) and the simplified contour Cs (§4.6)."""

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.contour import fill_contour, longest_exterior_contour, pin_points, resample_contour, simplify_contour


def test_self_intersecting_contour_leaves_no_holes():
    # a loop that crosses itself: even-odd filling would leave the overlap empty
    t = np.linspace(0, 2 * np.pi, 400, endpoint=False)
    pts = np.column_stack([50 + 30 * np.cos(t) + 15 * np.cos(2 * t), 50 + 30 * np.sin(t)])
    twice = np.vstack([pts, pts[::-1] * 0.7 + 15])  # a second loop through the first
    m = fill_contour(twice, (100, 100))
    assert m[50, 50] and not m[0, 0]
    import cv2

    inside = np.zeros((100, 100), np.uint8)
    cv2.fillPoly(inside, [np.rint(pts).astype(np.int32)], 1)
    inside = cv2.erode(inside, np.ones((3, 3), np.uint8)).astype(bool)  # ignore rounding at the border
    assert (m | ~inside).all()  # every pixel of the first loop is filled, overlaps included


def test_fill_contains_the_contour_pixels():
    m = np.zeros((60, 60), bool)
    m[10:50, 20:40] = True
    c = longest_exterior_contour(m)
    f = fill_contour(c, m.shape)
    assert np.array_equal(f, m)


def test_simplified_contour_surrounds_the_tree():
    m = np.zeros((256, 256), bool)
    yy, xx = np.mgrid[:256, :256]
    m |= (xx - 128) ** 2 + (yy - 100) ** 2 < 70 ** 2
    m[150:240, 122:134] = True
    c = longest_exterior_contour(m)
    cr = resample_contour(c, pin_points(c, baseline=169.0), counts=(20, 160, 20))
    cs = simplify_contour(cr, m.shape, m=20, dilate=8, counts=(20, 160, 20))
    assert cs.shape == (20, 2)
    assert np.hypot(*(cs[0] - cr[0])) <= 10  # Cs[0] sits next to B
    import cv2

    poly = np.zeros_like(m, np.uint8)
    cv2.fillPoly(poly, [np.rint(cs).astype(np.int32)], 1)
    assert (poly.astype(bool) & m).sum() >= 0.97 * m.sum()
    with pytest.raises(InputError):
        simplify_contour(cr, m.shape, m=2)
