"""``treeform train seg|feet|species|rbv``: train a perception network (needs the ``train`` extra: torch, onnx)."""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from treeform.cli.app import app, run_api, seed_option

train_app = typer.Typer(no_args_is_help=True, help="Train the perception networks on synthetic data (needs torch).")
app.add_typer(train_app, name="train")


@train_app.command("seg")
def seg_cmd(
    data: Path = typer.Option(..., "--data", help="Training dataset (treeform dataset generate)."),
    out: Path = typer.Option(..., "--out", "-o", help="Run directory: checkpoint.pt, model.onnx, metrics.json."),
    test_data: Optional[Path] = typer.Option(None, "--test-data", help="Held-out dataset (another seed) for the test split."),
    cutouts: Optional[Path] = typer.Option(None, "--cutouts", help="Folder of RGBA tree cut-outs (real texture)."),
    photos: Optional[Path] = typer.Option(None, "--photos", help="Folder of real photos: one side of a fixed split "
                                          "becomes out-of-focus backgrounds."),
    steps: int = typer.Option(2800, "--steps", help="Optimiser steps."),
    batch: int = typer.Option(16, "--batch", help="Scenes per step."),
    seed: int = seed_option(),
    device: str = typer.Option("cpu", "--device", help="cpu, cuda or auto (cuda when torch sees one)."),
    workers: int = typer.Option(0, "--workers", help="Processes composing scenes ahead of the optimiser "
                                "(0 = in line; same scenes either way)."),
    init: Optional[Path] = typer.Option(None, "--init", help="Start from these ONNX weights (same architecture): "
                                        "fine-tuning, e.g. of the shipped seg.onnx."),
    lr: float = typer.Option(3e-3, "--lr", help="Peak learning rate (lower when fine-tuning, e.g. 1e-3)."),
    photo_trees: float = typer.Option(0.15, "--photo-trees", help="Share of scenes that are sharp crops of the "
                                      "--photos, their main tree pseudo-labelled by the colour rules (0 = none)."),
    noise: float = typer.Option(0.03, "--noise", help="Share of scenes that are random noise, all background."),
    fine_stride: int = typer.Option(1, "--fine-stride", help="Resolution of the logits: 1 (sub-pixel head) or 4 "
                                    "(plain DeepLab-V3+)."),
    refine: int = typer.Option(0, "--refine", help="Channels of a full-resolution refinement of the logits "
                               "(0 = none; with --fine-stride 1). From --init weights without it, it starts as a no-op."),
    size: int = typer.Option(224, "--size", help="Edge of the square training scenes in pixels (the test scenes too)."),
    width: int = typer.Option(16, "--width", help="SegNet channel base (16: about 0.3 M parameters; 24: 0.7 M)."),
    bushes: float = typer.Option(0.0, "--bushes", help="Share of scenes with leafy bushes behind the tree's foot "
                                 "(labelled background)."),
    sparse_boost: float = typer.Option(0.0, "--sparse-boost", help="Draw cut-outs with weights fill^-BOOST (0 = "
                                       "uniformly; 1 = sparse and leafless trees as often as dense crowns' pixels)."),
    tree_dice: float = typer.Option(0.0, "--tree-dice", help="Weight of a per-scene Dice term on the tree (small and "
                                    "thin trees weigh as much as large crowns)."),
    repeats: int = typer.Option(2, "--repeats", help="Passes (with flips) over each round's composed scenes; more "
                                "when the optimiser outruns the scene composition (a GPU)."),
    chunk: int = typer.Option(256, "--chunk", help="Scenes composed per round (held in memory together; a short run "
                              "needs no more than steps x batch / repeats)."),
    test_scenes: int = typer.Option(400, "--test-scenes", min=2, max=100000,
                                    help="Scenes of the fixed test split scored at the end."),
):
    """Segmentation network (background / foliage / wood); resumes from OUT/checkpoint.pt."""
    from treeform.cli.progress import TrainProgress
    from treeform.learn.train import train_seg

    m = run_api(train_seg, data, out, test_data=test_data, cutouts=cutouts, photos=photos, steps=steps, batch=batch,
                seed=seed, device=device, workers=workers, init=str(init) if init else "", lr=lr,
                fine_stride=fine_stride, refine=refine, photo_tree_fraction=photo_trees, noise_negatives=noise,
                size=size, width=width, repeats=repeats, chunk=chunk, bush_fraction=bushes, sparse_boost=sparse_boost,
                tree_dice=tree_dice, test_scenes=test_scenes, display=TrainProgress("seg"),
                inputs=(("--data", data), ("--test-data", test_data), ("--cutouts", cutouts), ("--photos", photos),
                        ("--init", init)))
    r, c = m.get("renders"), m.get("cutouts")
    if r:
        typer.echo(f"test renders: mean IoU {100 * r['mean_iou']:.1f} % "
                   + ", ".join(f"{k} {100 * v:.1f} %" for k, v in r["iou"].items()))
    if c:
        typer.echo(f"test cut-outs: median tree IoU {c['tree_iou_median']:.3f} over {c['n']} scenes")
    typer.echo(f"weights: {Path(out) / 'model.onnx'}")


