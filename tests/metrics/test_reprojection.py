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


def test_color_distance_sees_colours_not_arrangement():
    from treeform.metrics import color_distance

    rng = np.random.default_rng(0)
    a = rng.integers(0, 256, (40, 40, 3)).astype(np.uint8)
    shuffled = a.reshape(-1, 3)[rng.permutation(1600)].reshape(40, 40, 3)
    assert color_distance(a, shuffled) < 0.01
    assert color_distance(a, a // 2) > 0.3  # darker: other colours
    mask = np.zeros((40, 40), bool)
    mask[:20] = True
    b = a.copy()
    b[20:] = 0
    assert color_distance(a, b, mask) < 1e-9 < color_distance(a, b)
    with pytest.raises(InputError):
        color_distance(a, a, np.zeros((40, 40), bool))
    with pytest.raises(InputError):
        color_distance(a[..., 0], a[..., 0])
