"""``treeform eval``: score tree-reconstruction methods on the same cases against ground truth."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from treeform.cli.app import app, run_api, seed_option


@app.command("eval")
def eval_cmd(
    cases: str = typer.Option("synthetic:21", "--cases", help="synthetic:N (grown trees with full 3D ground truth), "
                              "captures:N (the same, photographed all around: for multiview) "
                              "or photos:DIR (NAME_mask.png beside a photo is its true mask)."),
    methods: str = typer.Option("envelope", "--methods", help="Comma-separated methods, e.g. envelope,learned,abs "
                                "(multiview with captures:N)."),
    out: Path = typer.Option(..., "--out", "-o", help="Folder: results.json and cases/ (a rerun skips finished cases)."),
    seed: int = seed_option(help="Seed of the synthetic cases and of every method."),
    workers: Optional[int] = typer.Option(None, "--workers", help="Local Dask worker processes (default: all cores; "
                                          "0 = in this process)."),
    scheduler: Optional[str] = typer.Option(None, "--scheduler", help="Use a running Dask scheduler, e.g. tcp://host:8786."),
    viewer: int = typer.Option(4, "--viewer", help="Cases whose true and reconstructed trees go into report.html's "
                               "3D viewer (about 15 MB each)."),
):
    """Reconstruct every case with every method and score it (silhouettes from four sides, RBV, form metrics); report.html."""
    from treeform.cli.progress import CountProgress
    from treeform.evaluation import evaluate
    from treeform.evaluation.tables import summary_lines

    res = run_api(evaluate, cases, methods, out, seed=seed, workers=workers, scheduler=scheduler, viewer=viewer,
                  display=CountProgress("cases"))
    for line in summary_lines(res):
        typer.echo(line)
    typer.echo(f"results: {Path(out) / 'results.json'}; report: {Path(out) / 'report.html'}")
