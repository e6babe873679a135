"""``treeform forest``: thousands of impostor trees drawn with the LoD switch, timed (seed 001 §5.1)."""

from __future__ import annotations

from pathlib import Path

import typer

from treeform.cli.app import app, run_api, seed_option


@app.command("forest")
def forest_cmd(
    species_dir: Path = typer.Option(..., "--species-dir", help="Folder of tree output folders, each with impostor/ "
                                     "(`treeform impostor TREE_DIR`)."),
    out: Path = typer.Option(..., "--out", "-o", help="Output folder (frames/, contact_sheet.png, timing.json)."),
    trees: int = typer.Option(1000, "--trees", help="Tree instances scattered over the ground (blue noise)."),
    area: str = typer.Option("400x400", "--area", help="Ground width x depth in metres, e.g. 2000x2000."),
    switch_distance: float = typer.Option(200.0, "--switch-distance", help="LoD switch d in metres: billboard "
                                          "clouds nearer, relief impostors beyond."),
    card_px: float = typer.Option(32.0, "--card-px", help="Far crowns narrower than this many pixels on screen are "
                                  "drawn as impostor cards instead of the relief march (0: the relief for all)."),
    frames: int = typer.Option(4, "--frames", help="Frames of the fly-through."),
    size: str = typer.Option("1920x1080", "--size", help="Frame size in pixels, WxH."),
    baseline: bool = typer.Option(False, "--baseline", help="Also draw every frame with full meshes (tree.glb) and "
                                  "record baseline_ms_per_frame and the speed-up."),
    glb: bool = typer.Option(False, "--glb", help="Also write forest.glb: each species' impostor cards drawn at "
                             "its trees with EXT_mesh_gpu_instancing (for game engines and web viewers)."),
    html: bool = typer.Option(False, "--html", help="Also write forest.html: the forest in a browser (three.js, "
                              "offline), relief impostors and clipped billboard clouds with the renderer's own shaders."),
    seed: int = seed_option(help="Seed of the scatter (positions, scales, turns, species)."),
):
    """Scatter impostor trees over a ground and render a fly-through: clipped billboard clouds near, relief far."""
    from treeform.methods.envelope.forest import FOREST_STAGES, render_forest

    res = run_api(render_forest, species_dir, out=out, trees=trees, area=area, switch_distance=switch_distance,
                  frames=frames, size=size, card_px=card_px, baseline=baseline, glb=glb, html=html, seed=seed, stages=FOREST_STAGES,
                  inputs=[("--species-dir", species_dir)])
    t = res.timing
    line = (f"forest of {len(res.instances)} trees, {t['frames']} frames of {t['size'][0]}x{t['size'][1]}: "
            f"{t['visible_trees']:.0f} visible ({t['near_trees']:.0f} as billboard clouds, "
            f"{t['card_trees']:.0f} as impostor cards), "
            f"{t['ms_per_frame']:.0f} ms a frame")
    if baseline:
        line += f"; full meshes {t['baseline_ms_per_frame']:.0f} ms ({t['speedup']:.1f}x slower)"
    typer.echo(f"{line} -> {out}")
