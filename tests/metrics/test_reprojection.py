import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.metrics import extent_ratio, iou, reprojection_error


def test_reprojection_error_is_xor_over_mask():
    b = np.zeros((10, 10), bool)
    b[2:8, 2:8] = True  # 36 px
    i = np.zeros_like(b)
    i[2:8, 3:9] = True  # shifted by one column: 6 + 6 px disagree
    assert reprojection_error(i, b) == pytest.approx(12 / 36)
    assert reprojection_error(b, b) == 0.0
    assert iou(i, b) == pytest.approx(30 / 42)
    with pytest.raises(InputError):
        reprojection_error(i, np.zeros_like(b))
    with pytest.raises(InputError):
        iou(i, b[:5])


def test_extent_ratio():
    front = np.zeros((50, 100), bool)
    front[10:40, 20:80] = True
    side = np.zeros_like(front)
    side[10:40, 35:65] = True
    assert extent_ratio(side, front, percentile=0) == pytest.approx(0.5)
