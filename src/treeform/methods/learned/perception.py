"""Perception stage of paper 003 (§4.2, §5): photo -> semantic mask M (and, later, species U and RBV R).

:func:`segment_photo` is the whole of ``treeform segment``: read a photo, segment its main
tree (learned network by default, or the classical colour rules), write ``labels.png``
(single-channel 8-bit: 0 background, 1 foliage, 2 wood, at the photo's size) and
optionally an overlay. The networks run on onnxruntime (:mod:`treeform.learn.infer`);
nothing here imports torch or the training code.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from treeform._shared.defaults import DEFAULT_SEGMENTER
from treeform._shared.timing import StageTimer

__all__ = ["SEGMENT_STAGES", "SPECIES_STAGES", "SegmentResult", "classify_species", "segment_photo"]

SEGMENT_STAGES = ("load", "segment", "write")


@dataclass
class SegmentResult:
    """Result of :func:`segment_photo`: the segmentation, the photo and the written files."""

    segmentation: object
    photo: object
    files: dict
    seconds: dict

    @property
    def fractions(self) -> dict:
        lab = self.segmentation.labels
        return {"foliage": float((lab == 1).mean()), "wood": float((lab == 2).mean())}


def segment_photo(photo, *, out=None, overlay=None, mask=None, wood=None, segmenter: str = DEFAULT_SEGMENTER,
                  seed: int = 0, max_size: int = 4096, progress=None) -> SegmentResult:
    """Segment the main tree of a photo and write its labels.

    A cut-out (an RGBA image of a tree alone) is not segmented: its alpha is the tree, its
    foliage and wood told apart by colour (:func:`treeform.segment.mask_to_segmentation`), the
    mask ``reconstruct`` builds from it.

    Parameters
    ----------
    photo : path-like or ndarray, shape (H, W, 3), uint8
    out : path-like, optional
        ``labels.png``: 8-bit single channel, 0 background / 1 foliage / 2 wood, photo size.
    overlay : path-like, optional
        The photo with background dimmed, foliage green and wood red (PNG).
    mask : path-like, optional
        The tree as a black-and-white PNG (255 = foliage or wood), as ``reconstruct --mask`` reads it.
    wood : path-like, optional
        The wood (trunk and branches) as a black-and-white PNG, as ``grow --mask`` reads it.
    segmenter : {'learned', 'classical'}
    seed : int
        Seed of the classical graph cut (the network is deterministic).
    max_size : int
        Larger photos are reduced to this long side first.
    progress : callable, optional
        ``progress(stage, event, seconds)`` over :data:`SEGMENT_STAGES`.

    Raises
    ------
    InputError, NoTreeFoundError, ModelError, OutputError
    """
    from treeform._shared.checks import check_choice
    from treeform.io.outputs import check_out_file
    from treeform.segment import SEGMENTERS

    check_choice(segmenter, "segmenter", SEGMENTERS)
    out_p = check_out_file(out) if out is not None else None
    ov_p = check_out_file(overlay, "--overlay") if overlay is not None else None
    mask_p = check_out_file(mask, "--mask") if mask is not None else None
    wood_p = check_out_file(wood, "--wood") if wood is not None else None
    timer = StageTimer(progress)
    with timer.stage("load"):
        from treeform.methods._single_photo import load_photo, segment_or_mask

        ph, cut = load_photo(photo, max_size=max_size)
    with timer.stage("segment"):
        seg = segment_or_mask(ph.image, cut, segmenter=segmenter, seed=seed)
    files = {}
    with timer.stage("write"):
        from treeform.io.images import write_png

        if out_p is not None:
            files["labels"] = write_png(seg.labels, out_p)
        if ov_p is not None:
            from treeform.report.preview import segmentation_overlay

            files["overlay"] = write_png(segmentation_overlay(ph.image, seg), ov_p)
        if mask_p is not None:
            files["mask"] = write_png(np.where(seg.labels > 0, 255, 0).astype(np.uint8), mask_p)
        if wood_p is not None:
            files["wood"] = write_png(np.where(seg.labels == 2, 255, 0).astype(np.uint8), wood_p)
    return SegmentResult(seg, ph, files, dict(timer.timings))


SPECIES_STAGES = ("load", "segment", "species")


def classify_species(photo, *, segmenter: str = "learned", seed: int = 0, max_size: int = 640,
                     progress=None) -> dict:
    """Species probabilities ``{name: p}`` (best first) of the main tree of a photo (seed 003 §4.2.4).

    The photo is segmented (``segmenter``) and the species CNN reads the semantic mask. A
    cut-out's alpha is its tree (as for ``reconstruct``), labelled foliage / wood by colour.
    """
    from treeform.learn.infer import predict_species
    from treeform.methods._single_photo import load_photo, segment_or_mask

    timer = StageTimer(progress)
    with timer.stage("load"):
        ph, cut = load_photo(photo, max_size=max_size)
    with timer.stage("segment"):
        seg = segment_or_mask(ph.image, cut, segmenter=segmenter, seed=seed)
    with timer.stage("species"):
        return predict_species(seg.labels)
