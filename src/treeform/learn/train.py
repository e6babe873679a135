"""Training of the perception networks (torch, the optional ``train`` extra; seed 003 §4.2).

``treeform train seg --data DIR --out DIR`` trains :class:`~treeform.learn.nets.segnet.SegNet`
on randomised scenes (:class:`~treeform.learn.data.SceneStream`) built from a dataset of
``treeform dataset generate`` plus, when given, real photo cut-outs. Every run:

- is seeded: same data + seed + config -> the same scene stream and initialisation
  (bit-identical weights on the same machine and thread count);
- writes ``checkpoint.pt`` atomically every ``checkpoint_every`` steps and resumes from it
  after a kill (the scene stream is a function of the round, so a resumed run sees the
  same data as an uninterrupted one);
- reports ``progress(done, total, info)`` with the loss and images/s (the CLI draws it);
- ends with ``model.onnx`` (:func:`treeform.learn.export.export_onnx`) and ``metrics.json``
  on the fixed test split.

This module is never imported by inference (``treeform reconstruct`` / ``segment``).
"""

from __future__ import annotations

import json
import math
import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from treeform._shared.errors import InputError

__all__ = ["SegTrainConfig", "train_seg", "evaluate_segmenter"]


def _torch():
    try:
        import torch
    except ImportError:
        raise InputError("training needs torch: pip install 'treeform[train]'") from None
    return torch


@dataclass
class SegTrainConfig:
    """Settings of ``treeform train seg`` (stored in the run's ``config.json``)."""

    steps: int = 2800
    """Optimiser steps."""
    batch: int = 16
    """Scenes per step."""
    size: int = 224
    """Edge of the square training scenes."""
    width: int = 16
    """SegNet channel base."""
    fine_stride: int = 1
    """Resolution of SegNet's logits (1 = the scene's own pixels; 4 = plain DeepLab-V3+)."""
    lr: float = 3e-3
    """Peak AdamW learning rate (warm-up, then cosine decay to 2 %)."""
    weight_decay: float = 1e-4
    wood_weight: float = 3.0
    """Cross-entropy weight of wood pixels (thin, rare) and of the wood Dice term."""
    chunk: int = 256
    """Scenes composed per round (each round's scenes are used for chunk / batch steps... twice)."""
    repeats: int = 2
    """Passes over each round's scenes (with flips) before the next round."""
    cutout_fraction: float = 0.35
    negatives: float = 0.08
    photo_fraction: float = 0.2
    """Share of scenes over an out-of-focus crop of a real photo (when ``photos`` are given)."""
    seed: int = 0
    checkpoint_every: int = 100
    threads: int = 0
    """torch CPU threads (0 = all cores)."""

    @classmethod
    def from_dict(cls, d: dict) -> "SegTrainConfig":
        from treeform._shared.checks import check_known_options

        return cls(**check_known_options(cls, d))


def _partial_ce(logits, labels, wood_weight: float):
    """Cross-entropy with partial labels: 0/1/2 as usual, 3 = 'foliage or wood' (log of their summed prob)."""
    torch = _torch()
    logp = torch.log_softmax(logits, 1)
    lab = labels.long()
    known = lab.clamp(max=2)
    nll = -logp.gather(1, known[:, None])[:, 0]
    nll_any = -torch.logsumexp(logp[:, 1:3], 1)
    nll = torch.where(lab == 3, nll_any, nll)
    w = torch.where(lab == 2, torch.full_like(nll, wood_weight), torch.ones_like(nll))
    ce = (nll * w).sum() / w.sum()
    # Dice on wood over the scenes whose parts are known (synthetic renders)
    known_img = (lab != 3).flatten(1).all(1)
    if known_img.any():
        p = torch.softmax(logits, 1)[:, 2][known_img]
        t = (lab[known_img] == 2).float()
        dice = 1 - (2 * (p * t).sum() + 1) / (p.sum() + t.sum() + 1)
    else:
        dice = logits.sum() * 0
    return ce + 0.5 * wood_weight / 2.5 * dice


