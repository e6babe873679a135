"""``treeform batch``: reconstruct every photo of a folder on Dask."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from treeform.cli.app import app, Method, run_api, seed_option


@app.command("batch")
def batch_cmd(
    input_dir: Path = typer.Argument(..., metavar="INPUT_DIR", help="Folder of photos (JPEG, PNG, TIFF, WebP)."),
    out: Path = typer.Option(..., "--out", "-o", help="Folder: one subfolder per photo, manifest.json, "
                             "failures.json, summary.html (a rerun skips the photos done, retries the failed)."),
    method: Method = typer.Option(Method.envelope, "--method", help="Single-photo method for every photo."),
    seed: int = seed_option(help="Random seed of every reconstruction."),
    workers: Optional[int] = typer.Option(None, "--workers", help="Local Dask worker processes (default: all cores; "
                                          "0 = one photo after the other from this process)."),
    scheduler: Optional[str] = typer.Option(None, "--scheduler", help="Use a running Dask scheduler, e.g. "
                                            "tcp://host:8786 (its workers need treeform installed)."),
    timeout: float = typer.Option(600.0, "--timeout", help="Seconds a photo may take; then it is killed and "
                                  "recorded as failed."),
    memory_limit: str = typer.Option("4GB", "--memory-limit", help="Memory a photo's process may use "
                                     "(e.g. 4GB, 512MiB; none = no limit)."),
    min_free: str = typer.Option("500MB", "--min-free", help="Free space to keep on the output disk: the batch "
                                 "does not start below it, and stops starting photos once the disk fills "
                                 "(they are recorded as failed; a rerun retries them). none = no check."),
):
    """Reconstruct every photo of a folder, one Dask task per photo; a contact sheet in summary.html."""
    from treeform.batch import run_batch
    from treeform.cli.progress import CountProgress

    res = run_api(run_batch, input_dir, out, method=method.value, seed=seed, workers=workers, scheduler=scheduler,
                  timeout=timeout, memory_limit=memory_limit, min_free=min_free, display=CountProgress("photos"),
                  inputs=[input_dir])
    rate = f", {res['photos_per_second']:.2f} photos/s" if res["photos_per_second"] else ""
    typer.echo(f"{res['done']} of {res['total']} photos reconstructed ({res['skipped']} done before), "
               f"{res['failed']} failed{rate}; summary: {Path(out) / 'summary.html'}")
    if res["failed"]:
        typer.echo(f"failures: {Path(out) / 'failures.json'}")
