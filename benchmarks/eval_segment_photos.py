"""Both segmenters on every real photo of ../shared/data/photos: overlays side by side.

Writes out/segment_photos/<photo>.jpg (photo | classical | learned) for every photo, a grid of
all of them (out/segment_photos/all.jpg) and, with --readme, the README's grid of the named
photos (docs/images/segmentation.jpg). No ground truth exists for these photos: this is for
looking (is the main tree found, are autumn crowns foliage), and it prints how much of each
photo each segmenter calls tree and how much the two agree.

Run: `.venv/bin/python benchmarks/eval_segment_photos.py [--readme]`
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

ROOT = Path(__file__).resolve().parents[1]
PHOTOS = ROOT.parent / "shared" / "data" / "photos"
README_PHOTOS = ("Acer_rubrum_2", "Morus_rubra_1", "Juniperus_virginiana_2", "Celtis_occidentalis_2",
                 "Quercus_alba_1", "Pinus_taeda_2", "Catalpa_speciosa_1", "Sequoiadendron_giganteum_1")


def _label(img: np.ndarray, text: str) -> np.ndarray:
    im = Image.fromarray(img)
    d = ImageDraw.Draw(im)
    d.rectangle([0, 0, 8 * len(text) + 8, 16], fill=(0, 0, 0))
    d.text((4, 2), text, fill=(255, 255, 255))
    return np.asarray(im)


def main():
    from treeform._shared.errors import NoTreeFoundError
    from treeform.io import read_photo
    from treeform.report import compose_strip, segmentation_overlay
    from treeform.segment import segment
    from treeform.structures import Segmentation

    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default=str(ROOT / "out" / "segment_photos"))
    ap.add_argument("--readme", action="store_true", help="also write docs/images/segmentation.jpg")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    rows = {}
    print("| photo | classical tree % | learned tree % | agreement IoU |\n|---|---|---|---|")
    for path in sorted(PHOTOS.glob("*.jpg")):
        ph = read_photo(path, max_size=640)
        img = ph.image
        tiles, masks = [_label(img, path.stem)], []
        for method in ("classical", "learned"):
            try:
                seg = segment(img, method=method)
            except NoTreeFoundError:
                seg = Segmentation(np.zeros(img.shape[:2], np.uint8))
            masks.append(seg.tree_mask)
            tiles.append(_label(segmentation_overlay(img, seg), method))
        strip = compose_strip(tiles, height=240)
        rows[path.stem] = strip
        Image.fromarray(strip).save(out / f"{path.stem}.jpg", quality=88)
        a, b = masks
        union = (a | b).sum()
        agree = (a & b).sum() / union if union else 1.0
        print(f"| {path.stem} | {100 * a.mean():.0f} | {100 * b.mean():.0f} | {agree:.2f} |")

    def grid(names, width=720):
        strips = []
        for n in names:
            s = rows[n]
            h = int(round(s.shape[0] * width / s.shape[1]))
            strips.append(np.asarray(Image.fromarray(s).resize((width, h), Image.LANCZOS)))
        gap = np.full((6, width, 3), 255, np.uint8)
        return np.concatenate([x for s in strips for x in (s, gap)][:-1], 0)

    Image.fromarray(grid(sorted(rows))).save(out / "all.jpg", quality=85)
    if args.readme:
        Image.fromarray(grid([n for n in README_PHOTOS if n in rows])).save(
            ROOT / "docs" / "images" / "segmentation.jpg", quality=78)
    print(f"\noverlays in {out}")


if __name__ == "__main__":
    main()
