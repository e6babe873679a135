"""Tests of treeform.metrics.segmentation."""

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.metrics.segmentation import class_iou, confusion_matrix, tree_iou


def test_perfect_prediction_scores_one():
    ref = np.random.default_rng(0).integers(0, 3, (20, 30))
    iou = class_iou(confusion_matrix(ref, ref))
    assert np.allclose(iou, 1.0)
    assert tree_iou(ref, ref) == 1.0


def test_known_confusion():
    ref = np.array([[0, 0, 1, 1, 2, 3]])
    pred = np.array([[0, 1, 1, 1, 1, 0]])
    c = confusion_matrix(pred, ref)
    assert c.sum() == 5  # the unknown-part pixel (3) is skipped
    iou = class_iou(c)
    assert iou[0] == pytest.approx(1 / 2) and iou[1] == pytest.approx(2 / 4) and iou[2] == 0.0
    assert tree_iou(pred, ref) == pytest.approx(3 / 5)


def test_absent_class_is_nan_and_shapes_are_checked():
    c = confusion_matrix(np.zeros((4, 4), int), np.zeros((4, 4), int))
    assert np.isnan(class_iou(c)[2])
    with pytest.raises(InputError):
        tree_iou(np.zeros((3, 3)), np.zeros((3, 4)))
