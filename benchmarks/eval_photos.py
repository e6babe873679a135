"""Quality on real photos: reconstruct every photo of ../shared/data/photos with a given isolation
rating and report reprojection error, IoU, depth/width, front SSIM and colour distance. Writes out/eval/<name>/ and a summary.

Run: `.venv/bin/python benchmarks/eval_photos.py [--rating isolated] [--segmenter learned] [--out out/eval]`
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
    from treeform._shared.errors import TreeformError
    from treeform.methods.envelope.pipeline import reconstruct

    ap = argparse.ArgumentParser()
    ap.add_argument("--rating", default="isolated")
    ap.add_argument("--out", default=str(ROOT / "out" / "eval"))
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--segmenter", default=None, help="classical | learned (default: the method's)")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    with open(PHOTOS / "ATTRIBUTION.csv") as f:
        names = [r["file"] for r in csv.DictReader(f) if r["isolation_visual"] == args.rating]
    rows = {}
    for name in sorted(names):
        stem = Path(name).stem
        try:
            opts = {"segmenter": args.segmenter} if args.segmenter else {}
            res = reconstruct(PHOTOS / name, out=out / stem, seed=args.seed, **opts)
        except TreeformError as exc:
            rows[stem] = {"error": str(exc)}
            print(f"{stem:32s} FAILED: {exc}")
            continue
        m = res.metrics
        rows[stem] = {k: m[k] for k in ("reprojection_error", "iou", "depth_width_ratio", "front_ssim",
                                        "front_color_distance", "stems_at_5_percent", "total_seconds")}
        print(f"{stem:32s} err {100 * m['reprojection_error']:5.1f} %  IoU {m['iou']:.3f}  "
              f"depth/width {m['depth_width_ratio']:.2f}  SSIM {m['front_ssim']:.3f}  "
              f"colour {m['front_color_distance']:.3f}  stems {m['stems_at_5_percent']}  {m['total_seconds']:.2f} s")
    ok = [r for r in rows.values() if "error" not in r]
    errs = [r["reprojection_error"] for r in ok]
    dws = [r["depth_width_ratio"] for r in ok]
    summary = {"rating": args.rating, "n": len(rows), "failed": len(rows) - len(ok),
               "median_reprojection_error": statistics.median(errs) if errs else None,
               "worst_reprojection_error": max(errs) if errs else None,
               "median_iou": statistics.median(r["iou"] for r in ok) if ok else None,
               "median_front_ssim": statistics.median(r["front_ssim"] for r in ok) if ok else None,
               "one_stem": sum(r["stems_at_5_percent"] == 1 for r in ok),
               "median_front_color_distance": statistics.median(r["front_color_distance"] for r in ok) if ok else None,
               "depth_width_min": min(dws) if dws else None, "depth_width_max": max(dws) if dws else None,
               "per_photo": rows}
    (out / f"summary_{args.rating}.json").write_text(json.dumps(summary, indent=1))
    print(json.dumps({k: v for k, v in summary.items() if k != "per_photo"}, indent=1))


if __name__ == "__main__":
    main()
