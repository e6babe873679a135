"""Phenomenological growth benchmark (seed 003 §4.3, Tables 2-3); medians, never asserted.

Run: `python benchmarks/bench_growth.py [--repeat 7] [--seeds 30] [--picture docs/images/species.png]`.

Prints markdown tables: per species the median time of
:func:`treeform.growth.phenomenological.grow` (``--repeat`` runs of seed 0), its branch
(node) and default leaf counts, and the distributions over ``--seeds`` seeds of the
species-character metrics of the issue: height / crown width, the mean direction (Y) of the
twig tips, and the crown flatness (crown height / crown width), with the pairwise
acceptance checks (pine vs oak, willow tips, acacia vs maple). ``--picture`` also renders all
seven species side by side at the same scale.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from _common import machine  # benchmarks/ is on sys.path when a script runs

ROOT = Path(__file__).resolve().parents[1]



def bench_species(repeat: int, seeds: int):
    from treeform.growth.phenomenological import grow
    from treeform.growth.species import SPECIES, load_species
    from treeform.methods.learned import GrowConfig
    from treeform.growth.leaves import twig_nodes
    from treeform.methods.learned.grow import shape_metrics
    from treeform.metrics import tree_metrics

    cfg = GrowConfig()
    grow(load_species("oak"), seed=0)  # warm-up (imports)
    timing, shapes = {}, {}
    for sp in SPECIES:
        p = load_species(sp)
        times = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            sk = grow(p, seed=0)
            times.append(time.perf_counter() - t0)
        leaves = int(round(cfg.leaves_per_twig * len(twig_nodes(sk, cfg.twig_tips))))
        timing[sp] = (statistics.median(times), sk.n_nodes, leaves)
        rows = []
        for s in range(seeds):
            sk = grow(p, seed=s)
            tf = tree_metrics(sk)
            rows.append({**shape_metrics(sk), "nodes": sk.n_nodes,
                         "branching_angle": tf["branching_angle_deg"], "trunk_diameter": tf["trunk_diameter_m"],
                         "biomass": tf["biomass_m3"]})
        shapes[sp] = {k: np.array([r[k] for r in rows], float) for k in rows[0]}
    return timing, shapes


def _dist(a: np.ndarray) -> str:
    return f"{a.mean():.2f} ± {a.std():.2f} ({a.min():.2f}–{a.max():.2f})"


def species_picture(path: Path, *, seed: int = 0, tile=(320, 440), span: float = 34.0) -> None:
    """All seven species side by side, front view, same camera and scale, labelled."""
    from PIL import Image, ImageDraw, ImageFont

    from treeform.growth.species import SPECIES
    from treeform.io import write_png
    from treeform.methods.learned.grow import grow_tree, preview_lighting
    from treeform.render import Renderer, to_uint8_rgb
    from treeform.structures import Camera

    w, h = tile
    dist = 60.0
    fov = 2 * math.degrees(math.atan(span / 2 / dist))
    cy = span / 2 - 0.5
    label = 32
    out = Image.new("RGB", (w * len(SPECIES), h + label), (255, 255, 255))
    draw = ImageDraw.Draw(out)
    try:
        font = ImageFont.truetype("DejaVuSans.ttf", 20)
    except OSError:
        font = ImageFont.load_default()
    for k, sp in enumerate(SPECIES):
        res = grow_tree(sp, seed=seed, lod="high")
        # same distance and field of view for every species (same scale), centred on its crown
        lo, hi = res.foliage.positions.min(0), res.foliage.positions.max(0)
        cx, cz = 0.5 * (lo[0] + hi[0]), 0.5 * (lo[2] + hi[2])
        cam = Camera(w, h, fov, (cx, cy, cz + dist), (cx, cy, cz), (0.0, 1.0, 0.0), near=dist / 3, far=3 * dist)
        renderer = Renderer(cam, lighting=preview_lighting())
        try:
            out.paste(Image.fromarray(to_uint8_rgb(renderer.render(res.mesh).color)), (w * k, 0))
        finally:
            renderer.release()
        text = f"{sp}  ({res.metrics['height']:.0f} m)"
        draw.text((w * k + (w - draw.textlength(text, font=font)) / 2, h + 5), text, fill=(40, 40, 40), font=font)
    # a 5 m scale bar at the top left
    px = 5.0 / span * h
    draw.line([(16, 24), (16 + px, 24)], fill=(60, 60, 60), width=3)
    draw.text((22 + px, 12), "5 m", fill=(60, 60, 60), font=font)
    write_png(np.asarray(out), path)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--seeds", type=int, default=30)
    ap.add_argument("--picture", type=Path, default=None, help="also write the species picture here")
    ap.add_argument("--metrics-plot", type=Path, default=None,
                    help="also write box plots of the per-species metric distributions here (docs/images/metrics.png)")
    args = ap.parse_args()
    sys.path.insert(0, str(ROOT / "src"))
    timing, shapes = bench_species(args.repeat, args.seeds)
    print(f"machine: {machine()}\n")
    print(f"grow(species, seed=0): median of {args.repeat} runs; branches = skeleton nodes; leaves = default "
          "leaf clusters (3 per twig)\n")
    print("| species | grow median (s) | branches | leaves | branches over seeds (min–median–max) |")
    print("|---|---|---|---|---|")
    for sp, (t, n, leaves) in timing.items():
        a = shapes[sp]["nodes"]
        print(f"| {sp} | {t:.3f} | {n} | {leaves} | {a.min():.0f}–{np.median(a):.0f}–{a.max():.0f} |")
    print(f"\n{args.seeds} seeds per species, mean ± std (min–max):\n")
    print("| species | height (m) | crown width (m) | height / crown width | tip direction y | "
          "crown height / crown width |")
    print("|---|---|---|---|---|---|")
    for sp, a in shapes.items():
        print(f"| {sp} | {_dist(a['height'])} | {_dist(a['crown_width'])} | {_dist(a['slenderness'])} | "
              f"{_dist(a['tip_direction_y'])} | {_dist(a['crown_flatness'])} |")
    s = shapes
    n = args.seeds
    print("\nacceptance (per seed):")
    print(f"- pine height/width > oak height/width: {int(np.sum(s['pine']['slenderness'] > s['oak']['slenderness']))}"
          f"/{n}")
    print(f"- willow mean twig-tip direction below horizontal: {int(np.sum(s['willow']['tip_direction_y'] < 0))}/{n}")
    print(f"- acacia crown flatter than maple: "
          f"{int(np.sum(s['acacia']['crown_flatness'] < s['maple']['crown_flatness']))}/{n}")
    if args.picture is not None:
        species_picture(args.picture)
        print(f"\nwrote {args.picture}")
    if args.metrics_plot is not None:
        from PIL import Image

        from treeform.report.plots import box_plots

        titles = {"height": "height (m)", "slenderness": "height / crown width", "crown_flatness":
                  "crown height / crown width", "tip_direction_y": "twig-tip direction y (<0: drooping)",
                  "branching_angle": "branching angle (deg)", "trunk_diameter": "trunk diameter (m)",
                  "biomass": "biomass (m^3)", "nodes": "branches (nodes)", "crown_width": "crown width (m)"}
        keys = ["height", "slenderness", "crown_flatness", "tip_direction_y", "branching_angle", "trunk_diameter",
                "biomass", "nodes", "crown_width"]
        Image.fromarray(box_plots(shapes, keys, titles=titles, panel=(420, 280))).save(args.metrics_plot)
        print(f"wrote {args.metrics_plot} ({args.seeds} seeds per species)")


if __name__ == "__main__":
    main()