def _save_atomic(obj, path: Path) -> None:
    torch = _torch()
    tmp = path.with_name(path.name + ".tmp")
    torch.save(obj, tmp)
    os.replace(tmp, path)


def _lr_at(step: int, total: int, peak: float) -> float:
    warm = max(1, total // 30)
    if step < warm:
        return peak * (step + 1) / warm
    t = (step - warm) / max(1, total - warm)
    return peak * (0.02 + 0.98 * 0.5 * (1 + math.cos(math.pi * t)))


def _sprites(data, cutouts, split: str):
    from treeform.dataset.scenes import load_cutouts
    from treeform.learn.data import render_sprites

    renders = render_sprites(data) if data is not None else []
    cuts = load_cutouts(cutouts, split=split) if cutouts is not None else []
    return renders, cuts


def train_seg(data, out, *, test_data=None, cutouts=None, photos=None, config: SegTrainConfig | None = None, progress=None,
              **options) -> dict:
    """Train the segmentation network; resume from ``out/checkpoint.pt`` when present.

    Parameters
    ----------
    data : path
        A dataset of ``treeform dataset generate`` (training trees).
    out : path
        Run directory: ``checkpoint.pt``, ``config.json``, ``model.onnx``, ``metrics.json``.
    test_data : path, optional
        A dataset generated with another seed (the held-out trees of the test split).
    cutouts : path, optional
        RGBA photo cut-outs; the 'train' side of :func:`~treeform.dataset.scenes.cutout_split`
        joins training, the 'test' side the test split.
    photos : path, optional
        Real photos; the 'train' side of :func:`~treeform.dataset.scenes.photo_split` serves
        as out-of-focus backgrounds (the 'test' side is left to the real-texture benchmark).
    config : SegTrainConfig, optional
    progress : callable, optional
        ``progress(done, total, info)`` with ``info = {"loss", "images_per_s"}``.

    Returns
    -------
    dict
        The test metrics (also in ``out/metrics.json``).
    """
    torch = _torch()
    from treeform.learn.data import SceneStream
    from treeform.learn.nets.segnet import SegNet

    cfg = SegTrainConfig.from_dict({**(asdict(config) if config else {}), **options})
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if cfg.threads:
        torch.set_num_threads(cfg.threads)
    renders, cuts = _sprites(data, cutouts, "train")
    from treeform.dataset.scenes import load_photos

    bg_photos = load_photos(photos, split="train") if photos is not None else []
    stream = SceneStream(renders, cuts, size=cfg.size, seed=cfg.seed, cutout_fraction=cfg.cutout_fraction,
                         negatives=cfg.negatives, photos=bg_photos, photo_fraction=cfg.photo_fraction)
    torch.manual_seed(cfg.seed)
    model = SegNet(cfg.width, fine_stride=cfg.fine_stride)
    opt = torch.optim.AdamW(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    ckpt_path = out / "checkpoint.pt"
    step, prior_seconds = 0, 0.0
    if ckpt_path.exists():
        state = torch.load(ckpt_path, map_location="cpu", weights_only=False)
        if state.get("config") != asdict(cfg):
            raise InputError(f"{ckpt_path}: written with other settings; use another --out or delete it")
        model.load_state_dict(state["model"])
        opt.load_state_dict(state["optimizer"])
        step = int(state["step"])
        prior_seconds = float(state.get("seconds", 0.0))
        if "torch_rng" in state:  # dropout draws continue where the killed run stopped
            torch.set_rng_state(state["torch_rng"])
    (out / "config.json").write_text(json.dumps({"network": "seg", "data": str(data), "test_data": str(test_data),
                                                 "cutouts": str(cutouts), "photos": str(photos), **asdict(cfg)},
                                                indent=2))
    per_round = max(1, cfg.chunk * cfg.repeats // cfg.batch)
    model.train()
    t0, seen, loss_avg = time.perf_counter(), 0, None
    images = labels = None
    cur_round = -1
    while step < cfg.steps:
        r = step // per_round
        if r != cur_round:
            images, labels = stream.chunk(r, cfg.chunk)
            order = np.random.default_rng([cfg.seed, 9, r]).permutation(np.tile(np.arange(cfg.chunk), cfg.repeats))
            cur_round = r
        k = step % per_round
        idx = order[k * cfg.batch:(k + 1) * cfg.batch]
        flip = np.random.default_rng([cfg.seed, 10, step]).random(len(idx)) < 0.5
        x = images[idx].copy()
        y = labels[idx].copy()
        x[flip], y[flip] = x[flip][:, :, ::-1], y[flip][:, :, ::-1]
        xt = torch.from_numpy(np.ascontiguousarray(x)).permute(0, 3, 1, 2).float().div_(255.0)
        yt = torch.from_numpy(np.ascontiguousarray(y))
        for g in opt.param_groups:
            g["lr"] = _lr_at(step, cfg.steps, cfg.lr)
        loss = _partial_ce(model(xt), yt, cfg.wood_weight)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
        step += 1
        seen += len(idx)
        lv = loss.item()
        loss_avg = lv if loss_avg is None else 0.95 * loss_avg + 0.05 * lv
        if progress is not None:
            dt = time.perf_counter() - t0
            progress(step, cfg.steps, {"loss": loss_avg, "images_per_s": seen / dt if dt > 0 else 0.0})
        if step % cfg.checkpoint_every == 0 or step == cfg.steps:
            dt = time.perf_counter() - t0
            with open(out / "log.csv", "a") as fh:
                fh.write(f"{step},{loss_avg:.5f},{_lr_at(step - 1, cfg.steps, cfg.lr):.6f},{seen / dt:.2f}\n")
            _save_atomic({"model": model.state_dict(), "optimizer": opt.state_dict(), "step": step,
                          "config": asdict(cfg), "seconds": prior_seconds + dt,
                          "torch_rng": torch.get_rng_state()}, ckpt_path)
    model.eval()
    from treeform.learn.export import export_onnx

    onnx_path = export_onnx(model, out / "model.onnx", kind="seg", metadata={"train_steps": cfg.steps,
                                                                             "train_size": cfg.size})
    metrics = {"train_seconds": round(prior_seconds + time.perf_counter() - t0, 1), "steps": cfg.steps}
    test_r, test_c = _sprites(test_data, cutouts, "test") if (test_data or cutouts) else ([], [])
    if test_r or test_c:
        from treeform.learn.data import test_scenes
        from treeform.learn.infer import Segmenter

        seg = Segmenter(onnx_path)
        metrics.update(evaluate_segmenter(lambda im: seg.predict_labels(im, keep_main=False), test_scenes(test_r, test_c, size=cfg.size)))
    (out / "metrics.json").write_text(json.dumps(metrics, indent=2))
    return metrics


def evaluate_segmenter(predict, scenes: dict) -> dict:
    """Per-class IoU / mean IoU (render scenes) and tree IoU (cut-out scenes) of ``predict(image) -> labels``."""
    from treeform.metrics.segmentation import CLASSES, class_iou, confusion_matrix, tree_iou

    res = {}
    if "renders" in scenes:
        ims, labs = scenes["renders"]
        conf = np.zeros((3, 3), np.int64)
        tious = []
        for im, lab in zip(ims, labs):
            pred = predict(im)
            conf += confusion_matrix(pred, lab)
            if (lab > 0).any():
                tious.append(tree_iou(pred, lab))
        ious = class_iou(conf)
        res["renders"] = {"n": int(len(ims)), "iou": dict(zip(CLASSES, np.round(ious, 4).tolist())),
                          "mean_iou": round(float(np.nanmean(ious)), 4),
                          "tree_iou_median": round(float(np.median(tious)), 4) if tious else None,
                          "confusion": conf.tolist()}
    if "cutouts" in scenes:
        ims, labs = scenes["cutouts"]
        tious = [tree_iou(predict(im), lab) for im, lab in zip(ims, labs) if (lab > 0).any()]
        res["cutouts"] = {"n": len(tious), "tree_iou_median": round(float(np.median(tious)), 4),
                          "tree_iou_mean": round(float(np.mean(tious)), 4)}
    return res
