"""treeform benchmarks (medians; never asserted). Run: `make bench` or `python benchmarks/run.py [--repeat N]`.

Prints a markdown table and writes benchmarks/results.json with the machine description.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from _common import machine, median_time  # benchmarks/ is on sys.path when a script runs

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "src" / "treeform" / "data" / "Celtis_occidentalis_1.jpg"



def bench_reconstruct(repeat, method: str = "envelope"):
    """Median seconds of one method's reconstruct of the sample (warm), per-stage medians and the last metrics."""
    import importlib

    from treeform.methods import METHODS

    module, func = METHODS[method][2].split(":")
    reconstruct = getattr(importlib.import_module(module), func)
    stages = {}
    out = Path(tempfile.mkdtemp(prefix=f"treeform-bench-{method}-"))
    reconstruct(SAMPLE, out=out / "warm")  # warm-up: imports, GL context, onnxruntime sessions
    totals = []
    for i in range(repeat):
        t0 = time.perf_counter()
        res = reconstruct(SAMPLE, out=out / f"r{i}")
        totals.append(time.perf_counter() - t0)
        for k, v in res.metrics["timings"].items():
            stages.setdefault(k, []).append(v)
    return statistics.median(totals), {k: statistics.median(v) for k, v in stages.items()}, res.metrics


def bench_cold_cli(repeat):
    exe = Path(sys.executable).parent / "treeform"
    out = Path(tempfile.mkdtemp(prefix="treeform-cli-"))
    t_version, _ = median_time(lambda: subprocess.run([str(exe), "--version"], check=True, capture_output=True), repeat)
    t_cli, _ = median_time(lambda: subprocess.run([str(exe), "reconstruct", str(SAMPLE), "--out", str(out / "x")],
                                                  check=True, capture_output=True), max(1, repeat // 2))
    return t_version, t_cli


def bench_space_colonization(repeat):
    from treeform.growth import blue_noise_points, space_colonization

    inside = lambda p: np.linalg.norm((p - [0, 6, 0]) / [3, 2.5, 3], axis=1) < 1  # noqa: E731
    att = blue_noise_points(inside, ([-3, 3.5, -3], [3, 8.5, 3]), 10_000, seed=0)
    trunk = np.stack([np.zeros(10), np.linspace(0, 3.6, 10), np.zeros(10)], 1)
    r_mean = 2.8
    run = lambda: space_colonization(att, trunk, influence_radius=0.5 * r_mean, kill_distance=0.1 * r_mean,  # noqa: E731
                                     segment_length=0.04 * r_mean)
    t, _ = median_time(run, repeat)
    t_sample, _ = median_time(lambda: blue_noise_points(inside, ([-3, 3.5, -3], [3, 8.5, 3]), 10_000, seed=0), repeat)
    return t, t_sample, len(run().positions)

def bench_lsystem(repeat):
    """Medians of the L-system (seed 004 §4): a whole pine, a dressed 3-branch skeleton, B-spline smoothing."""
    from treeform.geometry import bspline_skeleton
    from treeform.growth.lsystem import dress_skeleton, lsystem_tree

    t_tree, _ = median_time(lambda: lsystem_tree("pine", seed=0), repeat)
    tree = lsystem_tree("pine", seed=0)
    trunk = np.stack([np.zeros(9), np.linspace(0, 8, 9), np.zeros(9)], 1)
    arms = [np.array([[0, 4, 0], [sx * 1.5, 5, sz], [sx * 3, 6, 2 * sz]]) for sx, sz in ((-1, 0.5), (1, -0.5), (0.3, 1))]
    radius = [np.r_[np.zeros(3), np.full(6, 1.5)]] + [np.array([1.2, 1.5, 1.0])] * 3
    dress = lambda: dress_skeleton([trunk] + arms, radius, preset="oak", seed=0, defines={"density": 6.0})  # noqa: E731
    t_dress, _ = median_time(dress, repeat)
    dressed = dress()
    t_spline, _ = median_time(lambda: bspline_skeleton(tree.skeleton, samples_per_segment=2), repeat)
    return (t_tree, tree.skeleton.n_nodes, tree.modules), (t_dress, len(dressed.foliage)), (t_spline, tree.skeleton.n_nodes)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=7)
    args = ap.parse_args()
    rows = []
    total, stages, metrics = bench_reconstruct(args.repeat)
    rows.append(("reconstruct, 450x600 photo, in-process (median)", total))
    for k, v in stages.items():
        rows.append((f"  stage {k}", v))
    total_l, stages_l, metrics_l = bench_reconstruct(args.repeat, "learned")
    rows.append(("reconstruct --method learned, 450x600 photo, in-process (median)", total_l))
    for k, v in stages_l.items():
        rows.append((f"  stage {k}" + (" (inside grow)" if k in ("leaves", "mesh") else ""), v))
    total_a, stages_a, metrics_a = bench_reconstruct(args.repeat, "abs")
    rows.append((f"reconstruct --method abs ({len(metrics_a['candidates'])} candidates), 450x600 photo, "
                 "in-process (median)", total_a))
    for k, v in stages_a.items():
        rows.append((f"  stage {k}", v))
    (t_ls, ls_nodes, ls_modules), (t_dr, dr_leaves), (t_bs, bs_nodes) = bench_lsystem(args.repeat)
    rows.append((f"L-system: whole pine ({ls_modules} modules, {ls_nodes} nodes)", t_ls))
    rows.append((f"L-system: dress a 4-branch skeleton, oak, density 6 ({dr_leaves} leaves)", t_dr))
    rows.append((f"B-spline skeleton, {bs_nodes} nodes, 2 samples per segment", t_bs))
    t_sc, t_bn, nodes = bench_space_colonization(args.repeat)
    rows.append((f"space colonization, 10,000 attractors ({nodes} nodes)", t_sc))
    rows.append(("blue-noise sampling, 10,000 attractors", t_bn))
    t_version, t_cli = bench_cold_cli(max(3, args.repeat // 2))
    rows.append(("`treeform --version` (interpreter start + import)", t_version))
    rows.append(("`treeform reconstruct` as a fresh process (includes start, imports, GL context)", t_cli))
    print(f"machine: {machine()}\n")
    print("| benchmark | median (s) |\n|---|---|")
    for name, t in rows:
        print(f"| {name} | {t:.3f} |")
    print(f"\nreprojection error {100 * metrics['reprojection_error']:.1f} %, IoU {metrics['iou']:.3f}, "
          f"triangles {metrics['triangles']}")
    print(f"learned: reprojection error {100 * metrics_l['reprojection_error']:.1f} %, IoU {metrics_l['iou']:.3f}, "
          f"species {metrics_l['species']}, triangles {metrics_l['triangles']}")
    print(f"abs: reprojection error {100 * metrics_a['reprojection_error']:.1f} % (first model "
          f"{100 * metrics_a['search_error_first']:.1f} %, best {100 * metrics_a['search_error_best']:.1f} % at the "
          f"search size), species {metrics_a['species']}, triangles {metrics_a['triangles']}")
    (ROOT / "benchmarks" / "results.json").write_text(json.dumps(
        {"machine": machine(), "command": "make bench", "repeat": args.repeat,
         "results": {name.strip(): round(t, 4) for name, t in rows}}, indent=1))


if __name__ == "__main__":
    main()
