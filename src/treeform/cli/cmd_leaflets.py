"""``treeform leaflets``: leaflet billboards with their Fig. 13 channels (seed 001 §3.6, §4.2)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from treeform.cli.app import app, run_api, seed_option


@app.command("leaflets")
def leaflets_cmd(
    out: Path = typer.Option(..., "--out", "-o", help="Output directory (rgba/normal/centroid/uv/ao/depth/type PNGs)."),
    shape: str = typer.Option("sphere", "--shape", help="Volume of the space colonization: sphere or cone."),
    leaflet: Optional[Path] = typer.Option(None, "--leaflet", help="RGBA picture of a leaf (default: procedural)."),
    size: int = typer.Option(512, "--size", help="Texture edge in pixels."),
    attractors: int = typer.Option(800, "--attractors", help="Attraction points (density of twigs and leaves)."),
    seed: int = seed_option(),
):
    """RGBA leaf-cluster billboard grown by space colonization, with normals, leaf centroids, UVs, AO, depth, type."""
    from treeform.methods.envelope.leaflets import LEAFLET_STAGES, leaflet_billboard

    res = run_api(leaflet_billboard, shape, leaflet=leaflet, size=size, attractors=attractors, seed=seed, out=out,
                  stages=LEAFLET_STAGES)
    typer.echo(f"{res.leaves} leaves on {res.nodes} twig nodes ({shape}); {len(res.files)} files in {out}")
