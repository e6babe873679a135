"""Metrics: reprojection error (seed 004 eq. 3), IoU, crown proportions, PSNR, SSIM, colour distance."""

from treeform.metrics.image import color_distance, psnr, ssim
from treeform.metrics.reprojection import extent_ratio, iou, reprojection_error, silhouette_gaps
from treeform.metrics.segmentation import class_iou, confusion_matrix, tree_iou

__all__ = ["reprojection_error", "iou", "extent_ratio", "silhouette_gaps", "psnr", "ssim", "color_distance", "class_iou", "confusion_matrix", "tree_iou"]

# tree-form metrics of seed 003 §6
from treeform.metrics.treeform_metrics import (  # noqa: E402
    METRIC_NAMES,
    average_branching_angle,
    biomass,
    branching_angles,
    leaf_area_index,
    leaf_area_index_triangles,
    max_radial_trunk_distance,
    mesh_metrics,
    metric_vector,
    stems_at,
    tree_height,
    tree_metrics,
    trunk_diameter,
)

__all__ += [
    "METRIC_NAMES",
    "average_branching_angle",
    "biomass",
    "branching_angles",
    "leaf_area_index",
    "leaf_area_index_triangles",
    "max_radial_trunk_distance",
    "mesh_metrics",
    "metric_vector",
    "stems_at",
    "tree_height",
    "tree_metrics",
    "trunk_diameter",
]
