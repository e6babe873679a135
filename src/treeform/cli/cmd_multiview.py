"""``treeform multiview``: photos taken around one tree -> 3D tree (seed 002)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from treeform.cli.app import (app, HiddenGrowth, IMPOSTOR_HELP, LeafPlacement, LeafTexture, Lod, run_api, seed_option, write_impostor,
                              write_report)


@app.command()
def multiview(
    photos: Path = typer.Argument(..., metavar="PHOTO_DIR", help="Folder of 10-60 photos taken around one tree."),
    out: Path = typer.Option(Path("out/multiview"), "--out", "-o", help="Output directory."),
    seed: int = seed_option(),
    leaves: int = typer.Option(15000, "--leaves", help="Number of leaf clusters (most on the crown surface the photos see)."),
    lod: Lod = typer.Option(Lod.medium, "--lod", help="Level of detail (triangle budget)."),
    leaf_texture: LeafTexture = typer.Option(LeafTexture.photo, "--leaf-texture", help="Leaf cards: the photos' "
                                             "own crown, each card from the photo that sees it best and carved "
                                             "against every view ('photo', default), or drawn clusters tinted with "
                                             "the photos' colours ('procedural': a smaller GLB)."),
    hidden_growth: HiddenGrowth = typer.Option(HiddenGrowth.replication, "--hidden-growth", help="The branches "
                                               "the photos do not see: the seen branches' own subtrees replicated "
                                               "into the crown, then grown toward the leaf points ('replication', "
                                               "default, as Tan et al. 2007 do), or space colonization alone "
                                               "('colonization')."),
    leaf_placement: LeafPlacement = typer.Option(LeafPlacement.surface, "--leaf-placement", help="Where the leaves "
                                                 "go: on the crown surface the photos carve ('surface', default), "
                                                 "or from each photo's leaf regions as Tan et al. 2007 place them "
                                                 "(mean shift, ellipses, placed on the hull, de-duplicated; "
                                                 "'segments')."),
    height: Optional[float] = typer.Option(None, "--height", help="Tree height in metres (default: metric scale "
                                           "from the cameras held at eye height, 1.6 m)."),
    segmenter: str = typer.Option("learned", "--segmenter", help="Tree matting per view: learned or classical."),
    masks: Optional[Path] = typer.Option(None, "--masks", help="Folder of per-photo mattes <photo stem>.png "
                                         "(labels 0/1/2 or white = tree) instead of the segmenter."),
    mask_size: int = typer.Option(768, "--mask-size", help="Long side of each photo's matte in pixels, 64-4096 "
                                  "(the network sees it at 1.25 times this size): finer mattes open more of the "
                                  "crown's gaps and keep thinner limbs, and take longer (24 photos of 1024 px: "
                                  "512 about 15 s faster, 1024 about a minute slower than 768)."),
    refine_poses: bool = typer.Option(True, "--refine-poses/--no-refine-poses", help="Turn each camera so that "
                                      "the other photos' visual hull fills its matte (silhouette coherence; the "
                                      "SfM, held by the far scene, can leave every camera a few pixels off about "
                                      "the tree)."),
    impostor: bool = typer.Option(False, "--impostor", help=IMPOSTOR_HELP),
    report: bool = typer.Option(False, "--report", help="Also write report.html: preview (the model beside three "
                                "photos from their own cameras), metrics, stage times, the tree in a 3D viewer."),
):
    """Several photos around a tree -> 3D tree: SfM, mattes, visual hull, branch graph, growth (Tan et al. 2007)."""
    from treeform.methods.multiview.pipeline import STAGES, reconstruct_multiview

    res = run_api(reconstruct_multiview, photos, stages=STAGES, out=out, seed=seed, leaves=leaves, lod=lod.value,
                  leaf_texture=leaf_texture.value, leaf_placement=leaf_placement.value,
                  hidden_growth=hidden_growth.value,
                  height=height, segmenter=segmenter, masks=masks, refine_poses=refine_poses,
                  mask_size=mask_size,
                  inputs=(("PHOTO_DIR", photos), ("--masks", masks)))
    m = res.metrics
    typer.echo(f"{m['registered']}/{m['photos']} photos registered, tree {m['tree_height_m']:.1f} m, "
               f"{m['nodes']} branch nodes ({m['visible_nodes']} seen), {m['leaves']} leaves, "
               f"silhouette IoU {m['silhouette_iou_median']:.2f} (median over the views), "
               f"{m['total_seconds']:.1f} s -> {out}")
    for key in ("registration_warning", "consistency_warning", "scale_warning"):
        if m.get(key):
            typer.echo(f"warning: {m[key]}", err=True)
    if impostor:
        write_impostor(out, seed)
    if report:
        write_report(out, f"treeform multiview {photos.name} --seed {seed}",
                     preview="preview: the model beside three of the photos, each from its own camera")
