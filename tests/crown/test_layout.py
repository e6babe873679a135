"""The tree's layout in its photo: where the trunk is and how wide, when the photo shows it and when not."""

import numpy as np
import pytest

from treeform.crown.layout import TRUNK_PRIOR, tree_layout
from treeform.structures import Segmentation


def _crown(h=200, w=160):
    lab = np.zeros((h, w), np.uint8)
    yy, xx = np.mgrid[:h, :w]
    lab[((yy - 60) / 50.0) ** 2 + ((xx - 80) / 60.0) ** 2 <= 1] = 1  # rows 10-110
    return lab


def test_the_wood_at_the_foot_gives_the_trunk_width():
    lab = _crown()
    lab[100:190, 77:84] = 2  # a 7-px trunk of bark to the ground
    lay = tree_layout(Segmentation(lab))
    assert lay.trunk_width == 7.0 and abs(lay.base[0] - 80.5) < 1.0


@pytest.mark.parametrize("under", ["bush", "skirt", "patches"])
def test_a_hidden_trunk_takes_the_prior_not_what_hides_it(under):
    """No wood at the foot, and under the crown a bush behind the foot, clumps of low leaves or foliage
    down to the ground: none is the trunk, so the width is the prior share of the tree's height (it was
    their whole width: a log as wide as a bush under the tree)."""
    lab = _crown()
    if under == "bush":
        lab[100:150, 79:81] = 1
        lab[150:190, 50:110] = 1  # 60 px wide, 30 % of the height
    elif under == "patches":  # a sapling's low leaves in clumps under its crown, the stem unseen
        lab[130:145, 40:75] = 1
        lab[160:175, 85:125] = 1
        lab[180:190, 70:95] = 1
    else:
        yy, xx = np.mgrid[:200, :160]
        lab[((yy - 100) / 90.0) ** 2 + ((xx - 80) / 60.0) ** 2 <= 1] = 1  # the crown reaches the ground
    seg = Segmentation(lab)
    lay = tree_layout(seg)
    rows = np.flatnonzero(seg.tree_mask.any(1))
    size = rows.max() - rows.min() + 1
    assert lay.trunk_width == pytest.approx(TRUNK_PRIOR * size)
    assert lay.trunk_width < 0.05 * size


def test_every_part_of_the_crown_is_kept_but_specks():
    """A sapling's crown in pieces along its stem: the tuft at the top, a clump of low leaves (a tenth of
    its area) and a speck (under CROWN_PART of it). The crown the envelope inflates and the leaves fill
    holds the tuft and the clump; it used to hold the tuft alone."""
    from treeform.crown.layout import CROWN_PART

    lab = np.zeros((200, 160), np.uint8)
    yy, xx = np.mgrid[:200, :160]
    lab[((yy - 50) / 40.0) ** 2 + ((xx - 80) / 40.0) ** 2 <= 1] = 1  # the tuft, ~5,000 px
    lab[120:135, 84:118] = 1  # low leaves beside the stem, ~500 px
    lab[150:154, 60:64] = 1  # a speck, 16 px
    lab[90:195, 78:82] = 2  # the stem
    lay = tree_layout(Segmentation(lab))
    assert lay.crown_mask[50, 80] and lay.crown_mask[127, 100]
    assert not lay.crown_mask[152, 62] and 16 < CROWN_PART * 5000
