"""``treeform cloud``: billboard cloud of a tree picture or photo (seed 000 §6)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from treeform.cli.app import app, run_api, seed_option, SEGMENTER_OPTION, SegmenterName


@app.command("cloud")
def cloud_cmd(
    image: Path = typer.Argument(..., metavar="IMAGE", help="RGBA tree picture (used as it is) or a photo (made into a billboard)."),
    out: Path = typer.Option(..., "--out", "-o", help="Billboard cloud (.glb); its JSON sidecar goes beside it."),
    segments: int = typer.Option(256, "--segments", help="Superpixels (billboards) the crown is cut into (Argudo et al. 2020 use 256)."),
    compactness: float = typer.Option(0.35, "--compactness",
                                      help="Superpixel compactness; lower follows the leaves more, with more ragged edges (published value 0.35)."),
    seed: int = seed_option(help="Random seed: same picture + seed -> identical files."),
    views: Optional[Path] = typer.Option(None, "--views",
                                         help="Also write picture | front | 30° | 60° | 90° views (PNG)."),
    segmenter: SegmenterName = SEGMENTER_OPTION,
    report: bool = typer.Option(False, "--report",
                                help="Also write <OUT stem>_report/report.html beside OUT: input, alpha and "
                                     "crown/trunk split, views (with --views), metrics incl. front-view PSNR/SSIM/IoU, "
                                     "stage times, the cloud in a 3D viewer (opens offline)."),
):
    """Picture of a tree -> billboard cloud: alpha-tested cards at depth (GLB) with a JSON description."""
    from treeform.methods.variations.cloud import CLOUD_STAGES, cloud

    res = run_api(cloud, image, out=out, views=views, segments=segments, compactness=compactness, seed=seed,
                  segmenter=segmenter.value, report=out.with_name(f"{out.stem}_report") if report else None,
                  stages=CLOUD_STAGES + (("report",) if report else ()))
    m = res.metrics
    line = (f"{out}: {m['billboards']} billboards (front {m['front']}, rear {m['rear']}, interior {m['interior']}, "
            f"trunk {m['trunk']}), atlas {m['atlas'][0]}x{m['atlas'][1]}, sidecar {out.with_suffix('.json')}")
    if "psnr" in m:
        line += f"; front view PSNR {m['psnr']:.1f} dB, SSIM {m['ssim']:.3f}, IoU {m['iou']:.3f}"
    typer.echo(line)
    if report:
        typer.echo(f"report: {res.files['report']}")
