"""Training of the trunk-foot detector (``treeform train feet``; torch, the optional ``train`` extra).

:class:`~treeform.learn.nets.feetnet.FeetNet` learns on an endless stream of
:func:`~treeform.dataset.feet_scenes.feet_scene` scenes (:class:`~treeform.learn.feet.FeetStream`)
built from the 'train' side of the RGBA cut-outs (never the package's library trees: those
are ``benchmarks/bench_scene.py``'s) over lawns, procedural backgrounds and blurred real
photos. The loss is CenterNet's: a penalty-reduced focal loss on the heatmap (Gaussian targets
of :func:`~treeform.learn.feet.feet_targets`, no loss near a hidden foot) plus an L1 loss on
the sub-cell offset at each foot's cell. As ``treeform train seg`` (:mod:`treeform.learn.train`),
a run is seeded, writes ``checkpoint.pt`` atomically and resumes from it, reports progress,
composes scenes in worker processes when asked and ends with ``model.onnx`` and
``metrics.json`` (recall / precision of the feet on the 'test' side of the cut-outs).

This module is never imported by inference.
"""

from __future__ import annotations

import functools
import json
import time
from dataclasses import asdict, dataclass

import numpy as np

from treeform._shared.errors import InputError

__all__ = ["FeetTrainConfig", "train_feet"]


@dataclass
class FeetTrainConfig:
    """Settings of ``treeform train feet`` (stored in the run's ``config.json``)."""

    steps: int = 3000
    """Optimiser steps."""
    batch: int = 16
    """Scenes per step."""
    width: int = 384
    """Width of the training scenes in pixels (a multiple of 16; the runtime sees a photo's long side at this)."""
    height: int = 288
    """Height of the training scenes (a multiple of 16)."""
    channels: int = 16
    """FeetNet channel base."""
    lr: float = 2e-3
    """Peak AdamW learning rate (warm-up, then cosine decay to 2 %)."""
    weight_decay: float = 1e-4
    offset_weight: float = 1.0
    """Weight of the L1 offset loss beside the focal loss."""
    empty: float = 0.08
    """Share of scenes without a tree."""
    render_fraction: float = 0.5
    """Share of the trees drawn from the synthetic renders (when ``renders`` are given)."""
    behind: float = 0.35
    """Chance that each tree after a scene's first stands nearly behind another
    (:func:`~treeform.dataset.feet_scenes.feet_scene`)."""
    behind_aside: float = 0.1
    """How far aside of it, at most, as a share of the scene's width."""
    init: str = ""
    """ONNX weights of a FeetNet of the same width to start from (fine-tuning)."""
    chunk: int = 128
    """Scenes composed per round."""
    repeats: int = 2
    """Passes (with flips) over each round's scenes before the next round."""
    seed: int = 0
    checkpoint_every: int = 100
    threads: int = 0
    """torch CPU threads (0 = all cores)."""
    device: str = "cpu"
    """Where the network trains: 'cpu', 'cuda' or 'auto'."""
    workers: int = 0
    """Processes composing rounds ahead of the optimiser (0 = in line; the scenes are the same either way)."""
    test_scenes: int = 200
    """Scenes of the fixed test split scored at the end."""
    max_minutes: float = 0.0
    """Stop cleanly (checkpoint, ONNX, metrics) after this many minutes of optimisation (0 = no limit)."""

    def __post_init__(self):
        """Every setting in its range, before anything is written or imported (one line for the CLI)."""
        import re

        from treeform._shared.checks import check_int, check_range
        from treeform._shared.rng import check_seed

        for name, lo, hi in (("steps", 1, 10**7), ("batch", 1, 4096), ("channels", 4, 128), ("chunk", 1, 10**5),
                             ("repeats", 1, 100), ("checkpoint_every", 1, 10**7), ("threads", 0, 1024),
                             ("workers", 0, 256), ("test_scenes", 2, 10**5)):
            check_int(getattr(self, name), name, lo, hi)
        check_seed(self.seed)
        for name in ("width", "height"):
            check_int(getattr(self, name), name, 64, 2048)
            if getattr(self, name) % 16:
                raise InputError(f"{name}: expected a multiple of 16 (the network's stride), got {getattr(self, name)}")
        check_range(self.lr, "lr", 1e-7, 1.0)
        check_range(self.weight_decay, "weight_decay", 0.0, 1.0)
        check_range(self.offset_weight, "offset_weight", 0.0, 100.0)
        check_range(self.empty, "empty", 0.0, 1.0)
        check_range(self.render_fraction, "render_fraction", 0.0, 1.0)
        check_range(self.behind, "behind", 0.0, 1.0)
        check_range(self.behind_aside, "behind_aside", 0.005, 1.0)
        check_range(self.max_minutes, "max_minutes", 0.0, 10**6)
        if not re.fullmatch(r"cpu|auto|cuda(:\d+)?|mps", str(self.device)):
            raise InputError(f"device: expected cpu, cuda, cuda:N, mps or auto, got {self.device!r}")

    @classmethod
    def from_dict(cls, d: dict) -> "FeetTrainConfig":
        from treeform._shared.checks import check_known_options

        return cls(**check_known_options(cls, d))


