"""Training of the mask networks: species CNN and cascaded RBV CNN (seed 003 §4.2.3–4.2.4, Table 1).

Both learn from the semantic masks of a ``treeform dataset generate`` dataset: its
ground-truth masks and, when segmentation weights are given, the masks the segmentation
network predicts on the same images (half of the draws), so that at run time, where only
predicted masks exist, the networks have seen their kind of error (the paper's "Error DL").
The test split (a dataset of another seed) is scored with both kinds of mask.

Seeded, checkpointed per epoch (``checkpoint.pt``, resumed after a kill), progress through
``progress(done, total, info)``; ends with ``model.onnx`` and ``metrics.json``.
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, dataclass

import numpy as np

from treeform._shared.errors import InputError
from treeform.learn.train import _lr_at, _open_run, _save_atomic, _torch

__all__ = ["MaskTrainConfig", "mask_arrays", "train_masknet"]


@dataclass
class MaskTrainConfig:
    """Settings of ``treeform train species`` / ``treeform train rbv``."""

    epochs: int = 40
    batch: int = 64
    lr: float = 2e-3
    weight_decay: float = 1e-4
    huber_beta: float = 0.05
    """Huber (smooth L1) transition of the RBV loss, in normalised radius units."""
    predicted_fraction: float = 0.5
    """Share of draws that use the segmentation network's mask instead of the true one."""
    seed: int = 0
    threads: int = 0

    def __post_init__(self):
        """Every setting in its range, before anything is written or imported (one line for the CLI)."""
        from treeform._shared.checks import check_int, check_range
        from treeform._shared.rng import check_seed

        for name, lo, hi in (("epochs", 1, 10**5), ("batch", 1, 4096), ("threads", 0, 1024)):
            check_int(getattr(self, name), name, lo, hi)
        check_seed(self.seed)
        check_range(self.lr, "lr", 1e-7, 1.0)
        check_range(self.weight_decay, "weight_decay", 0.0, 1.0)
        check_range(self.huber_beta, "huber_beta", 1e-6, 10.0)
        check_range(self.predicted_fraction, "predicted_fraction", 0.0, 1.0)

    @classmethod
    def from_dict(cls, d: dict) -> "MaskTrainConfig":
        from treeform._shared.checks import check_known_options

        return cls(**check_known_options(cls, d))


def mask_arrays(directory, *, seg_weights=None, progress=None) -> dict:
    """Inputs and targets of every sample of a dataset.

    Returns ``{"gt": (N, 3, 96, 96) float32, "pred": same or None, "species": (N,) int64,
    "rbv": (N, 341) float32, "flip_gt", "flip_pred", "rbv_flip"}`` (the mirrored copies
    for flip augmentation).
    """
    from treeform.dataset.augment import mirror_rbv
    from treeform.dataset.loader import SyntheticDataset
    from treeform.dataset.storage import decode_sample
    from treeform.learn.masks import mask_input

    ds = SyntheticDataset(directory)
    seg = None
    if seg_weights is not None:
        from treeform.learn.infer import Segmenter

        seg = Segmenter(seg_weights)
    n = len(ds)
    gt = np.zeros((n, 3, 96, 96), np.float32)
    pred = np.zeros_like(gt) if seg is not None else None
    species = np.zeros(n, np.int64)
    rbv = np.zeros((n, 341), np.float32)
    rbv_flip = np.zeros_like(rbv)
    for i in range(n):
        d = decode_sample(ds.members(i, ("image.png", "mask.png", "json")))
        gt[i] = mask_input(d["mask"])
        if seg is not None:
            lab = seg.predict_labels(d["image"])
            pred[i] = mask_input(lab) if lab.any() else gt[i] * 0 + np.array([1, 0, 0], np.float32)[:, None, None]
        species[i] = d["species_id"]
        rbv[i] = np.concatenate([r.ravel() for r in d["rbv"]])
        rbv_flip[i] = np.concatenate([mirror_rbv(r).ravel() for r in d["rbv"]])
        if progress is not None and (i + 1) % 100 == 0:
            progress(i + 1, n, {"stage": "masks"})
    return {"gt": gt, "pred": pred, "species": species, "rbv": rbv, "rbv_flip": rbv_flip}


def _evaluate(kind: str, model, arrays: dict) -> dict:
    torch = _torch()
    from treeform.learn.nets.masknets import split_levels

    res = {}
    for which in ("gt", "pred"):
        x = arrays[which]
        if x is None:
            continue
        with torch.no_grad():
            y = torch.cat([model(torch.from_numpy(x[i:i + 256])) for i in range(0, len(x), 256)]).numpy()
        if kind == "species":
            p = y.argmax(1)
            t = arrays["species"]
            conf = np.zeros((7, 7), np.int64)
            np.add.at(conf, (t, p), 1)
            res[which] = {"accuracy": round(float((p == t).mean()), 4), "confusion": conf.tolist()}
        else:
            err = [np.abs(a - b).mean() for a, b in zip(split_levels(y), split_levels(arrays["rbv"]))]
            res[which] = {"mae_percent": [round(100 * float(e), 3) for e in err]}
    res["n"] = int(len(arrays["species"]))
    return res


