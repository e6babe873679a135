"""Make docs/images/seasons.jpg: three autumn photos' colours on three green trees (seed 000 §5.3).

Top row: the autumn photos, with what is not their tree dimmed (the only pixels the
colours are taken from; the trunk, when one is visible, tinted). Then one row per
exemplar: the exemplar as it is, and after :func:`season_transfer` with each photo.
The exemplars are the CC0 CesiumGS billboard and two billboards that ``treeform
billboard`` cuts out of green, public-domain/CC0 summer photos. Prints the mean hue of
each crown and trunk before and after (CIE L*a*b* hue angle, degrees).

Run: `.venv/bin/python scripts/season_sheet.py [--data ../shared/data] [--out docs/images/seasons.jpg]`
(same inputs -> same picture).
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
PHOTOS = ("Acer_saccharinum_2.jpg", "Morus_rubra_1.jpg", "Asimina_triloba_1.jpg")  # yellow autumn crowns
TREES = (("billboards", "cesium_tree_billboard.png"),  # CC0
         ("photos", "Celtis_occidentalis_1.jpg"),  # public domain, cut out with `treeform billboard`
         ("photos", "Maclura_pomifera_2.jpg"))  # CC0, likewise
BACKGROUND = (200, 212, 224)  # a pale sky, so that pale yellow leaves show


def _exemplar(data: Path, folder: str, name: str, size: int):
    from treeform.io import read_rgba
    from treeform.methods.variations import billboard, process_exemplar

    path = data / folder / name
    rgba = read_rgba(path) if folder == "billboards" else billboard(path, seed=0, sky_gaps=True).rgba
    return process_exemplar(rgba, size=size, name=name)


def _over(rgba: np.ndarray) -> np.ndarray:
    a = rgba[..., 3:4].astype(np.float32) / 255.0
    return np.rint(rgba[..., :3] * a + np.array(BACKGROUND, np.float32) * (1 - a)).astype(np.uint8)


def _fit(img: np.ndarray, tile: int) -> np.ndarray:
    h, w = img.shape[:2]
    s = tile / max(h, w)
    small = cv2.resize(img, (max(1, round(w * s)), max(1, round(h * s))), interpolation=cv2.INTER_AREA)
    out = np.empty((tile, tile, 3), np.uint8)
    out[:] = BACKGROUND
    y, x = (tile - small.shape[0]) // 2, (tile - small.shape[1]) // 2
    out[y:y + small.shape[0], x:x + small.shape[1]] = small
    return out


def _label(tile: np.ndarray, text: str) -> np.ndarray:
    bar = np.full((22, tile.shape[1], 3), 255, np.uint8)
    cv2.putText(bar, text, (6, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (40, 40, 40), 1, cv2.LINE_AA)
    return np.concatenate([tile, bar], 0)


def _hue(rgba: np.ndarray, where: np.ndarray) -> str:
    from treeform.methods.variations.season import mean_hue

    px = rgba[where & (rgba[..., 3] > 0)][:, :3]
    return f"{mean_hue(px)[0]:6.1f}" if len(px) else "     -"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "images" / "seasons.jpg")
    ap.add_argument("--size", type=int, default=512, help="side of the normalised exemplars")
    ap.add_argument("--tile", type=int, default=300)
    args = ap.parse_args(argv)

    from treeform.io import read_photo
    from treeform.methods.variations import season_reference, season_transfer
    from treeform.methods.variations.season import crown_trunk_labels, mean_hue

    photos = [read_photo(args.data / "photos" / p).image for p in PHOTOS]
    refs = [season_reference(img, seed=0) for img in photos]
    trees = [_exemplar(args.data, folder, name, args.size) for folder, name in TREES]

    header = []
    for name, img, ref in zip(PHOTOS, photos, refs):
        vis = img.astype(np.float32)
        vis[ref.labels == 0] = 0.3 * vis[ref.labels == 0] + 0.7 * 40
        vis[ref.labels == 2] = 0.5 * vis[ref.labels == 2] + 0.5 * np.array([255, 0, 255])
        trunk = f"trunk {mean_hue(ref.trunk)[0]:.0f}" if ref.has_trunk else "no trunk"
        print(f"{name:24s} crown hue {mean_hue(ref.crown)[0]:6.1f}  {trunk}")
        header.append(_label(_fit(vis.astype(np.uint8), args.tile),
                             f"{name.split('_')[0]} {name.split('_')[1]}: crown {mean_hue(ref.crown)[0]:.0f} deg"))
    corner = _label(_fit(np.full((8, 8, 3), 255, np.uint8), args.tile), "")
    cv2.putText(corner, "exemplar  |  in the colours of:", (10, args.tile // 2), cv2.FONT_HERSHEY_SIMPLEX, 0.5,
                (40, 40, 40), 1, cv2.LINE_AA)
    rows = [np.concatenate([corner] + header, 1)]
    print(f"{'exemplar':28s} {'':10s} crown hue  trunk hue")
    for (_, name), ex in zip(TREES, trees):
        labels = crown_trunk_labels(ex.rgba, ex.labels)  # what the transfer calls crown and trunk
        crown, trunk = labels == 1, labels == 2
        print(f"{name:28s} {'before':10s} {_hue(ex.rgba, crown)}  {_hue(ex.rgba, trunk)}")
        tiles = [_label(_fit(_over(ex.rgba), args.tile), f"{name.split('.')[0][:26]}: crown {_hue(ex.rgba, crown).strip()}")]
        for pname, ref in zip(PHOTOS, refs):
            out = season_transfer(ex.rgba, ex.labels, ref)
            print(f"{'':28s} {pname.split('_')[0][:10]:10s} {_hue(out, crown)}  {_hue(out, trunk)}")
            tiles.append(_label(_fit(_over(out), args.tile), f"crown {_hue(out, crown).strip()} deg"))
        rows.append(np.concatenate(tiles, 1))
    sheet = np.concatenate(rows, 0)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    from PIL import Image

    tmp = args.out.with_name(f".{args.out.name}.{os.getpid()}.tmp.jpg")
    Image.fromarray(sheet).save(tmp, quality=88, optimize=True)
    os.replace(tmp, args.out)
    print(f"{args.out}: {sheet.shape[1]}x{sheet.shape[0]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
