"""``treeform skeleton2d``: the foliage skeleton of a photo (seed 004 §3), drawn over it."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import numpy as np
import typer

from treeform.cli.app import _choices, app, run_api, seed_option, SEGMENTER_OPTION, SegmenterName

SkeletonSource = _choices("SkeletonSource", "auto", "foliage", "wood")


@app.command("skeleton2d")
def skeleton2d_cmd(
    photo: Path = typer.Argument(..., metavar="PHOTO", help="Photo of a tree (JPEG, PNG, ...)."),
    out: Path = typer.Option(..., "--out", "-o", help="Overlay image (.png); the polylines go beside it (.json)."),
    branches: int = typer.Option(5, "--branches", min=1, max=32, help="First-order branches n (cuts: n - 1)."),
    levels: int = typer.Option(2, "--levels", min=1, max=3, help="Branch orders: 2 adds second-order branches in each area."),
    mask: Optional[Path] = typer.Option(None, "--mask", help="Tree mask image, white = tree (skips segmentation)."),
    seed: int = seed_option(help="Random seed (the cuts' draw)."),
    segmenter: SegmenterName = SEGMENTER_OPTION,
    source: SkeletonSource = typer.Option(SkeletonSource.auto, "--source",
                                          help="foliage: from the crown's outline (force field, DCE cuts); wood: "
                                               "along the visible wood; auto: wood when the branches show."),
):
    """Photo -> 2D branch skeleton: from the foliage's shape (force field, DCE cuts; Guénard et al. 2013) or the visible wood."""
    from treeform.methods.synthesis.pipeline import SKELETON2D_STAGES, skeleton2d

    sk, files = run_api(skeleton2d, photo, out=out, n_branches=branches, levels=levels, mask=mask, seed=seed,
                        segmenter=segmenter.value, source=source.value, stages=SKELETON2D_STAGES,
                        inputs=(photo, ("--mask", mask)))
    counts = np.bincount(sk.order, minlength=3) if len(sk.order) else [0, 0, 0]
    typer.echo(f"{files['png']}: {sk.meta['mode']} skeleton, {len(sk.branches)} branches (order 1: {counts[1]}, "
               f"order 2: {counts[2]}), polylines {files['json']}")
