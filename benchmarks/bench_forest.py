"""Forest rendering with the level-of-detail switch (issue 15, seed 001 §5.1).

Three trees (the bundled sample reconstructed by the envelope route, oak and pine grown by
``treeform grow``) get their impostor sets (``treeform impostor``); ``render_forest`` scatters
N instances of them over a W x W ground and draws a fly-through: clipped billboard clouds
nearer than d, relief-mapped RDMs beyond. With ``--baseline`` the same frames are drawn with
every visible tree as its full mesh, in the same process, so the speed-up is a ratio measured
side by side. Frame times are the renderer's draw time (``glFinish`` before and after; the
read-back of the picture is not counted), median over the frames.

Run: `.venv/bin/python benchmarks/bench_forest.py [--trees 50000] [--area 2000] [--size 1920x1080]
[--frames 3] [--switch-distance 200] [--baseline] [--write out/bench_forest.json] [--out DIR]`
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

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
    ap.add_argument("--species", default="sample,oak,pine")
    ap.add_argument("--out", type=Path, default=None, help="keep the frames here")
    ap.add_argument("--write", type=Path, default=None, help="write the timing JSON here")
    args = ap.parse_args()
    from treeform.methods.envelope.forest import render_forest
    from treeform.methods.envelope.impostor import make_impostor

    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        t0 = time.perf_counter()
        trees = make_trees(work / "species", args.species.split(","))
        for d in trees.values():
            make_impostor(d)
        prep = time.perf_counter() - t0
        res = render_forest(work / "species", out=args.out, trees=args.trees, area=(args.area, args.area),
                            size=args.size, frames=args.frames, switch_distance=args.switch_distance,
                            baseline=args.baseline)
    t = res.timing
    print(f"# {machine()} ({t['renderer']})")
    print(f"# species {args.species}: trees and impostors made in {prep:.1f} s")
    print(f"{t['trees']} trees on {args.area:.0f} m x {args.area:.0f} m, {args.size}, d = {args.switch_distance:.0f} m, "
          f"{t['frames']} frames: visible {t['visible_trees']:.0f} (near {t['near_trees']:.0f}, far {t['far_trees']:.0f})")
    print(f"LoD frame: {t['ms_per_frame']:.1f} ms median; trees/ms cloud {t['trees_per_ms']['cloud']}, "
          f"relief {t['trees_per_ms']['relief']}")
    if args.baseline:
        print(f"full meshes: {t['baseline_ms_per_frame']:.1f} ms median ({t['trees_per_ms']['mesh']} trees/ms) "
              f"-> speed-up {t['speedup']:.1f}x")
    for name, mem in t["memory_per_species_bytes"].items():
        print(f"memory {name}: {mem['total'] / 2**20:.2f} MiB "
              + ", ".join(f"{k} {v / 2**20:.2f}" for k, v in mem.items() if k != "total"))
    if args.write:
        args.write.parent.mkdir(parents=True, exist_ok=True)
        args.write.write_text(json.dumps({"machine": machine(), "args": sys.argv[1:], **t}, indent=1))


if __name__ == "__main__":
    main()
