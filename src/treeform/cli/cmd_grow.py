"""``treeform grow``: a species preset grown into a leafy 3D tree (paper 003 §4.3)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from treeform.cli.app import Lod, app, run_api


@app.command()
def grow(
    species: str = typer.Option("oak", "--species", "-s",
                                help="acacia, apple, willow, maple, birch, oak, pine, or a species .json file."),
    seed: int = typer.Option(0, "--seed", help="Random seed."),
    out: Path = typer.Option(Path("out/grow"), "--out", "-o", help="Output directory."),
    lod: Lod = typer.Option(Lod.medium, "--lod", help="Level of detail (triangle budget)."),
    leaves: Optional[int] = typer.Option(None, "--leaves", help="Number of leaf clusters (default: 3 per twig)."),
    rbv: Optional[Path] = typer.Option(None, "--rbv", help="Grow inside this radial bounding volume (.npz), bi-modally."),
    mask: Optional[Path] = typer.Option(None, "--mask", help="Branch mask (white = branch) the scaffold follows; needs --rbv."),
):
    """Grow a tree of a species with the bud-based growth model (Li et al. 2021, Tables 2-3)."""
    from treeform.methods.learned.grow import STAGES, grow_tree

    res = run_api(grow_tree, species, stages=STAGES, seed=seed, out=out, lod=lod.value, leaves=leaves,
                  rbv=None if rbv is None else str(rbv), mask=None if mask is None else str(mask))
    m = res.metrics
    typer.echo(f"{m['species']}: {m['nodes']} branches, {m['leaves']} leaves, {m['triangles']} triangles, "
               f"{m['height']:.1f} m tall, {m['crown_width']:.1f} m wide, {m['total_seconds']:.2f} s -> {out}")
