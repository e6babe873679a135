"""Pictures of results: preview strips and overlays."""

from treeform.report.preview import compose_strip, over_checkerboard, segmentation_overlay

__all__ = ["compose_strip", "over_checkerboard", "segmentation_overlay"]
