"""Training of the perception networks (torch, the optional ``train`` extra; seed 003 §4.2).

``treeform train seg --data DIR --out DIR`` trains :class:`~treeform.learn.nets.segnet.SegNet`
on randomised scenes (:class:`~treeform.learn.data.SceneStream`) built from a dataset of
``treeform dataset generate`` plus, when given, real photo cut-outs. Every run:

- is seeded: same data + seed + config -> the same scene stream and initialisation
  (bit-identical weights on the same machine and thread count, on the CPU; ``workers``
  processes compose the same scenes as the main process would);
- writes ``checkpoint.pt`` atomically every ``checkpoint_every`` steps and resumes from it
  after a kill (the scene stream is a function of the round, so a resumed run sees the
  same data as an uninterrupted one);
- reports ``progress(done, total, info)`` with the loss and images/s (the CLI draws it);
- ends with ``model.onnx`` (:func:`treeform.learn.export.export_onnx`) and ``metrics.json``
  on the fixed test split.

This module is never imported by inference (``treeform reconstruct`` / ``segment``).
"""

from __future__ import annotations

import functools
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
    refine: int = 0
    """Channels of SegNet's full-resolution refinement (0 = none; with ``init`` from weights without it,
    the branch is added and starts as a no-op)."""
    lr: float = 3e-3
    """Peak AdamW learning rate (warm-up, then cosine decay to 2 %)."""
    weight_decay: float = 1e-4
    wood_weight: float = 3.0
    """Cross-entropy weight of wood pixels (thin, rare) and of the wood Dice term."""
    chunk: int = 256
    """Scenes composed per round (each round's scenes make ``chunk * repeats / batch`` steps)."""
    repeats: int = 2
    """Passes over each round's scenes (with flips) before the next round."""
    cutout_fraction: float = 0.35
    negatives: float = 0.08
    photo_fraction: float = 0.2
    """Share of scenes over an out-of-focus crop of a real photo (when ``photos`` are given)."""
    photo_tree_fraction: float = 0.15
    """Share of scenes that are a sharp crop of a real photo, its main tree pseudo-labelled by the
    colour rules (when ``photos`` are given; :func:`~treeform.dataset.scenes.photo_pseudo_labels`)."""
    noise_negatives: float = 0.03
    """Share of scenes that are random noise, all background (noise is texture everywhere, like foliage)."""
    bush_fraction: float = 0.0
    """Share of scenes with a row of leafy bushes behind the tree's foot, labelled background
    (:class:`~treeform.learn.data.SceneStream`)."""
    sparse_boost: float = 0.0
    """Cut-outs drawn with weights ``fill ** -sparse_boost`` (0: uniformly): sparse and leafless trees oftener."""
    tree_dice: float = 0.0
    """Weight of a per-scene Dice term on the tree (foliage + wood against background): a sapling that
    covers 1 % of the frame weighs as much as a crown that fills it (0: none)."""
    init: str = ""
    """ONNX weights of a SegNet of the same shape to start from (fine-tuning), e.g. the shipped seg.onnx."""
    seed: int = 0
    checkpoint_every: int = 100
    threads: int = 0
    """torch CPU threads (0 = all cores)."""
    device: str = "cpu"
    """Where the network trains: 'cpu', 'cuda' or 'auto' (cuda when torch sees one)."""
    workers: int = 0
    """Processes composing rounds ahead of the optimiser (0 = in line; the scenes are the same either way)."""
    test_scenes: int = 400
    """Scenes of the fixed test split scored at the end (half renders, half cut-outs when both exist)."""

    def __post_init__(self):
        """Every setting in its range, before anything is written or imported (one line for the CLI)."""
        import re

        from treeform._shared.checks import check_choice, check_int, check_range
        from treeform._shared.rng import check_seed

        for name, lo, hi in (("steps", 1, 10**7), ("batch", 1, 4096), ("width", 4, 128), ("refine", 0, 128),
                             ("chunk", 1, 10**5), ("repeats", 1, 100), ("checkpoint_every", 1, 10**7), ("threads", 0, 1024), ("workers", 0, 256),
                             ("test_scenes", 2, 10**5)):
            check_int(getattr(self, name), name, lo, hi)
        check_seed(self.seed)
        check_int(self.size, "size", 32, 2048)
        if self.size % 8:
            raise InputError(f"size: expected a multiple of 8 (the network's stride), got {self.size}")
        check_choice(self.fine_stride, "fine_stride", (1, 2, 4))
        if self.refine and self.fine_stride != 1:
            raise InputError(f"refine: works with fine_stride 1, got fine_stride {self.fine_stride}")
        check_range(self.lr, "lr", 1e-7, 1.0)
        check_range(self.weight_decay, "weight_decay", 0.0, 1.0)
        check_range(self.wood_weight, "wood_weight", 0.0, 100.0)
        check_range(self.tree_dice, "tree_dice", 0.0, 100.0)
        check_range(self.sparse_boost, "sparse_boost", 0.0, 4.0)
        for name in ("cutout_fraction", "negatives", "photo_fraction", "photo_tree_fraction", "noise_negatives",
                     "bush_fraction"):
            check_range(getattr(self, name), name, 0.0, 1.0)
        if not re.fullmatch(r"cpu|auto|cuda(:\d+)?|mps", str(self.device)):
            raise InputError(f"device: expected cpu, cuda, cuda:N, mps or auto, got {self.device!r}")

    @classmethod
    def from_dict(cls, d: dict) -> "SegTrainConfig":
        from treeform._shared.checks import check_known_options

        return cls(**check_known_options(cls, d))


