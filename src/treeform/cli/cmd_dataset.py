"""``treeform dataset generate``, ``show`` and ``capture``: synthetic training data (seed 003 §4.2), test captures."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from treeform.cli.app import app, run_api, seed_option

dataset_app = typer.Typer(no_args_is_help=True, help="Synthetic training data: grown trees rendered photo-like, with exact masks.")
app.add_typer(dataset_app, name="dataset")


@dataset_app.command("generate")
def generate_cmd(
    n: int = typer.Option(..., "--n", "-n", help="Number of samples."),
    out: Path = typer.Option(..., "--out", "-o", help="Dataset directory (shards, manifest.json, failures.json)."),
    size: int = typer.Option(256, "--size", help="Image edge in pixels."),
    species: str = typer.Option("all", "--species", help="'all' or a comma-separated list, e.g. oak,pine."),
    workers: Optional[int] = typer.Option(None, "--workers", help="Local Dask worker processes (default: all cores)."),
    scheduler: Optional[str] = typer.Option(None, "--scheduler", help="Use a running Dask scheduler, e.g. tcp://host:8786."),
    seed: int = seed_option(help="Global seed: sample i depends only on (seed, i)."),
    shard_size: int = typer.Option(1000, "--shard-size", help="Samples per tar shard (resuming is per sample, "
                                                                "whatever the shard size)."),
    mesh: bool = typer.Option(False, "--mesh/--no-mesh", help="Also store each tree's GLB."),
    backgrounds: Optional[Path] = typer.Option(None, "--backgrounds", help="Folder of your own background photos."),
    photo_fraction: float = typer.Option(0.5, "--photo-fraction", help="Share of samples over your photos."),
    bare: float = typer.Option(0.0, "--bare", help="Share of leafless samples (winter trees: bark only, labelled "
                               "wood); 0 keeps every sample as before."),
):
    """Render N grown trees over varied backgrounds on Dask; rerun the same command to resume.

    Every sample is stored the moment it is made (OUT/partial/ until its shard is complete),
    so an interrupted run loses only the samples in progress; rerun the same command to go on.
    """
    from treeform.cli.progress import CountProgress
    from treeform.dataset import generate_dataset

    res = run_api(generate_dataset, out, n=n, size=size, species=species, workers=workers, scheduler=scheduler,
                  seed=seed, shard_size=shard_size, mesh=mesh, backgrounds=backgrounds, photo_fraction=photo_fraction,
                  bare=bare, display=CountProgress("samples"))
    rate = f" in {res.seconds:.1f} s ({res.samples_per_second:.2f} samples/s on {res.workers} workers)" if res.seconds else ""
    kept = f"; {res.kept} sample(s) kept from an interrupted run" if res.kept else ""
    typer.echo(f"{res.generated} samples in {len(res.shards_written)} new shard(s){rate}; "
               f"{len(res.shards_skipped)} shard(s) already done{kept}; {len(res.failed)} failed (see failures.json) "
               f"-> {out}")


@dataset_app.command("show")
def show_cmd(
    directory: Path = typer.Argument(..., metavar="DATASET", help="A generated dataset directory."),
    n: int = typer.Option(16, "--n", "-n", help="Number of samples on the sheet."),
    out: Optional[Path] = typer.Option(None, "--out", "-o", help="Sheet path (default DIR/contact_sheet.png)."),
):
    """Contact sheet of images beside their masks (white background, green foliage, blue branches)."""
    from treeform.dataset import show_dataset

    path = run_api(show_dataset, directory, n=n, out=out, stages=("load", "sheet"))
    typer.echo(f"contact sheet: {path}")


@dataset_app.command("capture")
def capture_cmd(
    out: Path = typer.Argument(..., metavar="OUT", help="Capture folder (images/ and truth/)."),
    views: int = typer.Option(24, "--views", help="Number of photos on the circle around the tree (3-360)."),
    size: int = typer.Option(1024, "--size", help="Image width in pixels (landscape 4:3)."),
    species: str = typer.Option("oak", "--species", help="acacia, apple, willow, maple, birch, oak or pine."),
    seed: int = seed_option(help="Seeds the tree, the park, the cameras and the noise."),
    model: Optional[Path] = typer.Option(None, "--model", help="A GLB tree instead of a grown one (no skeleton truth)."),
    clutter: bool = typer.Option(True, "--clutter/--no-clutter", help="Benches, rocks, bins, kiosks ... in the park."),
):
    """Photograph a grown tree in a 3D park from cameras around it, with ground truth (multi-view test data).

    Writes OUT/images/view_00.jpg ... (JPEG with phone-like EXIF) and OUT/truth/ (cameras.json,
    labels/, skeleton.json, tree.glb, meta.json).
    """
    from treeform.dataset.capture import STAGES, synthetic_capture

    res = run_api(synthetic_capture, out, views=views, size=size, species=species, seed=seed, model=model,
                  clutter=clutter, stages=STAGES, inputs=[("--model", model)])
    typer.echo(f"{len(res.images)} views of a {res.height:.1f} m tree in {res.seconds:.1f} s -> {res.out}")
