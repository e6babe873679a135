"""``treeform animate``: a tree swaying in the wind, as a looping animated GLB."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from treeform.cli.app import app, run_api, seed_option


@app.command("animate")
def animate_cmd(
    tree_dir: Path = typer.Argument(..., metavar="TREE_DIR", help="Output folder of treeform grow or reconstruct "
                                    "(skeleton.json + tree.glb)."),
    wind: float = typer.Option(6.0, "--wind", help="Mean wind speed, m/s (6 a breeze, 15 a strong wind)."),
    direction: float = typer.Option(0.0, "--direction", help="Where the wind blows towards, degrees about the "
                                    "vertical (0 = +X, 90 = +Z)."),
    seconds: float = typer.Option(4.0, "--seconds", help="Length of the loop, seconds."),
    fps: int = typer.Option(30, "--fps", help="Keyframes per second."),
    seed: int = seed_option(help="Seed of the gusts."),
    out: Optional[Path] = typer.Option(None, "--out", "-o", help="Animated GLB (default TREE_DIR/tree_animated.glb)."),
):
    """Sway a tree in a turbulent wind (rod dynamics per branch) and write a looping, skinned glTF."""
    from treeform.animate.tree import STAGES, animate_tree

    res = run_api(animate_tree, tree_dir, out=out, wind=wind, direction=direction, seconds=seconds, fps=fps,
                  seed=seed, stages=STAGES, inputs=[tree_dir])
    typer.echo(f"{res['path']}: {res['joints']} joints, {res['frames']} frames looping every {res['period']:g} s; "
               f"trunk moves up to {res['trunk_motion']:.2f} m, branch tips {res['tip_motion']:.2f} m")
