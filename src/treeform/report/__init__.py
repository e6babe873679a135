"""Pictures of results: preview strips and overlays; the evaluation's HTML page with a 3D viewer."""

from treeform.report.batch_page import write_batch_summary
from treeform.report.eval_page import write_eval_report
from treeform.report.run_page import write_run_report

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
           "preview_strip", "preview_windows", "segmentation_overlay", "write_batch_summary", "write_eval_report",
           "write_run_report"]