@train_app.command("feet")
def feet_cmd(
    cutouts: Path = typer.Option(..., "--cutouts", help="Folder of RGBA tree cut-outs: the 'train' side of a fixed "
                                 "split makes the scenes, the 'test' side scores the run."),
    out: Path = typer.Option(..., "--out", "-o", help="Run directory: checkpoint.pt, model.onnx, metrics.json."),
    photos: Optional[Path] = typer.Option(None, "--photos", help="Folder of real photos: one side of a fixed split "
                                          "becomes blurred backgrounds."),
    renders: Optional[Path] = typer.Option(None, "--renders", help="Synthetic trees (treeform dataset generate, or a "
                                           "sprite pack) drawn beside the cut-outs."),
    render_fraction: float = typer.Option(0.5, "--render-fraction", help="Share of the trees drawn from --renders."),
    behind: float = typer.Option(0.35, "--behind", help="Chance that each tree after a scene's first stands nearly "
                                 "behind another."),
    behind_aside: float = typer.Option(0.1, "--behind-aside", help="How far aside of it, at most, as a share of "
                                       "the scene's width."),
    steps: int = typer.Option(3000, "--steps", help="Optimiser steps."),
    batch: int = typer.Option(16, "--batch", help="Scenes per step."),
    seed: int = seed_option(),
    device: str = typer.Option("cpu", "--device", help="cpu, cuda or auto (cuda when torch sees one)."),
    workers: int = typer.Option(0, "--workers", help="Processes composing scenes ahead of the optimiser "
                                "(0 = in line; same scenes either way)."),
    repeats: int = typer.Option(2, "--repeats", help="Passes (with flips) over each round's composed scenes."),
    init: Optional[Path] = typer.Option(None, "--init", help="Start from these FeetNet ONNX weights (fine-tuning)."),
    lr: float = typer.Option(2e-3, "--lr", help="Peak learning rate (lower when fine-tuning, e.g. 1e-3)."),
    max_minutes: float = typer.Option(0.0, "--max-minutes", help="Stop cleanly (checkpoint, ONNX, metrics) after "
                                      "this many minutes of training (0 = no limit)."),
    test_scenes: int = typer.Option(200, "--test-scenes", min=2, max=100000,
                                    help="Scenes of the fixed test split scored at the end."),
):
    """Trunk-foot detector (heatmap of where each tree meets the ground); resumes from OUT/checkpoint.pt."""
    from treeform.cli.progress import TrainProgress
    from treeform.learn.train_feet import train_feet

    m = run_api(train_feet, cutouts, out, photos=photos, renders=renders, render_fraction=render_fraction,
                behind=behind, behind_aside=behind_aside,
                steps=steps, batch=batch, seed=seed, device=device, workers=workers, repeats=repeats,
                init=str(init) if init else "", lr=lr, max_minutes=max_minutes, test_scenes=test_scenes,
                display=TrainProgress("feet"),
                inputs=(("--cutouts", cutouts), ("--photos", photos), ("--renders", renders), ("--init", init)))
    t = m.get("test") or {}
    if t:
        typer.echo(f"test feet: recall {100 * t['recall']:.1f} %, precision {100 * t['precision']:.1f} %, "
                   f"median error {t['median_error_px']} px")
    typer.echo(f"weights: {Path(out) / 'model.onnx'}")


def _mask_cmd(kind: str, data, out, test_data, seg_weights, epochs, seed):
    from treeform.cli.progress import TrainProgress
    from treeform.learn.train_masks import train_masknet

    m = run_api(train_masknet, kind, data, out, test_data=test_data, seg_weights=seg_weights, epochs=epochs, seed=seed,
                display=TrainProgress(kind),
                inputs=(("--data", data), ("--test-data", test_data), ("--seg-weights", seg_weights)))
    for which, name in (("gt", "true masks"), ("pred", "predicted masks")):
        r = (m.get("test") or {}).get(which)
        if r and kind == "species":
            typer.echo(f"test {name}: accuracy {100 * r['accuracy']:.1f} %")
        elif r:
            typer.echo(f"test {name}: MAE per level " + " ".join(f"L{i + 1} {e:.2f} %" for i, e in enumerate(r["mae_percent"])))
    typer.echo(f"weights: {Path(out) / 'model.onnx'}")


_SEG_W = typer.Option(None, "--seg-weights", help="Segmentation ONNX: its predicted masks join training and testing.")


def _register_mask_command(kind: str, doc: str) -> None:
    def command(
        data: Path = typer.Option(..., "--data", help="Training dataset (treeform dataset generate)."),
        out: Path = typer.Option(..., "--out", "-o", help="Run directory."),
        test_data: Optional[Path] = typer.Option(None, "--test-data", help="Held-out dataset (another seed)."),
        seg_weights: Optional[Path] = _SEG_W,
        epochs: int = typer.Option(40, "--epochs", help="Passes over the data."),
        seed: int = seed_option(),
    ):
        _mask_cmd(kind, data, out, test_data, seg_weights, epochs, seed)

    command.__doc__ = doc
    train_app.command(kind)(command)


_register_mask_command("species", "Species CNN on semantic masks (7 species); resumes from OUT/checkpoint.pt.")
_register_mask_command("rbv", "Cascaded RBV CNN (levels 1-5, Huber loss) on semantic masks; resumes from OUT/checkpoint.pt.")
