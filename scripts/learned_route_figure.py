"""docs/images/learned_route.jpg: the learned route on the bundled sample, as seed 003 grows it
(top: grown in the predicted RBV, drawn leaves) and as treeform ships it (bottom: carved to the
photo's silhouette, filled out to it, photo-textured leaf cards).

Run: `.venv/bin/python scripts/learned_route_figure.py [--out docs/images/learned_route.jpg]`
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "src" / "treeform" / "data" / "Celtis_occidentalis_1.jpg"


def main():
    from treeform.methods.learned.pipeline import reconstruct

    ap = argparse.ArgumentParser()
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "images" / "learned_route.jpg")
    args = ap.parse_args()
    rows = []
    for label, opts in (("as published: grown in the RBV, drawn leaves",
                         dict(carve=False, fill=False, leaf_texture="procedural")),
                        ("treeform: carved to the silhouette, filled, photo leaves", {})):
        res = reconstruct(SAMPLE, seed=0, **opts)
        m = res.metrics
        strip = Image.fromarray(res.preview)
        text = f"{label} - error {100 * m['reprojection_error']:.1f} %, front SSIM {m['front_ssim']:.2f}"
        bar = Image.new("RGB", (strip.width, 28), "white")
        ImageDraw.Draw(bar).text((8, 8), text, fill=(0, 0, 0))
        rows.append(np.concatenate([np.asarray(bar), np.asarray(strip.convert("RGB"))], axis=0))
    w = max(r.shape[1] for r in rows)
    rows = [np.pad(r, ((0, 0), (0, w - r.shape[1]), (0, 0)), constant_values=255) for r in rows]
    Image.fromarray(np.concatenate(rows, axis=0)).save(args.out, quality=85)
    print(args.out)


if __name__ == "__main__":
    main()
