"""Seed 000 (image-based tree variations) benchmarks: medians of 7 repeats, never asserted.

Run: ``python benchmarks/bench_variations.py [--repeat 7]``. Prints a markdown table:

* one 1024 x 1024 variation from two exemplars with M = 20 (contour combination, region
  fill, simplified target contour, mean value coordinates, RGBA transfer), paper: 5.5 s;
* processing one exemplar from its file (read, normalise to 1024², crown/trunk
  segmentation, contours, pins, resampling, Cs), no cache.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from _common import machine, median_time  # benchmarks/ is on sys.path when a script runs

ROOT = Path(__file__).resolve().parents[1]
BILLBOARDS = ROOT.parent / "shared" / "data" / "billboards"



def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7)
    args = ap.parse_args(argv)
    sys.path.insert(0, str(ROOT / "src"))
    from treeform.methods.variations import process_exemplar, read_rgba, synthesize

    big = BILLBOARDS / "cesium_tree_billboard.png"
    small = BILLBOARDS / "savanna-trees_row3_col0.png"
    if not big.is_file():
        sys.exit(f"missing test data: {big}")
    a = process_exemplar(read_rgba(big))
    b = process_exemplar(read_rgba(small))
    synthesize([a, b], [0.5, 0.5])  # warm-up (imports, premultiplied copies)
    rows = []
    med, _ = median_time(lambda: synthesize([a, b], [0.4, 0.6], colour_weights=[0.5, 0.5], m=20), args.repeat)
    rows.append(("one 1024² variation, two exemplars, M = 20", med, "≤ 0.5 (paper: 5.5)"))
    med, _ = median_time(lambda: synthesize([a, b], [0.4, 0.6], m=20, mvc_step=1), args.repeat)
    rows.append(("  same, mean value coordinates exact at every pixel (mvc_step=1)", med, ""))
    for path in (big, small):
        med, _ = median_time(lambda: process_exemplar(read_rgba(path)), args.repeat)
        rows.append((f"process one exemplar ({path.name}, read → Cr, Cs)", med, "≤ 1"))
    print(f"machine: {machine()}; medians of {args.repeat}")
    print("| benchmark | median (s) | target (s) |\n|---|---|---|")
    for name, med, target in rows:
        print(f"| {name} | {med:.3f} | {target} |")


if __name__ == "__main__":
    main()
