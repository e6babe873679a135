"""``treeform grow``: a species preset grown into a leafy 3D tree (paper 003 §4.3)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from treeform.cli.app import app, FoliageKind, Lod, run_api, seed_option, TEXTURE_SIZE_HELP


@app.command()
def grow(
    species: str = typer.Option("oak", "--species", "-s",
                                help="acacia, apple, willow, maple, birch, oak, pine, or a species .json file."),
    seed: int = seed_option(),
    out: Path = typer.Option(Path("out/grow"), "--out", "-o", help="Output directory."),
    lod: Lod = typer.Option(Lod.medium, "--lod", help="Level of detail (triangle budget)."),
    leaves: Optional[int] = typer.Option(None, "--leaves", help="Number of leaf clusters (default: 3 per twig)."),
    rbv: Optional[Path] = typer.Option(None, "--rbv", help="Grow inside this radial bounding volume (.npz), bi-modally."),
    mask: Optional[Path] = typer.Option(None, "--mask", help="Branch mask (white = branch) the scaffold follows; needs --rbv."),
    foliage: FoliageKind = typer.Option(FoliageKind.auto, "--foliage",
                                        help="Leaf cards: broadleaf, needles or scales; auto: the species'."),
    texture_size: Optional[int] = typer.Option(None, "--texture-size", min=16, max=8192, help=TEXTURE_SIZE_HELP),
    report: bool = typer.Option(False, "--report", help="Also write report.html: preview, metrics, stage times, "
                                "the tree in a 3D viewer (opens offline)."),
):
    """Grow a leafy 3D tree of a species with a bud-based developmental model (Li et al. 2021)."""
    from treeform.methods.learned.grow import STAGES, grow_tree

    res = run_api(grow_tree, species, stages=STAGES, seed=seed, out=out, lod=lod.value, leaves=leaves,
                  rbv=None if rbv is None else str(rbv), mask=None if mask is None else str(mask),
                  foliage=foliage.value, texture_size=texture_size,
                  inputs=(("--rbv", rbv), ("--mask", mask)))
    m = res.metrics  # height and crown: treeform.metrics' definitions, as `treeform metrics` reports them
    typer.echo(f"{m['species']}: {m['nodes']} branches, {m['leaves']} leaves, {m['triangles']} triangles, "
               f"{m['height']:.1f} m tall, crown {m['crown_extent_x']:.1f} x {m['crown_extent_z']:.1f} m "
               f"(width {m['crown_width']:.1f} m), {m['total_seconds']:.2f} s -> {out}")
    if report:
        from treeform.cli.app import write_report

        write_report(out, f"treeform grow --species {species} --seed {seed}")
