"""Border following: exterior / interior contours, the longest exterior contour, orientation."""

import numpy as np
import pytest

from treeform._shared.errors import InputError, NoTreeFoundError
from treeform.contour import contour_length, find_contours, longest_exterior_contour, orient_contour, signed_area


def test_exterior_and_interior_contours():
    m = np.zeros((40, 60), bool)
    m[5:30, 5:30] = True
    m[10:15, 10:15] = False  # a hole
    m[5:8, 40:55] = True  # a second, smaller component
    cs, ext = find_contours(m)
    assert sorted(ext.tolist()) == [False, True, True]
    c = longest_exterior_contour(m)
    assert c[:, 0].min() == 5 and c[:, 0].max() == 29 and c[:, 1].max() == 29


def test_orientation_runs_from_the_bottom_to_the_right():
    m = np.zeros((30, 30), bool)
    m[5:25, 8:20] = True
    c = longest_exterior_contour(m)
    assert signed_area(c) < 0
    i = int(np.argmax(c[:, 1] * 100 - np.abs(c[:, 0] - 14)))  # a bottom point near the middle
    assert c[(i + 1) % len(c), 0] >= c[i, 0]  # forward goes right along the bottom
    assert np.array_equal(orient_contour(c[::-1]), c[::-1][::-1])


def test_length_and_edge_cases():
    assert contour_length([[0, 0], [3, 0], [3, 4]]) == pytest.approx(12.0)
    with pytest.raises(NoTreeFoundError):
        longest_exterior_contour(np.zeros((8, 8), bool))
    with pytest.raises(InputError):
        find_contours(np.zeros((4, 4, 3)))
    one = np.zeros((5, 5), bool)
    one[2, 2] = True
    assert longest_exterior_contour(one).tolist() == [[2.0, 2.0]]
