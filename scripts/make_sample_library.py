"""Render the sample exemplar library shipped in ``src/treeform/data/library/``.

The README's `vary`, `morph` and `library` examples need RGBA trees that anyone may use:
these are treeform's own species grown and rendered alone (CC0, made by this script), so
no third-party image is bundled. Reproducible: same treeform version -> same PNGs.

    python scripts/make_sample_library.py [--out src/treeform/data/library] [--height 256]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np
from PIL import Image

# species -> seeds; six broadleaves and one conifer, two trees each
TREES = {"oak": (1, 4), "maple": (2, 5), "birch": (0, 3), "apple": (1, 2), "acacia": (0, 6), "willow": (3, 4),
         "pine": (0, 2)}


def render_tree(species: str, seed: int, height_px: int) -> np.ndarray:
    """A grown tree rendered alone from the front: (h, w, 4) uint8 RGBA cropped to its alpha."""
    from treeform.methods.learned.grow import grow_tree, preview_lighting
    from treeform.render import Renderer
    from treeform.structures import Camera

    mesh = grow_tree(species, seed=seed, previews=False, lod="high").mesh
    lo, hi = mesh.bounds()
    centre = (lo + hi) / 2
    extent = float(max(hi[1] - lo[1], hi[0] - lo[0], 1e-3))
    fov = 20.0
    dist = 0.55 * extent / np.tan(np.radians(fov / 2)) + (hi[2] - lo[2])
    size = 3 * height_px  # render large, then reduce: smooth edges and leaf texture
    cam = Camera(size, size, fov, (centre[0], centre[1], centre[2] + dist), tuple(centre), (0, 1, 0),
                 0.1, dist * 3)
    rgba = Renderer(cam, samples=4, lighting=preview_lighting()).render(mesh).color
    ys, xs = np.nonzero(rgba[..., 3] > 0)
    crop = rgba[ys.min():ys.max() + 1, xs.min():xs.max() + 1]
    h, w = crop.shape[:2]
    im = Image.fromarray(crop, "RGBA")
    # premultiply for the reduction so transparent pixels do not bleed their colour in
    pre = np.asarray(im, np.float32)
    pre[..., :3] *= pre[..., 3:] / 255.0
    new = (max(1, round(w * height_px / h)), height_px)
    small = np.stack([np.asarray(Image.fromarray(pre[..., c]).resize(new, Image.Resampling.LANCZOS))
                      for c in range(4)], axis=-1)
    a = np.clip(small[..., 3:], 0, 255)
    rgb = np.where(a > 0, small[..., :3] * 255.0 / np.maximum(a, 1e-3), 0)
    return np.concatenate([np.clip(rgb, 0, 255), a], axis=-1).round().astype(np.uint8)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[1] / "src/treeform/data/library")
    ap.add_argument("--height", type=int, default=256)
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    for species, seeds in TREES.items():
        for seed in seeds:
            path = args.out / f"{species}_{seed}.png"
            Image.fromarray(render_tree(species, seed, args.height), "RGBA").save(path, optimize=True)
            print(f"{path}  {path.stat().st_size // 1024} KB")


if __name__ == "__main__":
    main()
