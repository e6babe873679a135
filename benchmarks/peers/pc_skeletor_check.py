"""Sanity check of the pc-skeletor peer on a synthetic tree with known branch axes.

    benchmarks/peers/.venv-pcs/bin/python benchmarks/peers/pc_skeletor_check.py [--points 20000]
        [--down-sample S] [--seed 0]

Builds a tree of cylinders (6 m vertical trunk r=0.2 m on Y, 8 first-order branches r=0.10-0.05 m,
8 second-order twigs r=0.04-0.03 m), samples ~N points on their surfaces (uniform per area) with
1 cm Gaussian noise, runs pc_skeletor_run.py on it in a subprocess and reports: runtime, skeleton
node -> nearest true axis distance (mean / median / p90 / max, and the mean relative to the local
branch radius), and axis coverage (share of axis length within 5 cm / 10 cm of a skeleton node).
Needs only numpy + scipy (both in the peer venv).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

HERE = Path(__file__).resolve().parent


def _unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def make_tree(rng: np.random.Generator):
    """List of (p0, p1, r0, r1) cylinders (tapered) - trunk, branches, twigs. Y up, metres."""
    segs = [(np.zeros(3), np.array([0.0, 6.0, 0.0]), 0.2, 0.2)]
    heights = [2.0, 2.6, 3.2, 3.7, 4.2, 4.7, 5.1, 5.5]
    for k, h in enumerate(heights):
        az = k * 2.39996  # golden angle
        elev = np.deg2rad(25 + 5 * k)
        d = _unit([np.cos(az) * np.cos(elev), np.sin(elev), np.sin(az) * np.cos(elev)])
        length = 3.0 - 0.2 * k
        r0 = 0.10 - 0.006 * k
        p0 = np.array([0.0, h, 0.0])
        p1 = p0 + length * d
        segs.append((p0, p1, r0, max(r0 * 0.6, 0.03)))
        # one twig from the middle of each branch
        q0 = p0 + 0.55 * length * d
        side = _unit(np.cross(d, [0.0, 1.0, 0.0]) * (1 if k % 2 else -1) + 0.6 * np.array([0, 1.0, 0]))
        segs.append((q0, q0 + 1.0 * side, 0.04, 0.03))
    return segs


def sample_surface(segs, n, noise, rng):
    # area of each (tapered) cylinder ~ 2*pi*mean_r*L; points proportional to area
    areas = np.array([2 * np.pi * 0.5 * (r0 + r1) * np.linalg.norm(p1 - p0) for p0, p1, r0, r1 in segs])
    counts = rng.multinomial(n, areas / areas.sum())
    out = []
    for (p0, p1, r0, r1), m in zip(segs, counts):
        axis = p1 - p0
        length = np.linalg.norm(axis)
        a = axis / length
        tmp = np.array([1.0, 0, 0]) if abs(a[0]) < 0.9 else np.array([0, 0, 1.0])
        u = _unit(np.cross(a, tmp))
        v = np.cross(a, u)
        t = rng.random(m)
        th = rng.random(m) * 2 * np.pi
        r = r0 + (r1 - r0) * t
        pts = p0 + np.outer(t * length, a) + (r * np.cos(th))[:, None] * u + (r * np.sin(th))[:, None] * v
        out.append(pts)
    pts = np.vstack(out)
    return pts + rng.normal(scale=noise, size=pts.shape)


def axis_samples(segs, step=0.01):
    pts, rad = [], []
    for p0, p1, r0, r1 in segs:
        m = max(2, int(np.linalg.norm(p1 - p0) / step) + 1)
        t = np.linspace(0, 1, m)
        pts.append(p0 + np.outer(t, p1 - p0))
        rad.append(r0 + (r1 - r0) * t)
    return np.vstack(pts), np.concatenate(rad)


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--points", type=int, default=20000)
    ap.add_argument("--noise", type=float, default=0.01)
    ap.add_argument("--down-sample", type=float, default=None, help="passed to pc_skeletor_run.py")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--keep", help="directory to keep cloud.npy / skeleton.json in")
    args = ap.parse_args()

    rng = np.random.default_rng(args.seed)
    segs = make_tree(rng)
    cloud = sample_surface(segs, args.points, args.noise, rng)
    axis, axis_r = axis_samples(segs)

    work = Path(args.keep) if args.keep else Path(tempfile.mkdtemp(prefix="pcs_check_"))
    work.mkdir(parents=True, exist_ok=True)
    np.save(work / "cloud.npy", cloud)
    cmd = [sys.executable, str(HERE / "pc_skeletor_run.py"), str(work / "cloud.npy"), str(work / "skeleton.json")]
    if args.down_sample is not None:
        cmd += ["--down-sample", str(args.down_sample)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        print(proc.stderr[-3000:], file=sys.stderr)
        print(f"pc_skeletor_run.py failed (rc={proc.returncode})")
        return 1
    res = json.loads((work / "skeleton.json").read_text())
    nodes = np.asarray(res["nodes"], float)

    tree = cKDTree(axis)
    d, idx = tree.query(nodes)
    rel = d / axis_r[idx]
    dn, _ = cKDTree(nodes).query(axis)
    cloud_d, _ = tree.query(cloud)  # reference: input points to axes (~ local radius)
    report = {
        "points": len(cloud),
        "points_used": res["n_points_used"],
        "seconds": round(res["seconds"], 2),
        "down_sample": res["params"]["down_sample"],
        "skeleton_nodes": len(nodes),
        "skeleton_edges": len(res["edges"]),
        "topology_nodes": len(res["topology"]["nodes"]),
        "node_to_axis_mean_m": round(float(d.mean()), 4),
        "node_to_axis_median_m": round(float(np.median(d)), 4),
        "node_to_axis_p90_m": round(float(np.percentile(d, 90)), 4),
        "node_to_axis_max_m": round(float(d.max()), 4),
        "node_to_axis_mean_over_radius": round(float(rel.mean()), 3),
        "input_points_to_axis_mean_m": round(float(cloud_d.mean()), 4),
        "axis_covered_5cm": round(float((dn < 0.05).mean()), 3),
        "axis_covered_10cm": round(float((dn < 0.10).mean()), 3),
        "work_dir": str(work),
    }
    print(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
