"""Make the README's ``docs/images/previews.jpg``: five real photos and their labelled previews.

Each row is the ``preview.png`` that ``treeform reconstruct`` writes (photo | segmentation |
front | side | top), scaled to one width, stacked. Photos from ``../shared/data/photos``
(credits in ``docs/images/CREDITS.md``); the two conifers with ``--form conifer``, the rest
``--form auto``.

    python scripts/readme_previews.py [--data ../shared/data/photos] [--out docs/images/previews.jpg]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
PHOTOS = {"Celtis_occidentalis_1.jpg": "auto", "Quercus_alba_1.jpg": "auto", "Thuja_plicata_1.jpg": "conifer",
          "Pinus_ponderosa_2.jpg": "conifer", "Catalpa_speciosa_1.jpg": "auto"}


def main(argv=None) -> None:
    from treeform.methods.envelope.pipeline import reconstruct

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=ROOT.parent / "shared" / "data" / "photos")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "images" / "previews.jpg")
    ap.add_argument("--width", type=int, default=1600)
    args = ap.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name, form in PHOTOS.items():
            res = reconstruct(args.data / name, out=Path(tmp) / name, form=form, seed=0)
            im = Image.open(Path(tmp) / name / "preview.png").convert("RGB")
            h = round(im.height * args.width / im.width)
            rows.append(np.asarray(im.resize((args.width, h), Image.Resampling.LANCZOS)))
            print(f"{name}: reprojection error {100 * res.metrics['reprojection_error']:.1f} %")
    Image.fromarray(np.concatenate(rows)).save(args.out, quality=88, optimize=True)
    print(args.out)


if __name__ == "__main__":
    main()