def _feet_stream(cutouts, photos, renders, *, size, seed, empty, render_fraction, behind=0.35, behind_aside=0.1):
    """The training :class:`~treeform.learn.feet.FeetStream` (also built in each worker process)."""
    from treeform.dataset.scenes import load_cutouts, load_photos
    from treeform.learn.data import render_sprites
    from treeform.learn.feet import FeetStream

    sprites = load_cutouts(cutouts, split="train")
    bg = load_photos(photos, split="train") if photos is not None else []
    rend = render_sprites(renders) if renders is not None else []
    return FeetStream(sprites, size=size, seed=seed, photos=bg, empty=empty, renders=rend,
                      render_fraction=render_fraction, behind=behind, behind_aside=behind_aside)


def _batch_targets(feet, visible, n_rows: int, n_cols: int):
    """Stacked :func:`~treeform.learn.feet.feet_targets` of a batch: heat (B, h, w), offset (B, 2, h, w), weight."""
    from treeform.learn.feet import feet_targets

    t = [feet_targets(f, v, (n_rows, n_cols)) for f, v in zip(feet, visible)]
    return (np.stack([a for a, _, _ in t]), np.stack([b for _, b, _ in t]), np.stack([c for _, _, c in t]))


def _focal_loss(torch, out, heat, offset, weight, offset_weight: float):
    """CenterNet's penalty-reduced focal loss (alpha 2, beta 4) + L1 offsets at the feet's cells."""
    logit = out[:, 0]
    p = torch.sigmoid(logit).clamp(1e-4, 1 - 1e-4)
    pos = (heat >= 1.0).float()
    neg = (1.0 - pos) * weight
    pos_loss = -(torch.log(p) * (1 - p) ** 2 * pos).sum()
    neg_loss = -(torch.log(1 - p) * p ** 2 * (1 - heat) ** 4 * neg).sum()
    n_pos = pos.sum().clamp(min=1.0)
    off = (torch.abs(torch.sigmoid(out[:, 1:3]) - offset) * pos[:, None]).sum() / n_pos
    return (pos_loss + neg_loss) / n_pos + offset_weight * off


def _load_head(model, path) -> None:
    """The head's weights from an exported FeetNet (its output is the graph's, so
    :func:`~treeform.learn.export.load_onnx_into` cannot match it by name; its parameters keep theirs)."""
    import onnx
    import torch
    from onnx import numpy_helper

    inits = {i.name: numpy_helper.to_array(i) for i in onnx.load(str(path)).graph.initializer}
    if "head.weight" not in inits or tuple(inits["head.weight"].shape) != tuple(model.head.weight.shape):
        raise InputError(f"{path}: no FeetNet head of this width (another architecture?)")
    with torch.no_grad():
        model.head.weight.copy_(torch.from_numpy(inits["head.weight"].copy()))
        model.head.bias.copy_(torch.from_numpy(inits["head.bias"].copy()))


