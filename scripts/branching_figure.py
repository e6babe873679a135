"""Make docs/images/branching.jpg: the envelope route's branches, Runions's rule against the default.

The bundled photo (Celtis occidentalis, public domain) is reconstructed twice with the envelope
method (seed 0): once with ``direction_weight=0`` (Runions's space colonization as written: every
lateral leaves its parent square to it) and once with the default (each step adds the node's own
direction: laterals leave at about 45 degrees and bend toward their attractors). The bark alone
is rendered by treeform's renderer from the front and the side, the mean branching angle
(:func:`treeform.metrics.average_branching_angle`) printed on each panel.

Run: `.venv/bin/python scripts/branching_figure.py [--out docs/images/branching.jpg]` (same input ->
same picture).
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

from skeleton_figures import _panel, _sheet

ROOT = Path(__file__).resolve().parents[1]
PHOTO = ROOT / "src" / "treeform" / "data" / "Celtis_occidentalis_1.jpg"


def _bark_views(mesh, size: int = 640) -> list[np.ndarray]:
    """The bark part over white, from the front and the right side (near-orthographic)."""
    from treeform.render import Renderer
    from treeform.structures.camera import box_camera
    from treeform.structures.mesh import Mesh

    bark = Mesh([p for p in mesh.parts if p.name == "bark"])
    lo, hi = (np.asarray(b, float) for b in bark.bounds())
    cams = [box_camera(lo, hi, az, 0.0, size) for az in (0.0, 90.0)]
    renderer = Renderer(cams[0], samples=8)
    out = []
    try:
        for cam in cams:
            renderer.camera = cam
            res = renderer.render(bark)
            rgba = res.color.astype(np.float32)
            a = rgba[..., 3:4] / 255.0
            img = np.clip(rgba[..., :3] * a + 255.0 * (1.0 - a), 0, 255).astype(np.uint8)
            rows, cols = np.flatnonzero(res.mask.any(1)), np.flatnonzero(res.mask.any(0))
            m = size // 40  # the tree's box and a margin
            out.append(img[max(rows[0] - m, 0):rows[-1] + m + 1, max(cols[0] - m, 0):cols[-1] + m + 1])
    finally:
        renderer.release()
    return out


def main(argv=None) -> None:
    from treeform import reconstruct
    from treeform.metrics import average_branching_angle

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "images" / "branching.jpg")
    args = ap.parse_args(argv)
    panels = []
    with tempfile.TemporaryDirectory() as tmp:
        for weight, name in ((0.0, "Runions's rule"), (1.0, "default")):
            res = reconstruct(PHOTO, out=Path(tmp) / name.replace(" ", "_"), seed=0, direction_weight=weight)
            angle = average_branching_angle(res.skeleton)
            for view, img in zip(("front", "side"), _bark_views(res.mesh)):
                panels.append(_panel(img, f"{name}, {view}: mean branching angle {angle:.0f} deg"))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(_sheet(panels)).save(args.out, quality=88)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