def _partial_ce(logits, labels, wood_weight: float, tree_dice: float = 0.0):
    """Cross-entropy with partial labels: 0/1/2 as usual, 3 = 'foliage or wood' (log of their summed prob),
    255 = no loss; plus a Dice term on wood and, with ``tree_dice``, a per-scene Dice term on the tree."""
    torch = _torch()
    logp = torch.log_softmax(logits, 1)
    lab = labels.long()
    known = lab.clamp(max=2)
    nll = -logp.gather(1, known[:, None])[:, 0]
    nll_any = -torch.logsumexp(logp[:, 1:3], 1)
    nll = torch.where(lab == 3, nll_any, nll)
    w = torch.where(lab == 2, torch.full_like(nll, wood_weight), torch.ones_like(nll))
    w = torch.where(lab == 255, torch.zeros_like(nll), w)  # UNSURE: no loss
    ce = (nll * w).sum() / w.sum()
    # Dice on wood over the scenes whose parts are known (synthetic renders)
    known_img = (lab <= 2).flatten(1).all(1)
    if known_img.any():
        p = torch.softmax(logits, 1)[:, 2][known_img]
        t = (lab[known_img] == 2).float()
        dice = 1 - (2 * (p * t).sum() + 1) / (p.sum() + t.sum() + 1)
    else:
        dice = logits.sum() * 0
    loss = ce + 0.5 * wood_weight / 2.5 * dice
    if tree_dice > 0:
        tree_t = ((lab >= 1) & (lab <= 3)).float()
        has_tree = tree_t.flatten(1).sum(1) > 0
        if has_tree.any():
            valid = (lab != 255).float()
            pt = torch.softmax(logits, 1)[:, 1:3].sum(1) * valid
            tt = tree_t * valid
            inter = (pt * tt).flatten(1).sum(1)
            d = 1 - (2 * inter + 1) / (pt.flatten(1).sum(1) + tt.flatten(1).sum(1) + 1)
            loss = loss + tree_dice * d[has_tree].mean()
    return loss


_RUNTIME_ONLY = ("threads", "device", "workers", "checkpoint_every", "test_scenes")
"""Settings that change where and how fast a run goes, not what it learns (a resume may change them)."""


def _same_run(a: dict, b: dict) -> bool:
    return ({k: v for k, v in a.items() if k not in _RUNTIME_ONLY}
            == {k: v for k, v in b.items() if k not in _RUNTIME_ONLY})


_STREAM = None  # a worker process's own SceneStream (built once by _start_worker)


def _start_worker(make_stream) -> None:
    global _STREAM
    import cv2

    cv2.setNumThreads(1)
    _STREAM = make_stream()


def _compose_round(r: int, n: int):
    return _STREAM.chunk(r, n)


def _scene_stream(data, cutouts, photos, *, size, seed, cutout_fraction, negatives, photo_fraction,
                  photo_tree_fraction=0.0, noise_negatives=0.0, bush_fraction=0.0, sparse_boost=0.0):
    """The training :class:`~treeform.learn.data.SceneStream` of ``train_seg`` (also built in each worker)."""
    from treeform.dataset.scenes import load_photos, photo_pseudo_labels
    from treeform.learn.data import SceneStream

    renders, cuts = _sprites(data, cutouts, "train")
    bg_photos = load_photos(photos, split="train") if photos is not None else []
    trees = []
    if photo_tree_fraction > 0:
        for ph in bg_photos:
            lab = photo_pseudo_labels(ph)
            if lab is not None:
                trees.append((ph, lab))
    return SceneStream(renders, cuts, size=size, seed=seed, cutout_fraction=cutout_fraction, negatives=negatives,
                       photos=bg_photos, photo_fraction=photo_fraction, photo_trees=trees,
                       photo_tree_fraction=photo_tree_fraction, noise_fraction=noise_negatives,
                       bush_fraction=bush_fraction, sparse_boost=sparse_boost)