def train_feet(cutouts, out, *, photos=None, renders=None, config: FeetTrainConfig | None = None, progress=None, **options) -> dict:
    """Train the trunk-foot detector; resume from ``out/checkpoint.pt`` when present.

    Parameters
    ----------
    cutouts : path
        RGBA tree cut-outs (e.g. ``../shared/data/billboards``); the 'train' side of
        :func:`~treeform.dataset.scenes.cutout_split` makes the scenes, the 'test' side the test split.
    out : path
        Run directory: ``checkpoint.pt``, ``config.json``, ``log.csv``, ``model.onnx``, ``metrics.json``.
    photos : path, optional
        Real photos; the 'train' side of :func:`~treeform.dataset.scenes.photo_split` serves as
        blurred backgrounds.
    renders : path, optional
        A dataset of ``treeform dataset generate`` or a sprite pack of
        :func:`~treeform.learn.data.save_sprites`: synthetic trees, a share ``render_fraction`` of the trees.
    config : FeetTrainConfig, optional
    progress : callable, optional
        ``progress(done, total, info)`` with ``info = {"loss", "images_per_s"}``.

    Returns
    -------
    dict
        The test metrics (also in ``out/metrics.json``).
    """
    from treeform.learn.train import _Rounds, _device, _init_from_onnx, _lr_at, _open_run, _resume, _save_atomic

    cfg = FeetTrainConfig.from_dict({**(asdict(config) if config else {}), **options})  # checked first
    out, torch = _open_run(cfg, out)
    from treeform.learn.nets.feetnet import FeetNet

    size = (cfg.width, cfg.height)
    make_stream = functools.partial(_feet_stream, cutouts, photos, renders, size=size, seed=cfg.seed, empty=cfg.empty,
                                    render_fraction=cfg.render_fraction, behind=cfg.behind,
                                    behind_aside=cfg.behind_aside)
    dev = _device(torch, cfg.device)
    torch.manual_seed(cfg.seed)
    model = FeetNet(cfg.channels).to(dev)
    opt = torch.optim.AdamW(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    ckpt_path = out / "checkpoint.pt"
    step, prior_seconds = _resume(torch, ckpt_path, model, opt, asdict(FeetTrainConfig()), asdict(cfg),
                                  ignore=("max_minutes",))
    (out / "config.json").write_text(json.dumps({"network": "feet", "cutouts": str(cutouts), "photos": str(photos),
                                                 "renders": str(renders), **asdict(cfg)}, indent=2))
    per_round = max(1, cfg.chunk * cfg.repeats // cfg.batch)
    rounds = _Rounds(make_stream, cfg.chunk, cfg.workers)
    if cfg.init and step == 0:
        _init_from_onnx(torch, model, cfg.init, rounds, dev, new_layers=("head",))
        _load_head(model, cfg.init)
    from treeform.learn.feet import STRIDE

    rows, cols = cfg.height // STRIDE, cfg.width // STRIDE
    model.train()
    t0, seen, loss_avg, cur_round = time.perf_counter(), 0, None, -1
    images = feet = vis = order = None
    try:
        while step < cfg.steps:
            if cfg.max_minutes and time.perf_counter() - t0 > 60 * cfg.max_minutes:
                break
            r = step // per_round
            if r != cur_round:
                images, feet, vis = rounds.get(r)
                order = np.random.default_rng([cfg.seed, 9, r]).permutation(np.tile(np.arange(cfg.chunk), cfg.repeats))
                cur_round = r
            k = step % per_round
            idx = order[k * cfg.batch:(k + 1) * cfg.batch]
            flip = np.random.default_rng([cfg.seed, 10, step]).random(len(idx)) < 0.5
            x = images[idx].copy()
            x[flip] = x[flip][:, :, ::-1]
            fb = [np.c_[cfg.width - 1 - feet[i][:, 0], feet[i][:, 1]] if fl else feet[i] for i, fl in zip(idx, flip)]
            heat, offset, weight = _batch_targets(fb, [vis[i] for i in idx], rows, cols)
            xt = torch.from_numpy(np.ascontiguousarray(x)).to(dev).permute(0, 3, 1, 2).float().div_(255.0)
            for g in opt.param_groups:
                g["lr"] = _lr_at(step, cfg.steps, cfg.lr)
            loss = _focal_loss(torch, model(xt), torch.from_numpy(heat).to(dev), torch.from_numpy(offset).to(dev),
                               torch.from_numpy(weight).to(dev), cfg.offset_weight)
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            step += 1
            seen += len(idx)
            lv = loss.item()
            loss_avg = lv if loss_avg is None else 0.98 * loss_avg + 0.02 * lv
            dt = time.perf_counter() - t0
            if progress is not None:
                progress(step, cfg.steps, {"loss": loss_avg, "images_per_s": seen / dt if dt > 0 else 0.0})
            if step % cfg.checkpoint_every == 0 or step == cfg.steps:
                with open(out / "log.csv", "a") as fh:
                    fh.write(f"{step},{loss_avg:.5f},{_lr_at(step - 1, cfg.steps, cfg.lr):.6f},{seen / dt:.2f}\n")
                _save_atomic({"model": model.state_dict(), "optimizer": opt.state_dict(), "step": step,
                              "config": asdict(cfg), "seconds": prior_seconds + dt}, ckpt_path)
    finally:
        rounds.close()
    dt = time.perf_counter() - t0
    if step % cfg.checkpoint_every:  # stopped by max_minutes between checkpoints
        _save_atomic({"model": model.state_dict(), "optimizer": opt.state_dict(), "step": step,
                      "config": asdict(cfg), "seconds": prior_seconds + dt}, ckpt_path)
    model = model.cpu().eval()
    from treeform.learn.export import export_onnx

    onnx_path = export_onnx(model, out / "model.onnx", kind="feet", example_shape=(1, 3, cfg.height, cfg.width),
                            metadata={"train_steps": step, "infer_side": max(cfg.width, cfg.height),
                                      "channels": cfg.channels})
    metrics = {"train_seconds": round(prior_seconds + dt, 1), "steps": step, "device": dev.type,
               "parameters": int(sum(p.numel() for p in model.parameters()))}
    metrics["test"] = evaluate_feet(onnx_path, cutouts, photos, n=cfg.test_scenes, size=size)
    (out / "metrics.json").write_text(json.dumps(metrics, indent=2))
    return metrics


def evaluate_feet(weights, cutouts, photos=None, *, n: int = 200, size: tuple = (384, 288)) -> dict:
    """Recall / precision / median error (pixels) of the feet found by ``weights`` on the fixed test split
    (the 'test' side of the cut-outs and photos); a found foot within 3 % of the width matches."""
    from treeform.dataset.scenes import load_cutouts, load_photos
    from treeform.learn.feet import feet_test_scenes, score_feet
    from treeform.learn.infer import FeetDetector

    try:
        sprites = load_cutouts(cutouts, split="test")
    except InputError:
        return {}
    bg = load_photos(photos, split="test") if photos is not None else []
    images, feet, vis = feet_test_scenes(sprites, n=n, size=size, photos=bg)
    det = FeetDetector(weights)
    found = [det.detect(im) for im in images]
    return score_feet(found, feet, vis, tolerance=0.03 * size[0])
