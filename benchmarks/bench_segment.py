"""Segmentation quality and speed: classical colour rules vs the learned network.

1. **Real texture, exact truth**: the held-out ('test' split by tree identity) RGBA cut-outs
   of ../shared/data/billboards (and more/) pasted at random scale and position over
   blurred crops of the held-out real photos in ../shared/data/photos (the 'test' side of
   ``photo_split``, by species; the other side serves as training backgrounds);
   tree-vs-background IoU of both segmenters (median, mean, share >= 0.9).
2. **Synthetic test split** (when --test-data is given, a dataset of another seed): the
   learned network's per-class IoU and mean IoU on randomised scenes of held-out trees.
3. **Speed**: median seconds of each segmenter on a 512-px photo (in-process, warm).

Run: `.venv/bin/python benchmarks/bench_segment.py [--n 120] [--test-data out/weights/data/test]`
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

import numpy as np

from _common import machine, median_time

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"


def composites(n: int, size: int, seed: int):
    from treeform.dataset.scenes import load_cutouts, load_photos, paste_on_photo

    sprites = load_cutouts(SHARED / "billboards", split="test")
    # only the photos of the held-out side (full size): the other side serves as training backgrounds
    photos = load_photos(SHARED / "photos", split="test", max_side=1 << 16)
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        sp = sprites[int(rng.integers(len(sprites)))]
        ph = photos[int(rng.integers(len(photos)))]
        img, mask = paste_on_photo(sp, ph, rng, size=size)
        out.append((img, mask, sp.name))
    return out, len(sprites)


def score(name: str, fn, cases):
    from treeform._shared.errors import NoTreeFoundError
    from treeform.metrics.segmentation import tree_iou

    ious, times = [], []
    for img, mask, _ in cases:
        t0 = time.perf_counter()
        try:
            lab = fn(img)
        except NoTreeFoundError:
            lab = np.zeros(mask.shape, np.uint8)
        times.append(time.perf_counter() - t0)
        ious.append(tree_iou(lab, mask.astype(np.uint8)))
    ious = np.asarray(ious)
    return {"segmenter": name, "n": len(ious), "median_iou": round(float(np.median(ious)), 4),
            "mean_iou": round(float(ious.mean()), 4), "share_ge_0.9": round(float((ious >= 0.9).mean()), 4),
            "median_seconds": round(statistics.median(times), 4)}


def resolution_ceiling(labels, strides=(2, 4, 8)) -> dict:
    """IoU of the true labels reduced to each stride (area average of one-hot) and upsampled back
    bilinearly: the best a network whose logits stop at that stride can score."""
    import cv2

    from treeform.metrics.segmentation import CLASSES, class_iou, confusion_matrix

    out = {}
    for k in strides:
        conf = np.zeros((3, 3), np.int64)
        for lab in labels:
            h, w = lab.shape
            onehot = np.eye(3, dtype=np.float32)[lab]
            coarse = cv2.resize(onehot, (w // k, h // k), interpolation=cv2.INTER_AREA)
            conf += confusion_matrix(cv2.resize(coarse, (w, h), interpolation=cv2.INTER_LINEAR).argmax(-1), lab)
        ious = class_iou(conf)
        out[k] = {"iou": dict(zip(CLASSES, np.round(ious, 4).tolist())), "mean_iou": round(float(np.nanmean(ious)), 4)}
    return out


def main():
    from treeform.segment import segment_tree, segment_tree_learned

    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=120)
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--seed", type=int, default=2024)
    ap.add_argument("--test-data", default=None, help="held-out synthetic dataset (another seed)")
    ap.add_argument("--weights", default=None, help="ONNX weights (default: the shipped seg.onnx)")
    args = ap.parse_args()
    cases, n_sprites = composites(args.n, args.size, args.seed)
    learned = lambda im: segment_tree_learned(im, weights=args.weights).labels  # noqa: E731
    classical = lambda im: segment_tree(im).labels  # noqa: E731
    score("warm-up", learned, cases[:1])
    rows = [score("learned", learned, cases), score("classical", classical, cases)]
    print(f"# Segmentation, real cut-outs over blurred real photos ({args.n} composites of {n_sprites} held-out "
          f"cut-outs, {args.size} px)\n\nmachine: {machine()}\n")
    print("| segmenter | median tree IoU | mean | share >= 0.9 | median s / image |\n|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['segmenter']} | {r['median_iou']:.3f} | {r['mean_iou']:.3f} | {r['share_ge_0.9']:.2f} | "
              f"{r['median_seconds']:.3f} |")
    result = {"machine": machine(), "composites": rows}
    from PIL import Image

    photo = np.asarray(Image.open(SHARED / "photos" / "Celtis_occidentalis_1.jpg").convert("RGB"))
    import cv2

    s = 512 / max(photo.shape[:2])
    photo = cv2.resize(photo, (round(photo.shape[1] * s), round(photo.shape[0] * s)), interpolation=cv2.INTER_AREA)
    t_l, _ = median_time(lambda: learned(photo), 11)
    t_c, _ = median_time(lambda: classical(photo), 5)
    print(f"\nspeed on a {photo.shape[1]}x{photo.shape[0]} photo: learned {t_l:.3f} s, classical {t_c:.3f} s (median)")
    result["speed_512"] = {"learned": round(t_l, 4), "classical": round(t_c, 4)}
    if args.test_data:
        from treeform.learn.data import render_sprites, test_scenes
        from treeform.learn.infer import Segmenter
        from treeform.learn.train import evaluate_segmenter

        seg = Segmenter(args.weights)
        sc = test_scenes(render_sprites(args.test_data), [], n=400)
        m = evaluate_segmenter(lambda im: seg.predict_labels(im, keep_main=False), sc)["renders"]
        print(f"\nsynthetic test split ({m['n']} scenes of held-out trees): mean IoU {100 * m['mean_iou']:.1f} % — "
              + ", ".join(f"{k} {100 * v:.1f} %" for k, v in m["iou"].items()))
        result["synthetic"] = m
        ceiling = resolution_ceiling(sc["renders"][1])
        print("resolution ceiling (the true labels reduced to stride k and upsampled back): "
              + ", ".join(f"stride {k}: mean IoU {100 * v['mean_iou']:.1f} % (wood {100 * v['iou']['wood']:.1f} %)"
                          for k, v in ceiling.items()))
        result["resolution_ceiling"] = ceiling
    (ROOT / "out").mkdir(exist_ok=True)
    (ROOT / "out" / "bench_segment.json").write_text(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
