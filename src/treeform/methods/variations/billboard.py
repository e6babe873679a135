"""Photo -> RGBA billboard by segmentation, trimap and alpha matting (seed 000 §4.3, Fig. 4).

The ``treeform billboard`` stage of the image-based variations method; re-exported by
:mod:`treeform.methods.variations.pipeline`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from treeform._shared.errors import InputError
from treeform._shared.timing import ProgressCallback, StageTimer
from treeform.io.outputs import check_out_file
from treeform.methods.variations.config import VariationsConfig

__all__ = ["Billboard", "billboard", "BILLBOARD_STAGES"]

BILLBOARD_STAGES = ("load", "segment", "trimap", "matting", "export")


@dataclass
class Billboard:
    """What :func:`billboard` made."""

    rgba: np.ndarray
    alpha: np.ndarray
    trimap: np.ndarray
    segmentation: object
    photo: object
    box: tuple
    metrics: dict
    sheet: np.ndarray | None = None
    files: dict = field(default_factory=dict)


def billboard(photo, *, out=None, sheet=None, config: VariationsConfig | None = None,
              progress: ProgressCallback | None = None, **options) -> Billboard:
    """Photo of a tree -> RGBA billboard (seed 000 §4.3, Fig. 4).

    The photo is segmented automatically (:func:`treeform.segment.segment`); a
    trimap is derived from the segmentation (a dilated band = unknown, the eroded trunk
    and points sampled in the eroded crown = foreground, the rest = background — with
    ``sky_gaps=True`` also sky seen through crown gaps, beyond the paper,
    :func:`treeform.segment.make_trimap`); closed-form alpha
    matting and foreground colour estimation (PyMatting) give the billboard, which is
    cropped to the tree with a small transparent margin.

    Parameters
    ----------
    photo : path-like, ndarray (H, W, 3) uint8 or Photo
    out : path-like, optional
        The RGBA PNG to write.
    sheet : path-like, optional
        A PNG of photo | trimap | billboard over a checkerboard.
    config : VariationsConfig, optional
    progress : callable, optional
        Stages :data:`BILLBOARD_STAGES`.

    Returns
    -------
    Billboard
        ``rgba`` (cropped), ``alpha`` (photo size), ``metrics`` with ``iou`` = IoU of
        ``alpha > 0.5`` with the segmentation's tree mask.
    """
    from treeform.methods.variations.pipeline import _config, contact_sheet
    from treeform.structures import Photo

    cfg = _config(config, options)
    out_path = check_out_file(out) if out is not None else None
    sheet_path = check_out_file(sheet, "--sheet") if sheet is not None else None
    timer = StageTimer(progress)
    with timer.stage("load"):
        if isinstance(photo, Photo):
            ph = photo
        elif isinstance(photo, np.ndarray):
            if photo.ndim != 3 or photo.shape[2] != 3 or photo.dtype != np.uint8:
                raise InputError(f"photo: expected an (H, W, 3) uint8 array, got {photo.shape} {photo.dtype}")
            ph = Photo(np.ascontiguousarray(photo))
        else:
            from treeform.io import read_photo

            ph = read_photo(photo, max_size=cfg.photo_max_size)
        image = ph.image
    with timer.stage("segment"):
        from treeform.segment import segment

        seg = segment(image, method=cfg.segmenter, seed=cfg.seed, require_tree=True)
    with timer.stage("trimap"):
        from treeform.segment.matting import make_trimap

        tri = make_trimap(image, seg, gaps=cfg.sky_gaps, seed=cfg.seed)
    with timer.stage("matting"):
        from treeform.segment.matting import alpha_matting, estimate_foreground

        alpha = alpha_matting(image, tri, max_side=cfg.matting_side)
        fg = estimate_foreground(image, alpha)
        full = np.empty(image.shape[:2] + (4,), np.uint8)
        full[..., :3] = np.clip(np.rint(fg * 255), 0, 255)
        full[..., 3] = np.clip(np.rint(alpha * 255), 0, 255)
        full[full[..., 3] == 0] = 0
        m = alpha > 0.5
        tree = seg.tree_mask
        union = int((m | tree).sum())
        iou = float((m & tree).sum() / union) if union else 0.0
        ys, xs = np.nonzero(full[..., 3] > 0)
        if ys.size == 0:
            from treeform._shared.errors import NoTreeFoundError

            raise NoTreeFoundError("the matte is empty: no tree found in the photo")
        pad = max(2, int(round(0.02 * max(image.shape[:2]))))
        h, w = alpha.shape
        box = (max(0, ys.min() - pad), max(0, xs.min() - pad), min(h, ys.max() + 1 + pad), min(w, xs.max() + 1 + pad))
        rgba = full[box[0]:box[2], box[1]:box[3]].copy()
    res = Billboard(rgba, alpha, tri, seg, ph, box, {"iou": iou, "size": [int(w), int(h)]})
    with timer.stage("export"):
        targets, arrays = [], []
        if sheet_path is not None:
            tri8 = np.repeat((tri * 255).astype(np.uint8)[..., None], 3, axis=2)
            res.sheet = contact_sheet([image, tri8, full], tile=max(cfg.tile, 384), cols=3)
            targets.append(sheet_path)
            arrays.append(res.sheet)
        if out_path is not None:
            targets.append(out_path)
            arrays.append(rgba)
        if targets:
            from treeform.io import write_png
            from treeform.io._atomic import atomic_paths

            with atomic_paths(targets) as temps:  # both files, or neither
                for tmp, arr in zip(temps, arrays):
                    write_png(arr, tmp)
            res.files = dict(zip(["sheet"] * (sheet_path is not None) + ["billboard"] * (out_path is not None),
                                 targets))
    res.metrics["timings"] = {k: round(v, 4) for k, v in timer.timings.items()}
    return res
