"""Seed 000 §6 (billboard clouds) benchmarks: medians of 5 repeats, never asserted.

Run: ``python benchmarks/bench_cloud.py [--repeat 5] [--photos N] [--strips DIR]``. Prints two
markdown tables:

* speed — SLIC superpixels + straight-edge replacement on a 1024² tree (target ≤ 2 s;
  paper: 20–50 s), placing 500 billboards (front, rear, interior, trunk; target ≤ 0.2 s);
* quality — the front render of the cloud against the picture over the tree's pixels
  (PSNR, SSIM, silhouette IoU; targets PSNR ≥ 25 dB or SSIM ≥ 0.9, IoU ≥ 0.95) for the
  bundled photo, the first ``--photos`` isolated photos of ``../shared/data/photos`` (each
  made into an RGBA billboard first) and the CC0 Cesium RGBA tree.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from _common import machine, median_time  # benchmarks/ is on sys.path when a script runs

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"
SAMPLE = ROOT / "src" / "treeform" / "data" / "Celtis_occidentalis_1.jpg"
CESIUM = SHARED / "billboards" / "cesium_tree_billboard.png"


def _isolated(n: int) -> list[Path]:
    import csv

    path = SHARED / "photos" / "ATTRIBUTION.csv"
    if not path.is_file():
        return []
    with open(path) as f:
        rows = [r["file"] for r in csv.DictReader(f) if r["isolation_visual"] == "isolated"]
    return [SHARED / "photos" / name for name in sorted(rows)[:n]]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--photos", type=int, default=4, help="isolated photos of ../shared/data/photos to measure")
    ap.add_argument("--strips", type=Path, default=None, help="also write each turntable strip into this folder")
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT / "src"))
    from treeform.crown import inflate_envelope
    from treeform.geometry.billboard_cloud import luminance, place_billboards, replace_straight_edges, superpixels
    from treeform.methods.variations import billboard, normalize_rgba, split_crown_trunk
    from treeform.methods.variations.cloud import cloud

    picture = normalize_rgba(billboard(SAMPLE).rgba, size=1024)
    labels = split_crown_trunk(picture)
    crown, tree = labels == 1, labels > 0

    def edges():
        sp = superpixels(picture[..., :3], crown)
        return replace_straight_edges(sp, crown, within=tree)

    regions = edges()  # warm-up
    speed = []
    med, _ = median_time(edges, args.repeat)
    speed.append((f"superpixels + edge replacement, 1024² tree ({len(regions)} superpixels, "
                  f"{len(regions.curves)}/{regions.straight} straight edges replaced)", med, "≤ 2 (paper: 20–50)"))
    height = inflate_envelope(crown, k=None).front_z
    lum = luminance(picture, regions.boxes, regions.masks)
    n = len(regions)
    first = place_billboards(regions.boxes, regions.masks, lum, height, tree, crown=crown, interior=0.0)
    interior = max(0.0, (500 - len(first)) / n)  # extra billboards that bring the total to about 500
    placed = place_billboards(regions.boxes, regions.masks, lum, height, tree, crown=crown, interior=interior)
    med, _ = median_time(lambda: place_billboards(regions.boxes, regions.masks, lum, height, tree, crown=crown,
                                                  interior=interior), args.repeat)
    speed.append((f"placing {len(placed)} billboards ({placed.counts()})", med, "≤ 0.2 (paper: < 1)"))

    print(f"machine: {machine()}; medians of {args.repeat}")
    print("| benchmark | median (s) | target (s) |\n|---|---|---|")
    for name, m, target in speed:
        print(f"| {name} | {m:.3f} | {target} |")

    photos = [p for p in _isolated(args.photos + 1) if p.name != SAMPLE.name][:args.photos]
    inputs = [SAMPLE, *photos] + ([CESIUM] if CESIUM.is_file() else [])
    if args.strips is not None:
        args.strips.mkdir(parents=True, exist_ok=True)
    print("\n| picture | input | billboards (front/rear/interior) | PSNR (dB) | SSIM | IoU | cloud (s) |")
    print("|---|---|---|---|---|---|---|")
    for path in inputs:
        t0 = time.perf_counter()
        views = args.strips / f"{path.stem}.png" if args.strips is not None else None
        res = cloud(path, views=views, evaluate=True)
        dt = time.perf_counter() - t0 - res.metrics["timings"]["render"]
        m = res.metrics
        print(f"| {path.name} | {res.sidecar['source']['kind']} | {m['billboards']} ({m['front']}/{m['rear']}/"
              f"{m['interior']}) | {m['psnr']:.1f} | {m['ssim']:.3f} | {m['iou']:.3f} | {dt:.2f} |")


if __name__ == "__main__":
    main()