def train_masknet(kind: str, data, out, *, test_data=None, seg_weights=None, config: MaskTrainConfig | None = None,
                  progress=None, **options) -> dict:
    """Train the species (``kind='species'``) or RBV (``kind='rbv'``) network; resume from ``out/checkpoint.pt``.

    Parameters
    ----------
    kind : {'species', 'rbv'}
    data, test_data : path
        Training and held-out datasets of ``treeform dataset generate``.
    out : path
        Run directory.
    seg_weights : path, optional
        Segmentation ONNX weights: predicted masks join training and testing.
    progress : callable, optional
        ``progress(done, total, info)`` over epochs x steps.

    Returns
    -------
    dict
        Test metrics (also ``out/metrics.json``).
    """
    if kind not in ("species", "rbv"):
        raise InputError(f"kind: expected 'species' or 'rbv', got {kind!r}")
    cfg = MaskTrainConfig.from_dict({**(asdict(config) if config else {}), **options})  # checked first
    out, torch = _open_run(cfg, out)
    from treeform.learn.export import export_onnx
    from treeform.learn.nets.masknets import RBVNet, SpeciesNet, split_levels

    cache = out / "arrays.npz"
    if cache.exists():
        z = np.load(cache, allow_pickle=False)
        arr = {k: (z[k] if k in z.files else None) for k in ("gt", "pred", "species", "rbv", "rbv_flip")}
    else:
        arr = mask_arrays(data, seg_weights=seg_weights)
        np.savez(cache.with_name("arrays.tmp.npz"), **{k: v for k, v in arr.items() if v is not None})
        cache.with_name("arrays.tmp.npz").replace(cache)
    torch.manual_seed(cfg.seed)
    model = SpeciesNet() if kind == "species" else RBVNet()
    opt = torch.optim.AdamW(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    n = len(arr["species"])
    steps_per_epoch = max(1, n // cfg.batch)
    total = cfg.epochs * steps_per_epoch
    ckpt = out / "checkpoint.pt"
    epoch, prior_seconds = 0, 0.0
    if ckpt.exists():
        st = torch.load(ckpt, map_location="cpu", weights_only=False)
        if st.get("config") != asdict(cfg) or st.get("kind") != kind:
            raise InputError(f"{ckpt}: written with other settings; use another --out or delete it")
        model.load_state_dict(st["model"])
        opt.load_state_dict(st["optimizer"])
        epoch = int(st["epoch"])
        prior_seconds = float(st.get("seconds", 0.0))
        if "torch_rng" in st:
            torch.set_rng_state(st["torch_rng"])
    (out / "config.json").write_text(json.dumps({"network": kind, "data": str(data), "test_data": str(test_data),
                                                 "seg_weights": str(seg_weights), **asdict(cfg)}, indent=2))
    huber = torch.nn.SmoothL1Loss(beta=cfg.huber_beta)
    t0, seen = time.perf_counter(), 0
    loss_avg = None
    while epoch < cfg.epochs:
        model.train()
        rng = np.random.default_rng([cfg.seed, 11, epoch])
        order = rng.permutation(n)
        use_pred = (rng.random(n) < cfg.predicted_fraction) if arr["pred"] is not None else np.zeros(n, bool)
        flip = rng.random(n) < 0.5
        for k in range(steps_per_epoch):
            idx = order[k * cfg.batch:(k + 1) * cfg.batch]
            x = np.where(use_pred[idx, None, None, None], arr["pred"][idx] if arr["pred"] is not None else 0,
                         arr["gt"][idx])
            fl = flip[idx]
            x[fl] = x[fl][..., ::-1]
            step = epoch * steps_per_epoch + k
            for g in opt.param_groups:
                g["lr"] = _lr_at(step, total, cfg.lr)
            y = model(torch.from_numpy(np.ascontiguousarray(x)))
            if kind == "species":
                loss = torch.nn.functional.cross_entropy(y, torch.from_numpy(arr["species"][idx]))
            else:
                t = np.where(fl[:, None], arr["rbv_flip"][idx], arr["rbv"][idx])
                tt = torch.from_numpy(t)
                loss = sum(huber(a, b) for a, b in zip(split_levels(y), split_levels(tt)))
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            seen += len(idx)
            lv = loss.item()
            loss_avg = lv if loss_avg is None else 0.95 * loss_avg + 0.05 * lv
            if progress is not None:
                dt = time.perf_counter() - t0
                progress(step + 1, total, {"loss": loss_avg, "images_per_s": seen / dt if dt > 0 else 0.0})
        epoch += 1
        _save_atomic({"model": model.state_dict(), "optimizer": opt.state_dict(), "epoch": epoch,
                      "config": asdict(cfg), "kind": kind, "seconds": prior_seconds + time.perf_counter() - t0,
                      "torch_rng": torch.get_rng_state()}, ckpt)
    model.eval()
    export_onnx(model, out / "model.onnx", kind=kind, metadata={"epochs": cfg.epochs})
    metrics = {"network": kind, "train_seconds": round(prior_seconds + time.perf_counter() - t0, 1),
               "train_samples": int(n)}
    if test_data is not None:
        test = mask_arrays(test_data, seg_weights=seg_weights)
        metrics["test"] = _evaluate(kind, model, test)
    (out / "metrics.json").write_text(json.dumps(metrics, indent=2))
    return metrics
