"""Pictures of results: preview strips and overlays."""

from treeform.report.preview import (
    PREVIEW_LABELS,
    compose_strip,
    over_checkerboard,
    photo_window,
    preview_cameras,
    preview_strip,
    preview_windows,
    segmentation_overlay,
)

__all__ = ["PREVIEW_LABELS", "compose_strip", "over_checkerboard", "photo_window", "preview_cameras",
           "preview_strip", "preview_windows", "segmentation_overlay"]
