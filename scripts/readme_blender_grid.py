"""Make the README's ``docs/images/blender_grid.jpg``: eight real photos and their trees rendered in Blender.

Each photo of ``../shared/data/photos`` is reconstructed (``treeform reconstruct``, envelope
method, seed 0; the two conifers with ``--form conifer``, the rest ``--form auto``), the GLB
opened by Blender's glTF importer and rendered with Cycles (``scripts/blender_view.py``) from the front, the right side and
three-quarter above. Rows: photo | front | side | 3/4. Needs ``make blender`` (bpy in
``.venv-blender``). Credits for the photos: docs/images/CREDITS.md.

    python scripts/readme_blender_grid.py [--data ../shared/data/photos] [--out docs/images/blender_grid.jpg]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

ROOT = Path(__file__).resolve().parents[1]
PHOTOS = {"Celtis_occidentalis_1.jpg": "auto", "Quercus_alba_1.jpg": "auto", "Catalpa_speciosa_1.jpg": "auto",
          "Acer_rubrum_2.jpg": "auto", "Fagus_grandifolia_2.jpg": "auto", "Juglans_nigra_1.jpg": "auto",
          "Thuja_plicata_1.jpg": "conifer", "Pinus_ponderosa_2.jpg": "conifer"}
VIEWS = ("front", "side", "three_quarter")
LABELS = ("photo", "front (Blender, Cycles)", "side", "three-quarter")
BG = np.array([242, 243, 240], np.float32)


def _over_bg(rgba: np.ndarray) -> np.ndarray:
    a = rgba[..., 3:4].astype(np.float32) / 255.0
    return np.clip(rgba[..., :3] * a + BG * (1 - a), 0, 255).astype(np.uint8)


def _fit(im: np.ndarray, h: int) -> np.ndarray:
    pil = Image.fromarray(im)
    return np.asarray(pil.resize((max(1, round(pil.width * h / pil.height)), h), Image.Resampling.LANCZOS))


def main(argv=None) -> None:
    from treeform.methods.envelope.pipeline import reconstruct

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data" / "photos")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "images" / "blender_grid.jpg")
    ap.add_argument("--blender-python", default=str(ROOT / ".venv-blender" / "bin" / "python"))
    ap.add_argument("--size", type=int, default=360, help="row height in pixels")
    ap.add_argument("--samples", type=int, default=32)
    args = ap.parse_args(argv)
    rows, starts = [], None
    font = ImageFont.load_default(size=max(12, args.size // 18))
    with tempfile.TemporaryDirectory() as tmp:
        for name, form in PHOTOS.items():
            d = Path(tmp) / Path(name).stem
            res = reconstruct(args.data / name, out=d, form=form, seed=0)
            facts = d / "blender.json"
            subprocess.run([args.blender_python, str(ROOT / "scripts" / "blender_view.py"), str(d / "tree.glb"),
                            "--json", str(facts), "--render", str(d / "blender"), "--views", ",".join(VIEWS),
                            "--size", str(args.size), "--samples", str(args.samples)],
                           check=True, capture_output=True)
            renders = json.loads(facts.read_text())["renders"]
            cells = [_fit(res.photo.image, args.size)]
            cells += [_over_bg(np.asarray(Image.open(renders[v]["path"]).convert("RGBA"))) for v in VIEWS]
            gap = np.full((args.size, 8, 3), 255, np.uint8)
            row = np.concatenate([c for cell in cells for c in (cell, gap)][:-1], axis=1)
            rows.append(row)
            starts = starts or list(np.cumsum([0] + [c.shape[1] + gap.shape[1] for c in cells[:-1]]))
            m = res.metrics
            print(f"{name}: reprojection error {100 * m['reprojection_error']:.1f} %, front SSIM "
                  f"{m['front_ssim']:.3f}, black share {max(r['black_share'] for r in renders.values()):.4f}")
    width = max(r.shape[1] for r in rows)
    rows = [np.pad(r, ((0, 8), (0, width - r.shape[1]), (0, 0)), constant_values=255) for r in rows]
    grid = Image.fromarray(np.concatenate(rows))
    head = Image.new("RGB", (width, args.size // 10), "white")
    draw = ImageDraw.Draw(head)
    for x, label in zip(starts, LABELS):
        draw.text((int(x) + 6, 4), label, fill=(40, 40, 40), font=font)
    out = Image.new("RGB", (width, head.height + grid.height), "white")
    out.paste(head, (0, 0))
    out.paste(grid, (0, head.height))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    out.save(args.out, quality=86, optimize=True)
    print(args.out)


if __name__ == "__main__":
    main()
