"""Bi-modal growth (seed 003 §4.3–4.4) on synthetic ground truth, per species.

For each species a ground-truth tree is grown (seed 1) and
- **fill**: a tree is grown bi-modally inside the ground truth's level-4 RBV (markers in its
  volume); fill = mean over non-empty sectors of min(grown / target sector radius, 1);
- **mask IoU**: the ground truth's main branches (radius >= 1 px) are rendered from the front
  at 512 px as the branch mask; a tree is grown from that mask and the level-4 RBV; IoU of
  its front wood render (all branches) with the mask;
- **own RBV**: every node of the grown tree lies in its own RBV at levels 3–5.

Run: `python benchmarks/bench_bimodal.py`
"""

from __future__ import annotations

import time

import numpy as np


def main():
    from treeform.geometry.tubes import branch_mesh
    from treeform.growth.bimodal import bimodal_grow
    from treeform.growth.phenomenological import grow
    from treeform.growth.species import SPECIES, load_species
    from treeform.render import Renderer
    from treeform.structures import Camera, Mesh, RadialBoundingVolume

    size = 512
    print("| species | fill of target RBV (level 4) | inside target | own RBV L3-5 | mask IoU | grow from mask (s) |")
    print("|---|---|---|---|---|---|")
    ious, fills = [], []
    for sp in SPECIES:
        p = load_species(sp)
        gt = grow(p, seed=1)
        rbv5 = RadialBoundingVolume.from_skeleton(gt, level=5)
        target = rbv5.at_level(4)
        rec = bimodal_grow(p, target, seed=2)
        got = RadialBoundingVolume.from_skeleton(rec, level=4)
        ok = target.physical_radii > 0
        fill = float(np.minimum(got.physical_radii[ok] / target.physical_radii[ok], 1.0).mean())
        own = all(RadialBoundingVolume.from_skeleton(rec, level=k).contains(rec.positions).all() for k in (3, 4, 5))
        h = rbv5.physical_height
        dist = 1000 * h
        cam = Camera(size, size, 2 * np.degrees(np.arctan(0.6 * h / dist)), (0, h / 2, dist), (0, h / 2, 0),
                     near=dist - 3 * h, far=dist + 3 * h)
        px = 1.2 * h / size
        mask = Renderer(cam, samples=1).render(Mesh([branch_mesh(gt, radial_segments=6, min_radius=px)])).mask
        base = cam.project(np.zeros((1, 3)))[0]
        t0 = time.perf_counter()
        tree = bimodal_grow(p, target, mask=mask, seed=2, mask_scale=dist / cam.focal, mask_base=(base[0], base[1]))
        dt = time.perf_counter() - t0
        wood = Renderer(cam, samples=1).render(Mesh([branch_mesh(tree, radial_segments=6)])).mask
        iou = float((mask & wood).sum() / (mask | wood).sum())
        ious.append(iou)
        fills.append(fill)
        print(f"| {sp} | {fill:.3f} | {target.contains(rec.positions).mean():.3f} | {own} | {iou:.2f} | {dt:.2f} |")
    print(f"\nmean fill {np.mean(fills):.3f} (min {np.min(fills):.3f}); mean mask IoU {np.mean(ious):.2f} "
          f"(min {np.min(ious):.2f}, {sum(i >= 0.6 for i in ious)}/{len(ious)} >= 0.6)")


if __name__ == "__main__":
    main()
