"""Metrics: reprojection error (seed 004 eq. 3), IoU, crown proportions."""

from treeform.metrics.reprojection import extent_ratio, iou, reprojection_error

__all__ = ["reprojection_error", "iou", "extent_ratio"]
