"""Segmentation quality: confusion matrix, per-class IoU, mean IoU and tree-vs-background IoU.

Labels follow :class:`~treeform.structures.Segmentation` (0 background, 1 foliage, 2 wood);
a reference label of 3 (:data:`treeform.dataset.scenes.TREE_ANY`, a tree pixel of unknown
part) counts for the tree IoU only.
"""

from __future__ import annotations

import numpy as np

from treeform._shared.errors import InputError

__all__ = ["confusion_matrix", "class_iou", "tree_iou"]

CLASSES = ("background", "foliage", "wood")


def _pair(pred, ref):
    p, r = np.asarray(pred), np.asarray(ref)
    if p.shape != r.shape or p.ndim != 2:
        raise InputError(f"pred and ref: expected two (H, W) label images of one shape, got {p.shape} and {r.shape}")
    return p, r


def confusion_matrix(pred, ref, *, classes: int = 3) -> np.ndarray:
    """(classes, classes) int64 counts: rows = reference label, columns = predicted label.

    Reference pixels outside ``0 .. classes-1`` (e.g. 3 = tree of unknown part) are skipped.

    >>> confusion_matrix(np.array([[0, 1]]), np.array([[0, 2]])).tolist()
    [[1, 0, 0], [0, 0, 0], [0, 1, 0]]
    """
    p, r = _pair(pred, ref)
    keep = r < classes
    idx = r[keep].astype(np.int64) * classes + np.clip(p[keep].astype(np.int64), 0, classes - 1)
    return np.bincount(idx, minlength=classes * classes).reshape(classes, classes)


def class_iou(confusion: np.ndarray) -> np.ndarray:
    """Per-class IoU from a confusion matrix (NaN for a class absent from both)."""
    c = np.asarray(confusion, np.float64)
    inter = np.diag(c)
    union = c.sum(0) + c.sum(1) - inter
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(union > 0, inter / union, np.nan)


def tree_iou(pred, ref) -> float:
    """IoU of the tree (any label > 0) between two label images; 1.0 when both are empty.

    >>> tree_iou(np.array([[1, 2, 0]]), np.array([[3, 0, 0]]))
    0.5
    """
    p, r = _pair(pred, ref)
    pt, rt = p > 0, r > 0
    union = int((pt | rt).sum())
    return float((pt & rt).sum() / union) if union else 1.0
