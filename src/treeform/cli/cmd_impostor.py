"""``treeform impostor``: colour cubemap and radial distance map of a tree, for rendering it at distance."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from treeform.cli.app import app, run_api, seed_option


@app.command("impostor")
def impostor_cmd(
    tree_dir: Path = typer.Argument(..., metavar="TREE_DIR", help="Output folder of a treeform run (its tree.glb)."),
    out: Optional[Path] = typer.Option(None, "--out", "-o", help="Output folder (default TREE_DIR/impostor)."),
    face: int = typer.Option(256, "--face", help="Edge of a colour cubemap face, texels (canvas 4F x 3F)."),
    rdm_resolution: int = typer.Option(128, "--rdm-resolution", help="Edge of a radial distance map face, texels."),
    seed: int = seed_option(help="Seed of the texture synthesis."),
    colors: str = typer.Option("synthesis", "--colors", help="Colour cubemap: 'synthesis' (from the front view: all a "
                               "single photo shows) or 'baked' (the mesh's own colours from all round: a grown or "
                               "multi-view tree)."),
    engine: Optional[str] = typer.Option(None, "--engine", help="Also write impostor/engine/: lod0.glb (full mesh), "
                                         "lod1.glb (billboard cloud), lod2.glb (impostor cards) and lods.json, "
                                         "switching at NEAR,FAR metres, e.g. 40,200."),
    opacity: int = typer.Option(96, "--opacity", help="Voxels along the edge of opacity.npz, the leaves' and wood's "
                                "extinction per voxel: the relief impostor sees through the crown's gaps as the mesh "
                                "does from afar (0: none; the relief is then the RDM's solid envelope)."),
):
    """Synthesize the tree's colour cubemap from its front view (seamless over every cube edge) and its RDM."""
    from treeform.methods.envelope.impostor import IMPOSTOR_STAGES, make_impostor

    from treeform.cli.app import _fail

    switch = None
    if engine is not None:
        try:
            switch = tuple(float(x) for x in engine.split(","))
        except ValueError:
            _fail(f"--engine: expected NEAR,FAR in metres, e.g. 40,200, got {engine!r}", 2)
        if len(switch) != 2:
            _fail(f"--engine: expected NEAR,FAR in metres, e.g. 40,200, got {engine!r}", 2)
    res = run_api(make_impostor, tree_dir, out=out, face=face, rdm_resolution=rdm_resolution, seed=seed,
                  colors=colors, engine=switch, opacity_resolution=opacity, stages=IMPOSTOR_STAGES,
                  inputs=[tree_dir])
    t = res.manifest["timings"]
    typer.echo(f"impostor of {tree_dir}: 6 colour faces of {face}² and an RDM of 6 x {rdm_resolution}² "
               f"(mean radius {res.rdm.mean_radius():.2f} m)"
               f"{f', an opacity grid of {opacity}³' if res.opacity is not None else ''} in {sum(t.values()):.1f} s -> "
               f"{Path(next(iter(res.files.values()))).parent}")
