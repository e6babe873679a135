"""Make docs/images/skeleton_{field,dce,cuts,wood}.png: seed 004 §3 on a real photo, and the wood skeleton.

- ``skeleton_field.png`` (Fig. 2 / 3): Cornea et al.'s field (contour sources only) and the
  field with the cuts as artificial contour points (eq. (1)); log magnitude in grey, arrows
  on a grid, the branches over the second.
- ``skeleton_dce.png`` (Fig. 5): the photo's tree contour, its DCE polygons with 24 and 2n
  vertices, the inward vertices in blue.
- ``skeleton_cuts.png`` (Fig. 4 / 7): the cuts, the partition and the final skeleton over the
  photo, with first-order branches only and with the second order.
- ``skeleton_wood.png``: a leafless photo (``--bare``), its segmentation's wood, the foliage
  skeleton (§3: branches from the outline alone) and the wood skeleton (least-cost paths to the
  base along the visible wood) that the abs search proposes when the branches show.

The photo (Celtis occidentalis, Chhe, public domain, via Wikimedia Commons) comes from
``../shared/data/photos``; it is segmented with treeform's classical segmenter.

Run: `.venv/bin/python scripts/skeleton_figures.py [--data ../shared/data] [--out docs/images]
[--photo Celtis_occidentalis_1.jpg] [--bare Platanus_occidentalis_2.jpg] [--n 5] [--seed 0]`
(same inputs -> same pictures).
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

import cv2
import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
PANEL_H = 420  # height of each panel in the sheets


def _load(path: Path, long_side: int = 600) -> np.ndarray:
    im = Image.open(path).convert("RGB")
    s = long_side / max(im.size)
    return np.asarray(im.resize((round(im.size[0] * s), round(im.size[1] * s)), Image.LANCZOS))


def _panel(img: np.ndarray, title: str) -> np.ndarray:
    h, w = img.shape[:2]
    out = cv2.resize(img, (round(w * PANEL_H / h), PANEL_H), interpolation=cv2.INTER_AREA)
    out = np.ascontiguousarray(out)
    cv2.rectangle(out, (0, 0), (out.shape[1], 24), (255, 255, 255), -1)
    cv2.putText(out, title, (6, 17), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
    return out


def _sheet(panels: list[np.ndarray]) -> np.ndarray:
    gap = np.full((PANEL_H, 6, 3), 255, np.uint8)
    parts = []
    for p in panels:
        parts += [p, gap]
    return np.concatenate(parts[:-1], axis=1)


def _save(img: np.ndarray, path: Path) -> None:
    """Write a palette PNG (256 colours), small enough for the docs; atomically."""
    q = Image.fromarray(img).quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    tmp = path.with_suffix(".tmp.png")
    q.save(tmp, optimize=True)
    os.replace(tmp, path)
    print(f"{path}  {path.stat().st_size / 1024:.0f} KB")


def _field_picture(mask: np.ndarray, f: np.ndarray, step: int = 18) -> np.ndarray:
    mag = np.hypot(f[..., 0], f[..., 1])
    lm = np.zeros_like(mag)
    inside = mask & (mag > 0)
    lm[inside] = np.log(mag[inside])
    lo, hi = np.percentile(lm[inside], [2, 98])
    g = np.clip((lm - lo) / max(hi - lo, 1e-9), 0, 1)
    img = np.where(mask, 40 + 180 * g, 255).astype(np.uint8)
    img = np.repeat(img[..., None], 3, axis=2)
    H, W = mask.shape
    for y in range(step // 2, H, step):
        for x in range(step // 2, W, step):
            if not mask[y, x] or mag[y, x] == 0:
                continue
            u = f[y, x] / mag[y, x] * (0.42 * step)
            cv2.arrowedLine(img, (x, y), (int(round(x + u[0])), int(round(y + u[1]))), (0, 150, 255), 1,
                            cv2.LINE_AA, tipLength=0.35)
    return img


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "images")
    ap.add_argument("--photo", default="Celtis_occidentalis_1.jpg")
    ap.add_argument("--bare", default="Platanus_occidentalis_2.jpg", help="a leafless photo for skeleton_wood.png")
    ap.add_argument("--n", type=int, default=5)
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()

    from treeform.segment import segment
    from treeform.skeleton import dce, draw_skeleton, force_field, foliage_skeleton
    from treeform.skeleton.dce import inward_vertices, outer_contour

    image = _load(args.data / "photos" / args.photo)
    mask = segment(image, method="classical", seed=0).tree_mask
    sk1 = foliage_skeleton(mask, n_branches=args.n, levels=1, seed=args.seed)
    sk2 = foliage_skeleton(mask, n_branches=args.n, levels=2, seed=args.seed)
    args.out.mkdir(parents=True, exist_ok=True)

    # Fig. 2 / 3: Cornea's field, then the field with the cuts and the branches
    cornea = _field_picture(mask, force_field(mask))
    cut = _field_picture(mask, sk1.field)
    cut = draw_skeleton(cut, sk1, show_partition=False)
    _save(_sheet([_panel(image, "photo"), _panel(cornea, "Cornea field (contour sources)"),
                  _panel(cut, f"field with {len(sk1.cuts)} cuts (eq. 1) + branches")]),
          args.out / "skeleton_field.png")

    # Fig. 5: contour and DCE polygons (24 and 2n vertices), inward vertices in blue
    contour = outer_contour(mask)
    th = 2
    panels = []
    base = (0.55 * image + 0.45 * 255).astype(np.uint8)
    c0 = base.copy()
    cv2.polylines(c0, [np.round(contour).astype(np.int32).reshape(-1, 1, 2)], True, (220, 0, 0), th, cv2.LINE_AA)
    panels.append(_panel(c0, f"contour ({len(contour)} px)"))
    for nv in (24, 2 * args.n):
        poly = contour[dce(contour, nv)]
        img = base.copy()
        cv2.polylines(img, [np.round(contour).astype(np.int32).reshape(-1, 1, 2)], True, (230, 150, 150), 1,
                      cv2.LINE_AA)
        cv2.polylines(img, [np.round(poly).astype(np.int32).reshape(-1, 1, 2)], True, (0, 140, 0), th, cv2.LINE_AA)
        idx, _ = inward_vertices(poly)
        for k, p in enumerate(poly):
            col = (0, 60, 255) if k in set(idx.tolist()) else (0, 140, 0)
            cv2.circle(img, (int(round(p[0])), int(round(p[1]))), 6 if col[2] == 255 else 4, col, -1, cv2.LINE_AA)
        panels.append(_panel(img, f"DCE, {nv} vertices ({len(idx)} inward, blue)"))
    _save(_sheet(panels), args.out / "skeleton_dce.png")

    # Fig. 4 / 7: cuts, partition, final skeleton
    _save(_sheet([_panel(draw_skeleton(image, sk1), f"{args.n} areas, cuts, first order"),
                  _panel(draw_skeleton(image, sk2), "with second order"),
                  _panel(draw_skeleton(np.full_like(image, 255), sk2, show_partition=False), "skeleton")]),
          args.out / "skeleton_cuts.png")

    # the wood skeleton of a leafless tree, beside the foliage skeleton of the same mask
    from treeform.crown.layout import tree_layout
    from treeform.skeleton import wood_skeleton

    bare = _load(args.data / "photos" / args.bare)
    seg = segment(bare, method="classical", seed=0)
    lay = tree_layout(seg)
    trunk = np.asarray(lay.trunk_path, np.float64)
    wood_img = np.where(seg.wood_mask[..., None], np.array([150, 60, 20], np.uint8),
                        np.where(seg.tree_mask[..., None], np.array([120, 200, 120], np.uint8), 255)).astype(np.uint8)
    fol = foliage_skeleton(lay.crown_mask, n_branches=args.n, levels=2, trunk=trunk, seed=args.seed)
    wsk = wood_skeleton(seg.tree_mask, seg.wood_mask, trunk=trunk, levels=2)
    faded = (0.5 * bare + 0.5 * 255).astype(np.uint8)
    _save(_sheet([_panel(bare, "leafless photo"), _panel(wood_img, "wood (brown) / foliage (green)"),
                  _panel(draw_skeleton(faded, fol), f"foliage skeleton (n = {args.n})"),
                  _panel(draw_skeleton(faded, wsk, show_partition=False),
                         f"wood skeleton ({int((wsk.order == 1).sum())} first order)")]),
          args.out / "skeleton_wood.png")


if __name__ == "__main__":
    main()