class _Rounds:
    """Rounds of a :class:`~treeform.learn.data.SceneStream`, in line or composed ahead by worker processes.

    ``make_stream`` is a picklable callable that builds the stream; each of the ``workers``
    processes (spawned, not forked: a fork of a process whose OpenCV or OpenMP threads
    have started can deadlock) builds its own. Round ``r`` depends only on (seed, r), so
    the scenes are identical whichever process composes them; ``2 * workers`` rounds are
    kept in flight.
    """

    def __init__(self, make_stream, n: int, workers: int):
        self.n, self.workers = int(n), int(workers)
        self._pool, self._pending, self.stream, self._last = None, {}, None, None
        if self.workers > 0:
            import multiprocessing as mp
            from concurrent.futures import ProcessPoolExecutor

            self._pool = ProcessPoolExecutor(self.workers, mp_context=mp.get_context("spawn"),
                                             initializer=_start_worker, initargs=(make_stream,))
        else:
            self.stream = make_stream()

    def get(self, r: int):
        if self._last is not None and self._last[0] == r:  # asked again (fine-tuning calibrates on round 0)
            return self._last[1]
        self._last = (r, self._compose(r))
        return self._last[1]

    def _compose(self, r: int):
        if self._pool is None:
            return self.stream.chunk(r, self.n)
        for k in list(self._pending):
            if k < r:
                self._pending.pop(k).cancel()
        for k in range(r, r + 2 * self.workers):
            if k not in self._pending:
                self._pending[k] = self._pool.submit(_compose_round, k, self.n)
        return self._pending.pop(r).result()

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None


def _open_run(cfg, out) -> tuple[Path, object]:
    """A training run's folder (checked writable, made) and torch, its CPU threads set from ``cfg.threads``.

    Called after the settings are checked (their ``__post_init__``), so a bad option is one line
    before torch is imported or anything is written.
    """
    from treeform.io.outputs import check_out_dir

    out = check_out_dir(out)
    torch = _torch()
    out.mkdir(parents=True, exist_ok=True)
    if cfg.threads:
        torch.set_num_threads(cfg.threads)
    return out, torch


def _device(torch, name: str):
    if name == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if name not in ("cpu", "cuda"):
        raise InputError(f"device {name!r}: expected cpu, cuda or auto")
    if name == "cuda" and not torch.cuda.is_available():
        raise InputError("device cuda: torch sees no CUDA device (use --device cpu)")
    return torch.device(name)


def _save_atomic(obj, path: Path) -> None:
    torch = _torch()
    tmp = path.with_name(path.name + ".tmp")
    torch.save(obj, tmp)
    os.replace(tmp, path)


def _resume(torch, ckpt_path: Path, model, opt, defaults: dict, settings: dict, *,
            ignore: tuple = ()) -> tuple[int, float]:
    """Load a killed run's checkpoint into ``model`` and ``opt``; (step, seconds trained so far).

    (0, 0.0) without a checkpoint. Settings added since the checkpoint was written take their
    ``defaults`` (they did not exist then); keys in ``ignore`` (e.g. a wall-clock limit) may
    differ. A checkpoint of other settings is one clear error.
    """
    if not ckpt_path.exists():
        return 0, 0.0
    state = torch.load(ckpt_path, map_location="cpu", weights_only=False)
    free = dict.fromkeys(ignore, 0)
    if not _same_run({**defaults, **(state.get("config") or {}), **free}, {**settings, **free}):
        raise InputError(f"{ckpt_path}: written with other settings; use another --out or delete it")
    model.load_state_dict(state["model"])
    opt.load_state_dict(state["optimizer"])
    if "torch_rng" in state:  # dropout draws continue where the killed run stopped
        torch.set_rng_state(state["torch_rng"])
    return int(state["step"]), float(state.get("seconds", 0.0))


