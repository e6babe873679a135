"""Forest rendering with the level-of-detail switch (issue 15, seed 001 §5.1).

Three trees (the bundled sample reconstructed by the envelope route, oak and pine grown by
``treeform grow``) get their impostor sets (``treeform impostor``); ``render_forest`` scatters
N instances of them over a W x W ground and draws a fly-through: clipped billboard clouds
nearer than d, relief-mapped RDMs beyond. With ``--baseline`` the same frames are drawn with
every visible tree as its full mesh, in the same process, so the speed-up is a ratio measured
side by side. Frame times are the renderer's draw time (``glFinish`` before and after; the
read-back of the picture is not counted), median over the frames.

The main run uses ``render_forest``'s default card tier (far crowns narrower than 32 px on
screen as six-view impostor cards instead of the relief march). With ``--card-px P1,P2,..``
the main run draws every far tree with the relief instead (``card_px=0``, the paper's two
levels) and the forest is drawn once more for each P; each frame is compared with the
relief-only frame: mean absolute difference (0-255, RGB) and the share of pixels that differ by
more than 16 in some channel. ``--repeat R`` draws the whole set R times in turn (A B C A B C:
a GPU's clocks drift between runs) and reports the median of each frame's time over the repeats
and the median of the per-frame ratios to the relief-only frame.

Run: `.venv/bin/python benchmarks/bench_forest.py [--trees 50000] [--area 2000] [--size 1920x1080]
[--frames 3] [--switch-distance 200] [--baseline] [--relief-steps 32] [--card-px 32,64] [--repeat 3] [--species-dir DIR]
[--keep-species DIR] [--write out/bench_forest.json] [--out DIR]`
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from _common import machine
from bench_impostor import make_trees


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trees", type=int, default=5000)
    ap.add_argument("--area", type=float, default=700.0, help="edge of the square ground, metres")
    ap.add_argument("--size", default="1920x1080")
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--switch-distance", type=float, default=200.0)
    ap.add_argument("--baseline", action="store_true")
    ap.add_argument("--relief-steps", type=int, default=32, help="linear-search samples of the relief march")
    ap.add_argument("--species", default="sample,oak,pine")
    ap.add_argument("--species-dir", type=Path, default=None,
                    help="tree folders with their impostor/ already made (skips making them)")
    ap.add_argument("--keep-species", type=Path, default=None, help="make the trees here and keep them")
    ap.add_argument("--card-px", default="", help="also draw with the card tier at these crown widths (px)")
    ap.add_argument("--repeat", type=int, default=1, help="draw the set of variants this many times in turn")
    ap.add_argument("--out", type=Path, default=None, help="keep the frames here")
    ap.add_argument("--write", type=Path, default=None, help="write the timing JSON here")
    args = ap.parse_args()
    from treeform.methods.envelope.forest import render_forest
    from treeform.methods.envelope.impostor import make_impostor

    cards = [float(v) for v in args.card_px.split(",") if v.strip()]
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        species_dir = args.species_dir
        if species_dir is None:
            species_dir = args.keep_species or Path(tmp) / "species"
            trees = make_trees(species_dir, args.species.split(","))
            for d in trees.values():
                make_impostor(d)
        prep = time.perf_counter() - t0
        common = dict(trees=args.trees, area=(args.area, args.area), size=args.size, frames=args.frames,
                      switch_distance=args.switch_distance, relief_steps=args.relief_steps)
        base = {"card_px": 0.0} if cards else {}
        res = render_forest(species_dir, out=args.out, baseline=args.baseline, **base, **common)
        runs = {p: [] for p in cards if p > 0}
        base_ms = [[f["ms"] for f in res.timing["per_frame"]]]
        for r in range(max(1, args.repeat)):
            if r:
                base_ms.append([f["ms"] for f in render_forest(species_dir, **base, **common).timing["per_frame"]])
            for p in runs:
                runs[p].append(render_forest(species_dir, card_px=p, **common))
    t = res.timing
    base_ms = np.median(np.asarray(base_ms), axis=0)  # per frame, over the repeats
    print(f"# {machine()} ({t['renderer']})")
    print(f"# species {args.species}: trees and impostors made in {prep:.1f} s")
    print(f"{t['trees']} trees on {args.area:.0f} m x {args.area:.0f} m, {args.size}, "
          f"d = {args.switch_distance:.0f} m, {t['frames']} frames: visible {t['visible_trees']:.0f} "
          f"(near {t['near_trees']:.0f}, far {t['far_trees']:.0f}, cards {t['card_trees']:.0f})")
    print(f"LoD frame: {t['ms_per_frame']:.1f} ms median; trees/ms cloud {t['trees_per_ms']['cloud']}, "
          f"relief {t['trees_per_ms']['relief']}")
    if args.baseline:
        print(f"full meshes: {t['baseline_ms_per_frame']:.1f} ms median ({t['trees_per_ms']['mesh']} trees/ms) "
              f"-> speed-up {t['speedup']:.1f}x")
    rows = []
    if runs:
        print(f"relief for every far tree (card_px 0): {np.median(base_ms):.1f} ms median (each frame's median over "
              f"{max(1, args.repeat)} runs)")
    for p, rs in runs.items():
        r = rs[0]
        diff = [np.abs(a.astype(np.int16) - b.astype(np.int16))[..., :3] for a, b in zip(r.frames, res.frames)]
        mad = float(np.median([d.mean() for d in diff]))
        share = float(np.median([(d.max(-1) > 16).mean() for d in diff]))
        ms = np.median([[f["ms"] for f in x.timing["per_frame"]] for x in rs], axis=0)
        ratio = float(np.median(ms / base_ms))
        tt = r.timing
        rows.append({"card_px": p, "ms_per_frame": round(float(np.median(ms)), 3), "ratio_to_relief": round(ratio, 3),
                     "card_trees": tt["card_trees"], "relief_trees": tt["far_trees"], "mean_abs_diff": round(mad, 3),
                     "share_diff_16": round(share, 4), "per_frame": [x.timing["per_frame"] for x in rs]})
        print(f"card tier < {p:g} px: {np.median(ms):.1f} ms median ({ratio:.2f}x the relief-only frame, per-frame "
              f"median); cards {tt['card_trees']:.0f}, relief {tt['far_trees']:.0f}; against the relief-only frame: "
              f"mean |diff| {mad:.2f} / 255, {100 * share:.2f} % of pixels differ by > 16")
    for name, mem in t["memory_per_species_bytes"].items():
        print(f"memory {name}: {mem['total'] / 2**20:.2f} MiB "
              + ", ".join(f"{k} {v / 2**20:.2f}" for k, v in mem.items() if k != "total"))
    if args.write:
        args.write.parent.mkdir(parents=True, exist_ok=True)
        args.write.write_text(json.dumps({"machine": machine(), "args": sys.argv[1:], **t, "card_tiers": rows},
                                         indent=1))


if __name__ == "__main__":
    main()
