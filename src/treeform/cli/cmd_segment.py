"""``treeform segment``: the tree's pixels of a photo as labels (0 background, 1 foliage, 2 wood)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from treeform.cli.app import app, run_api, seed_option, SEGMENTER_OPTION, SegmenterName


PHOTO_HELP = "Photo of a tree (JPEG, PNG, HEIC, ...), or a cut-out (RGBA PNG / WebP): its alpha is the tree."


@app.command("segment")
def segment_cmd(
    photo: Path = typer.Argument(..., metavar="PHOTO", help=PHOTO_HELP),
    out: Optional[Path] = typer.Option(None, "--out", "-o", help="labels.png: 8-bit, 0 background, 1 foliage, 2 wood."),
    overlay: Optional[Path] = typer.Option(None, "--overlay", help="Also write the photo with the labels tinted (PNG)."),
    mask: Optional[Path] = typer.Option(None, "--mask", help="Also write the tree as a white-on-black mask "
                                                             "(what `reconstruct --mask` reads)."),
    wood: Optional[Path] = typer.Option(None, "--wood", help="Also write the trunk and branches as a white-on-black "
                                                             "mask (what `grow --mask` reads)."),
    segmenter: SegmenterName = SEGMENTER_OPTION,
    seed: int = seed_option(help="Seed of the classical graph cut."),
):
    """Segment the main tree of a photo: background / foliage / wood labels at the photo's size."""
    from treeform.methods.learned.perception import SEGMENT_STAGES, segment_photo

    if out is None and overlay is None and mask is None and wood is None:
        typer.echo("error: nothing to write: give --out labels.png and/or --overlay, --mask, --wood", err=True)
        raise typer.Exit(2)
    res = run_api(segment_photo, photo, out=out, overlay=overlay, mask=mask, wood=wood, segmenter=segmenter.value,
                  seed=seed, stages=SEGMENT_STAGES)
    f = res.fractions
    h, w = res.segmentation.shape
    typer.echo(f"{w}x{h} photo: foliage {100 * f['foliage']:.1f} %, wood {100 * f['wood']:.1f} % -> "
               + ", ".join(str(p) for p in res.files.values()))


@app.command("species")
def species_cmd(
    photo: Path = typer.Argument(..., metavar="PHOTO", help=PHOTO_HELP),
    json_out: bool = typer.Option(False, "--json", help="Print all probabilities as JSON."),
    segmenter: SegmenterName = typer.Option(SegmenterName.learned, "--segmenter",
                                            help="Segmentation the species network reads (it was trained on "
                                                 "the learned one's masks)."),
    seed: int = seed_option(help="Seed of the classical graph cut."),
):
    """Species of the main tree of a photo: the top 3 of the seven presets with probabilities."""
    import json

    from treeform.methods.learned.perception import SPECIES_STAGES, classify_species

    probs = run_api(classify_species, photo, segmenter=segmenter.value, seed=seed, stages=SPECIES_STAGES)
    if json_out:
        typer.echo(json.dumps({k: round(v, 4) for k, v in probs.items()}))
    else:
        for name, p in list(probs.items())[:3]:
            typer.echo(f"{name:<8} {p:.3f}")
