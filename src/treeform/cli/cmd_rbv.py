"""``treeform rbv TREE -o rbv.npz``: the radial bounding volume of a tree, the file ``grow --rbv`` reads."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from treeform._shared.errors import TreeformError
from treeform.cli.app import app


@app.command()
def rbv(
    tree: Path = typer.Argument(..., metavar="TREE", help="A treeform output folder, skeleton.json or a .glb tree."),
    out: Path = typer.Option(..., "--out", "-o", help="The volume as .npz (what `grow --rbv` reads)."),
    level: int = typer.Option(4, "--level", min=1, max=5, help="Resolution: level L has 2^(L-1) layers x sectors."),
    plot: Optional[Path] = typer.Option(None, "--plot", help="Also draw the volume (side and top view, PNG)."),
):
    """Radial bounding volume of a tree: its outermost extent per height layer and angular sector."""
    from treeform.methods.learned.volume import fit_rbv

    try:
        vol = fit_rbv(tree, level=level, out=out, plot=plot)
    except TreeformError as exc:
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(exc.exit_code)
    n = vol.n_layers
    typer.echo(f"{n} layers x {n} sectors, {vol.physical_height:.1f} m tall, widest radius "
               f"{vol.physical_radii.max():.1f} m, {vol.volume():.0f} m³ -> {out}" + (f", {plot}" if plot else ""))
