"""Photo -> RGBA billboard on the isolated photos: alpha IoU with the segmentation, and a contact sheet.

Run: `python benchmarks/eval_billboards.py [--sky-gaps] [--sheet docs/images/billboards.jpg]`
"""

from __future__ import annotations

import argparse
import csv
import statistics
from pathlib import Path

import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
PHOTOS = ROOT.parent / "shared" / "data" / "photos"


def checker(h, w, s=12):
    yy, xx = np.mgrid[:h, :w]
    return np.where(((yy // s + xx // s) % 2 == 0)[..., None], 235, 200).astype(np.uint8).repeat(3, axis=2)


def main():
    from treeform.methods.variations.pipeline import billboard

    ap = argparse.ArgumentParser()
    ap.add_argument("--sky-gaps", action="store_true")
    ap.add_argument("--sheet", type=Path, default=None)
    args = ap.parse_args()
    with open(PHOTOS / "ATTRIBUTION.csv") as f:
        names = sorted(r["file"] for r in csv.DictReader(f) if r["isolation_visual"] == "isolated")
    ious, tiles = [], []
    for name in names:
        res = billboard(PHOTOS / name, sky_gaps=args.sky_gaps)
        iou = res.metrics["iou"]
        ious.append(iou)
        print(f"{Path(name).stem:28s} IoU {iou:.3f}", flush=True)
        if args.sheet:
            photo = res.photo.image
            a = res.alpha[..., None].astype(np.float32)
            comp = (a * photo + (1 - a) * checker(*res.alpha.shape)).astype(np.uint8)
            pair = np.concatenate([photo, comp], 1)
            im = Image.fromarray(pair)
            im = im.resize((round(im.width * 240 / im.height), 240), Image.LANCZOS)
            tiles.append(np.asarray(im))
    print(f"median IoU {statistics.median(ious):.3f}, min {min(ious):.3f}, {sum(i >= 0.9 for i in ious)}/{len(ious)} >= 0.9")
    if args.sheet:
        cols = 4
        rows = [tiles[i:i + cols] for i in range(0, len(tiles), cols)]
        width = max(sum(t.shape[1] for t in r) + 8 * (len(r) + 1) for r in rows)
        sheet = np.full((len(rows) * 248 + 8, width, 3), 255, np.uint8)
        for ri, r in enumerate(rows):
            x = 8
            for t in r:
                sheet[8 + ri * 248: 8 + ri * 248 + 240, x:x + t.shape[1]] = t
                x += t.shape[1] + 8
        Image.fromarray(sheet).save(args.sheet, optimize=True)
        print(f"wrote {args.sheet}")


if __name__ == "__main__":
    main()
