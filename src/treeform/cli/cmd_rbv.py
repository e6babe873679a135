"""``treeform rbv TREE -o rbv.npz``: the radial bounding volume of a tree, the file ``grow --rbv`` reads."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from treeform._shared.errors import TreeformError
from treeform.cli.app import app


def fit_rbv(tree, *, level: int = 4, out=None, plot=None):
    """Fit the radial bounding volume of a tree and write it (``.npz``) and optionally a picture.

    ``tree`` is a treeform output folder, a skeleton JSON or a GLB (see
    :func:`treeform.io.read_tree`): a skeleton gives the volume of its branch surfaces, any
    other GLB that of its vertices around the vertical axis through its lowest point.
    """
    import numpy as np

    from treeform.io import check_out_file, read_tree, write_png
    from treeform.structures import RadialBoundingVolume, TreeSkeleton

    if isinstance(level, bool) or level not in (1, 2, 3, 4, 5):
        raise TreeformError(f"--level: expected 1..5, got {level!r}")
    out_p = check_out_file(out, suffix=".npz") if out is not None else None
    plot_p = check_out_file(plot, "--plot") if plot is not None else None
    tree = read_tree(tree)
    if isinstance(tree, TreeSkeleton):
        rbv = RadialBoundingVolume.from_skeleton(tree, level=level)
    else:
        low = tree[:, 1] <= tree[:, 1].min() + 0.02 * max(float(np.ptp(tree[:, 1])), 1e-9)
        base = (*tree[low][:, [0, 2]].mean(axis=0),)
        rbv = RadialBoundingVolume.from_points(tree, level=level,
                                               axis_origin=(base[0], float(tree[:, 1].min()), base[1]))
    if out_p is not None:
        rbv.save(out_p)
    if plot_p is not None:
        from treeform.report.rbv_plot import plot_rbv

        write_png(plot_rbv(rbv), plot_p)
    return rbv


@app.command()
def rbv(
    tree: Path = typer.Argument(..., metavar="TREE", help="A treeform output folder, skeleton.json or a .glb tree."),
    out: Path = typer.Option(..., "--out", "-o", help="The volume as .npz (what `grow --rbv` reads)."),
    level: int = typer.Option(4, "--level", min=1, max=5, help="Resolution: level L has 2^(L-1) layers x sectors."),
    plot: Optional[Path] = typer.Option(None, "--plot", help="Also draw the volume (side and top view, PNG)."),
):
    """Radial bounding volume of a tree: its outermost extent per height layer and angular sector."""
    try:
        vol = fit_rbv(tree, level=level, out=out, plot=plot)
    except TreeformError as exc:
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(exc.exit_code)
    n = vol.n_layers
    typer.echo(f"{n} layers x {n} sectors, {vol.physical_height:.1f} m tall, widest radius "
               f"{vol.physical_radii.max():.1f} m, {vol.volume():.0f} m³ -> {out}" + (f", {plot}" if plot else ""))
