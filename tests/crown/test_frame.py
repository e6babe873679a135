"""A crown the photo's edges cut is continued past them, rounded (issue 11: no boxes)."""

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.crown.frame import REACH, beyond_frame


def _widths(mask):
    return mask.sum(1)


def test_a_crown_cut_by_the_top_gets_a_rounded_top_and_keeps_its_pixels():
    yy, xx = np.mgrid[:90, :120]
    disc = (yy - 30) ** 2 + (xx - 60) ** 2 < 45 ** 2  # its top 15 rows lie above the frame
    padded, (top, left) = beyond_frame(disc)
    assert left == 0 and padded.shape == (90 + top, 120) and top > 0
    assert np.array_equal(padded[top:], disc)  # the photo's pixels stay as they were
    crown_h = 90 - int(np.flatnonzero(disc.any(1))[0])
    assert top <= np.ceil(REACH * crown_h)
    w = _widths(padded[:top + 1])
    assert np.all(np.diff(w[w > 0]) >= 0)  # narrower upward: a dome, not a box
    assert w[w > 0][0] < 0.5 * w[-1]


def test_sides_and_corners_are_continued_the_ground_never():
    yy, xx = np.mgrid[:100, :80]
    crown = ((yy - 35) ** 2 / 55 ** 2 + (xx - 40) ** 2 / 60 ** 2 < 1) & (yy < 70)  # fills the top and sides
    crown[70:, 38:42] = True  # the trunk to the bottom edge
    padded, (top, left) = beyond_frame(crown)
    right = padded.shape[1] - left - 80
    assert top > 0 and left > 0 and right > 0 and padded.shape[0] == 100 + top  # nothing added below
    assert padded[top - 1, left - 1] and padded[top - 1, left + 80]  # the corners are bridged, not notched
    assert not padded[0, 0] and not padded[0, -1]  # ... and rounded off
    # left and right alike for a symmetric crown
    assert left == right and np.array_equal(padded, padded[:, ::-1])


def test_a_crown_inside_the_frame_or_touching_it_by_a_few_pixels_is_left_alone():
    yy, xx = np.mgrid[:60, :80]
    inside = (yy - 30) ** 2 + (xx - 40) ** 2 < 20 ** 2
    p, off = beyond_frame(inside)
    assert off == (0, 0) and np.array_equal(p, inside)
    inside[0, 40] = True  # a twig's tip touching the top edge
    assert beyond_frame(inside)[1] == (0, 0)
    assert beyond_frame(np.zeros((10, 10), bool))[1] == (0, 0)


def test_bad_arguments_are_one_clear_error():
    with pytest.raises(InputError, match="mask"):
        beyond_frame(np.zeros(10, bool))
    with pytest.raises(InputError, match="reach"):
        beyond_frame(np.ones((10, 10), bool), reach=-1)


def test_what_reaches_a_side_only_below_the_crowns_middle_is_not_continued():
    """A hedge or a neighbour the mask took in at the crown's foot is not the crown cut by the frame."""
    yy, xx = np.mgrid[:100, :80]
    crown = (yy - 35) ** 2 + (xx - 40) ** 2 < 25 ** 2
    crown[55:95, 38:42] = True   # the trunk
    crown[75:95, 40:] = True     # a hedge from the trunk to the right edge, low down
    assert beyond_frame(crown)[1] == (0, 0) and beyond_frame(crown)[0].shape == crown.shape
    crown[20:50, 40:] = True     # the crown itself reaching the right edge: continued
    padded, (top, left) = beyond_frame(crown)
    assert top == 0 and left == 0 and padded.shape[1] > 80
    assert not padded[75:95, 80:].any()  # not at the hedge's rows