def _init_from_onnx(torch, model, weights, rounds, dev, *, new_layers: tuple) -> None:
    """Fine-tuning: shipped ONNX weights into ``model``, BatchNorm statistics from the first round's scenes."""
    from treeform.learn.export import load_onnx_into

    first = rounds.get(0)[0][:32]
    load_onnx_into(model, weights, calibrate=torch.from_numpy(first).to(dev).permute(0, 3, 1, 2).float() / 255.0,
                   new_layers=new_layers)


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
    cfg = SegTrainConfig.from_dict({**(asdict(config) if config else {}), **options})  # checked first
    out, torch = _open_run(cfg, out)
    from treeform.learn.nets.segnet import SegNet

    make_stream = functools.partial(_scene_stream, data, cutouts, photos, size=cfg.size, seed=cfg.seed,
                                    cutout_fraction=cfg.cutout_fraction, negatives=cfg.negatives,
                                    photo_fraction=cfg.photo_fraction, photo_tree_fraction=cfg.photo_tree_fraction,
                                    noise_negatives=cfg.noise_negatives, bush_fraction=cfg.bush_fraction,
                                    sparse_boost=cfg.sparse_boost)
    dev = _device(torch, cfg.device)
    torch.manual_seed(cfg.seed)
    model = SegNet(cfg.width, fine_stride=cfg.fine_stride, refine=cfg.refine).to(dev)
    if dev.type == "cuda":
        torch.backends.cudnn.benchmark = True
    opt = torch.optim.AdamW(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    ckpt_path = out / "checkpoint.pt"
    step, prior_seconds = _resume(torch, ckpt_path, model, opt, asdict(SegTrainConfig()), asdict(cfg))
    (out / "config.json").write_text(json.dumps({"network": "seg", "data": str(data), "test_data": str(test_data),
                                                 "cutouts": str(cutouts), "photos": str(photos), **asdict(cfg)},
                                                indent=2))
    per_round = max(1, cfg.chunk * cfg.repeats // cfg.batch)
    rounds = _Rounds(make_stream, cfg.chunk, cfg.workers)
    if cfg.init and step == 0:
        _init_from_onnx(torch, model, cfg.init, rounds, dev, new_layers=("full", "refine"))
    try:
        _optimise(torch, model, opt, rounds, cfg, dev, step, per_round, out, prior_seconds, progress)
    finally:
        rounds.close()
    model = model.cpu().eval()
    from treeform.learn.export import export_onnx

    onnx_path = export_onnx(model, out / "model.onnx", kind="seg", metadata={"train_steps": cfg.steps,
                                                                             "train_size": cfg.size})
    state = torch.load(ckpt_path, map_location="cpu", weights_only=False) if ckpt_path.exists() else {}
    metrics = {"train_seconds": round(float(state.get("seconds", 0.0)), 1), "steps": cfg.steps,
               "device": dev.type}
    test_r, test_c = _sprites(test_data, cutouts, "test") if (test_data or cutouts) else ([], [])
    if test_r or test_c:
        from treeform.learn.data import test_scenes
        from treeform.learn.infer import Segmenter

        seg = Segmenter(onnx_path)
        metrics.update(evaluate_segmenter(lambda im: seg.predict_labels(im, keep_main=False), test_scenes(test_r, test_c, n=cfg.test_scenes, size=cfg.size)))
    (out / "metrics.json").write_text(json.dumps(metrics, indent=2))
    return metrics


def _optimise(torch, model, opt, rounds, cfg, dev, step, per_round, out, prior_seconds, progress) -> None:
    """The optimiser loop of :func:`train_seg` from ``step``; checkpoints every ``cfg.checkpoint_every``."""
    ckpt_path = out / "checkpoint.pt"
    model.train()
    t0, seen, loss_avg = time.perf_counter(), 0, None
    images = labels = order = None
    cur_round = -1
    while step < cfg.steps:
        r = step // per_round
        if r != cur_round:
            images, labels = rounds.get(r)
            order = np.random.default_rng([cfg.seed, 9, r]).permutation(np.tile(np.arange(cfg.chunk), cfg.repeats))
            cur_round = r
        k = step % per_round
        idx = order[k * cfg.batch:(k + 1) * cfg.batch]
        flip = np.random.default_rng([cfg.seed, 10, step]).random(len(idx)) < 0.5
        x = images[idx].copy()
        y = labels[idx].copy()
        x[flip], y[flip] = x[flip][:, :, ::-1], y[flip][:, :, ::-1]
        xt = torch.from_numpy(np.ascontiguousarray(x)).to(dev).permute(0, 3, 1, 2).float().div_(255.0)
        yt = torch.from_numpy(np.ascontiguousarray(y)).to(dev)
        for g in opt.param_groups:
            g["lr"] = _lr_at(step, cfg.steps, cfg.lr)
        loss = _partial_ce(model(xt), yt, cfg.wood_weight, cfg.tree_dice)
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
