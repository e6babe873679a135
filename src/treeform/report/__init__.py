"""Pictures of results: preview strips and overlays."""

from treeform.report.preview import compose_strip, segmentation_overlay

__all__ = ["compose_strip", "segmentation_overlay"]
