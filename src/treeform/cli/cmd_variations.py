"""``treeform library process``, ``vary``, ``morph``, ``billboard``: image-based tree variations (seed 000)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from treeform.cli.app import app, run_api, seed_option, SEGMENTER_OPTION, SegmenterName

library_app = typer.Typer(no_args_is_help=True, help="Libraries of RGBA tree images (exemplars for `treeform vary`).")
app.add_typer(library_app, name="library")

_CACHE = typer.Option(None, "--cache", help="Exemplar cache directory (default: $TREEFORM_CACHE_DIR or ~/.cache).")


@library_app.command("process")
def library_process(
    directory: Path = typer.Argument(..., metavar="LIBRARY", help="Directory of RGBA tree images (.png, .webp, .tif)."),
    cache: Optional[Path] = _CACHE,
    sheet: Optional[Path] = typer.Option(None, "--sheet", help="Also write a contact sheet of the exemplars (PNG)."),
):
    """Process every tree of a library once: normalise, segment crown/trunk, contours (cached)."""
    from treeform.methods.variations.pipeline import LIBRARY_STAGES, process_library

    lib = run_api(process_library, directory, cache_dir=cache, sheet=sheet, stages=LIBRARY_STAGES)
    trunks = sum(e.has_trunk for e in lib.exemplars)
    typer.echo(f"{len(lib)} exemplars ({trunks} with a trunk, {lib.from_cache} from the cache) in {lib.cache_dir}")


@app.command("vary")
def vary_cmd(
    library: Path = typer.Argument(..., metavar="LIBRARY", help="Directory of RGBA tree images."),
    n: int = typer.Option(20, "-n", help="Number of variations."),
    out: Path = typer.Option(..., "--out", "-o", help="Output directory (PNGs, contact_sheet.png, config.json)."),
    from_tree: Optional[Path] = typer.Option(None, "--from", help="Make variations of this RGBA tree."),
    seed: int = seed_option(),
    season: Optional[Path] = typer.Option(None, "--season", help="Photo of a tree whose crown and trunk colours the new trees take (only the tree's pixels count)."),
    any_form: bool = typer.Option(False, "--any-form", help="Blend trees of any growth form (default: broadleaf with broadleaf, conifer with conifer, palm with palm)."),
    cache: Optional[Path] = _CACHE,
):
    """New tree images: each a random blend of the library's tree shapes, coloured from them."""
    from treeform.methods.variations.pipeline import vary, vary_stages

    res = run_api(vary, library, n=n, out=out, from_tree=from_tree, season=season, cache_dir=cache, seed=seed,
                  any_form=any_form, stages=vary_stages(n), inputs=(library, ("--from", from_tree), ("--season", season)))
    typer.echo(f"{len(res.images)} variations and contact_sheet.png in {out}")


@app.command("morph")
def morph_cmd(
    a: Path = typer.Argument(..., metavar="TREE_A", help="First RGBA tree."),
    b: Path = typer.Argument(..., metavar="TREE_B", help="Second RGBA tree."),
    steps: int = typer.Option(7, "--steps", help="Number of frames, t = 0 .. 1."),
    out: Path = typer.Option(..., "--out", "-o", help="Strip of frames (PNG)."),
    cache: Optional[Path] = _CACHE,
):
    """Morph one tree image into another, in STEPS frames."""
    from treeform.methods.variations.pipeline import MORPH_STAGES, morph

    run_api(morph, a, b, steps=steps, out=out, cache_dir=cache, stages=MORPH_STAGES, inputs=(a, b))
    typer.echo(f"{steps} frames in {out}")


@app.command("billboard")
def billboard_cmd(
    photo: Path = typer.Argument(..., metavar="PHOTO", help="Photo of a tree (JPEG, PNG, ...)."),
    out: Path = typer.Option(..., "--out", "-o", help="RGBA billboard (PNG)."),
    sheet: Optional[Path] = typer.Option(None, "--sheet", help="Also write photo | trimap | billboard (PNG)."),
    seed: int = seed_option(),
    sky_gaps: bool = typer.Option(False, "--sky-gaps/--no-sky-gaps", help="Also make sky seen through gaps in the crown transparent."),
    segmenter: SegmenterName = SEGMENTER_OPTION,
):
    """Photo -> RGBA billboard: the tree cut out of its background with a soft alpha (matting)."""
    from treeform.methods.variations.pipeline import BILLBOARD_STAGES, billboard

    res = run_api(billboard, photo, out=out, sheet=sheet, seed=seed, sky_gaps=sky_gaps, segmenter=segmenter.value,
                  stages=BILLBOARD_STAGES)
    typer.echo(f"{out}: {res.rgba.shape[1]}x{res.rgba.shape[0]} RGBA, IoU with the segmentation {res.metrics['iou']:.3f}")
