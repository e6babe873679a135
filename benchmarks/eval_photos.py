"""Quality on real photos: reconstruct every photo of ../shared/data/photos with a given isolation
rating and report reprojection error, IoU, depth/width, front SSIM, colour distance and how open the
side view is beside the photo's own tree mask (``silhouette_gaps``). Writes out/eval/<name>/ and a summary.

Run: `.venv/bin/python benchmarks/eval_photos.py [--rating isolated] [--method envelope|learned|abs]
[--segmenter learned] [--candidates N] [--out out/eval]`
"""

from __future__ import annotations

import argparse
import csv
import json
import statistics
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PHOTOS = ROOT.parent / "shared" / "data" / "photos"


def main():
    import importlib

    from treeform._shared.errors import TreeformError
    from treeform.methods import METHODS
    from treeform.metrics import silhouette_gaps

    ap = argparse.ArgumentParser()
    ap.add_argument("--rating", default="isolated")
    ap.add_argument("--out", default=str(ROOT / "out" / "eval"))
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--segmenter", default=None, help="classical | learned (default: the method's)")
    ap.add_argument("--method", default="envelope", help="a single-photo method of the registry")
    ap.add_argument("--candidates", type=int, default=None, help="abs: models tested per photo")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="a config option of the method (VALUE as JSON, else a string), e.g. --set carve=false")
    args = ap.parse_args()
    options = {}
    for item in args.set:
        key, _, value = item.partition("=")
        try:
            options[key] = json.loads(value)
        except json.JSONDecodeError:
            options[key] = value
    module, func = METHODS[args.method][2].split(":")
    reconstruct = getattr(importlib.import_module(module), func)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    with open(PHOTOS / "ATTRIBUTION.csv") as f:
        names = [r["file"] for r in csv.DictReader(f) if r["isolation_visual"] == args.rating]
    rows = {}
    for name in sorted(names):
        stem = Path(name).stem
        try:
            opts = {"segmenter": args.segmenter} if args.segmenter else {}
            if args.candidates is not None:
                opts["candidates"] = args.candidates
            opts.update(options)
            res = reconstruct(PHOTOS / name, out=out / stem, seed=args.seed, **opts)
        except TreeformError as exc:
            rows[stem] = {"error": str(exc)}
            print(f"{stem:32s} FAILED: {exc}")
            continue
        m = res.metrics
        rows[stem] = {k: m[k] for k in ("reprojection_error", "iou", "depth_width_ratio", "front_ssim",
                                        "front_color_distance", "side_color_distance", "stems_at_5_percent",
                                        "total_seconds")}
        # how open the crown is from the side, beside the photo's own tree mask (a solid ball scores 0)
        if "side" in getattr(res, "renders", {}):
            rows[stem]["side_gaps"] = silhouette_gaps(res.renders["side"].mask)
            rows[stem]["photo_gaps"] = silhouette_gaps(res.segmentation.tree_mask)
        for k in ("search_error_first", "search_error_best", "n_branches"):  # abs: the search's gain
            if k in m:
                rows[stem][k] = m[k]
        print(f"{stem:32s} err {100 * m['reprojection_error']:5.1f} %  IoU {m['iou']:.3f}  "
              f"depth/width {m['depth_width_ratio']:.2f}  SSIM {m['front_ssim']:.3f}  "
              f"colour {m['front_color_distance']:.3f} side {m['side_color_distance']:.3f}  "
              f"stems {m['stems_at_5_percent']}  {m['total_seconds']:.2f} s")
    ok = [r for r in rows.values() if "error" not in r]
    errs = [r["reprojection_error"] for r in ok]
    dws = [r["depth_width_ratio"] for r in ok]
    summary = {"method": args.method, "options": options, "rating": args.rating, "n": len(rows), "failed": len(rows) - len(ok),
               "median_total_seconds": statistics.median(r["total_seconds"] for r in ok) if ok else None,
               "median_reprojection_error": statistics.median(errs) if errs else None,
               "worst_reprojection_error": max(errs) if errs else None,
               "median_iou": statistics.median(r["iou"] for r in ok) if ok else None,
               "median_front_ssim": statistics.median(r["front_ssim"] for r in ok) if ok else None,
               "one_stem": sum(r["stems_at_5_percent"] == 1 for r in ok),
               "median_front_color_distance": statistics.median(r["front_color_distance"] for r in ok) if ok else None,
               "median_side_color_distance": statistics.median(r["side_color_distance"] for r in ok) if ok else None,
               "depth_width_min": min(dws) if dws else None, "depth_width_max": max(dws) if dws else None,
               "per_photo": rows}
    if ok and "side_gaps" in ok[0]:
        summary["median_side_gaps"] = statistics.median(r["side_gaps"] for r in ok)
        summary["median_photo_gaps"] = statistics.median(r["photo_gaps"] for r in ok)
    if ok and "search_error_first" in ok[0]:
        summary["median_search_error_first"] = statistics.median(r["search_error_first"] for r in ok)
        summary["median_search_error_best"] = statistics.median(r["search_error_best"] for r in ok)
    (out / f"summary_{args.method}_{args.rating}.json").write_text(json.dumps(summary, indent=1))
    print(json.dumps({k: v for k, v in summary.items() if k != "per_photo"}, indent=1))


if __name__ == "__main__":
    main()
