"""Bi-modal growth (seed 003 §4.3–4.4) on synthetic ground truth, per species.

For each species a ground-truth tree is grown (seed 1) and
- **fill**: a tree is grown bi-modally inside the ground truth's level-4 RBV (markers in its
  volume); fill = mean over non-empty sectors of min(grown / target sector radius, 1);
- **tracing IoU**: the ground truth's main branches (radius >= 1 px) are rendered from the front
  at 512 px as the branch mask; the tracing stage alone (planar scaffold at pixel spacing, not
  turned, one crown year) is grown from it and the level-4 RBV; IoU of its front wood render
  (all branches) with the mask;
- **own volume** (``own_volume``, seed 003 §5 with perfect perception): the default bi-modal
  growth from each tree's own level-4 RBV and branch mask, 7 species x 3 seeds: mean sector
  radius, average branching angle and biomass against the original's.
- **own RBV**: every node of the grown tree lies in its own RBV at levels 3–5.
- **calibration** (``--calibrate``): each species' marker density (1,500 markers in its median
  level-4 RBV) and perception angle (the cone of the limbs that fill the RBV off the mask's
  plane), chosen on growth seeds 4–6 so that the regrown trees' branching angle and biomass
  match their originals'; ``--write`` stores them in the presets.

Run: `python benchmarks/bench_bimodal.py [--own | --calibrate [--write]]`
"""

from __future__ import annotations

import time

import numpy as np


def front_branch_mask(gt, h: float, size: int = 512):
    """Orthographic-like front camera of a tree of height ``h``, its branch mask (>= 1 px) and base pixel."""
    from treeform.geometry.tubes import branch_mesh
    from treeform.render import Renderer
    from treeform.structures import Camera, Mesh

    dist = 1000 * h
    cam = Camera(size, size, 2 * np.degrees(np.arctan(0.6 * h / dist)), (0, h / 2, dist), (0, h / 2, 0),
                 near=dist - 3 * h, far=dist + 3 * h)
    px = 1.2 * h / size
    mask = Renderer(cam, samples=1).render(Mesh([branch_mesh(gt, radial_segments=6, min_radius=px)])).mask
    base = cam.project(np.zeros((1, 3)))[0]
    return cam, mask, (base[0], base[1]), dist / cam.focal


def main():
    from treeform.geometry.tubes import branch_mesh
    from treeform.growth.bimodal import bimodal_grow
    from treeform.growth.phenomenological import grow
    from treeform.growth.species import SPECIES, load_species
    from treeform.render import Renderer
    from treeform.structures import Mesh, RadialBoundingVolume

    size = 512
    print("| species | fill of target RBV (level 4) | inside target | own RBV L3-5 | tracing IoU | grow from mask (s) |")
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
        cam, mask, base, mpp = front_branch_mask(gt, rbv5.physical_height, size)
        t0 = time.perf_counter()
        tree = bimodal_grow(p, target, mask=mask, seed=2, mask_scale=mpp, mask_base=base,
                            orient=False, clamp=False, crown_years=1, spacing=mpp, marker_density=0)
        dt = time.perf_counter() - t0
        wood = Renderer(cam, samples=1).render(Mesh([branch_mesh(tree, radial_segments=6)])).mask
        iou = float((mask & wood).sum() / (mask | wood).sum())
        ious.append(iou)
        fills.append(fill)
        print(f"| {sp} | {fill:.3f} | {target.contains(rec.positions).mean():.3f} | {own} | {iou:.2f} | {dt:.2f} |")
    print(f"\nmean fill {np.mean(fills):.3f} (min {np.min(fills):.3f}); mean tracing IoU {np.mean(ious):.2f} "
          f"(min {np.min(ious):.2f}, {sum(i >= 0.6 for i in ious)}/{len(ious)} >= 0.6)")


def own_volume(seeds=(1, 2, 3), size: int = 512):
    """Seed 003 §5 with perfect perception: regrow each species from its own level-4 RBV and branch mask.

    For 7 species x ``seeds``: a tree grown with the seed is the truth; its level-4 RBV
    (metres) and its front branch mask (branches >= 1 px at ``size``) feed
    :func:`bimodal_grow`. Reports the mean sector radius of the regrown tree's level-4 RBV
    over the truth's, and the regrown / true average branching angle and biomass.
    """
    from treeform.growth.bimodal import bimodal_grow
    from treeform.growth.phenomenological import grow
    from treeform.growth.species import SPECIES, load_marker_density, load_perception_angle, load_species
    from treeform.metrics import average_branching_angle, biomass
    from treeform.structures import RadialBoundingVolume

    rows = []
    print("\n| species | seed | mean sector radius ratio | branching angle ratio | biomass ratio | nodes (true / regrown) | s |")
    print("|---|---|---|---|---|---|---|")
    for sp in SPECIES:
        p = load_species(sp)
        for seed in seeds:
            gt = grow(p, seed=seed)
            target = RadialBoundingVolume.from_skeleton(gt, level=4)
            _, mask, base, mpp = front_branch_mask(gt, target.physical_height, size)
            t0 = time.perf_counter()
            rec = bimodal_grow(p, target, mask=mask, seed=seed + 100, mask_scale=mpp, mask_base=base,
                               perception_angle=load_perception_angle(sp), marker_density=load_marker_density(sp))
            dt = time.perf_counter() - t0
            got = RadialBoundingVolume.from_points(np.maximum(rec.positions, [-np.inf, 0.0, -np.inf]), level=4)
            ratio = got.physical_radii.mean() / target.physical_radii.mean()
            ang = average_branching_angle(rec) / average_branching_angle(gt)
            bio = biomass(rec) / biomass(gt)
            rows.append((sp, seed, ratio, ang, bio))
            print(f"| {sp} | {seed} | {ratio:.2f} | {ang:.2f} | {bio:.2f} | {gt.n_nodes} / {rec.n_nodes} | {dt:.1f} |")
    r = np.array([x[2:] for x in rows])
    ok = (r[:, 0] >= 0.9) & (np.abs(r[:, 1] - 1) <= 0.25) & (np.abs(r[:, 2] - 1) <= 0.25)
    print(f"\nmean: sector radius {r[:, 0].mean():.2f} (min {r[:, 0].min():.2f}), branching angle {r[:, 1].mean():.2f}, "
          f"biomass {r[:, 2].mean():.2f} (range {r[:, 2].min():.2f}-{r[:, 2].max():.2f}); "
          f"{ok.sum()}/{len(ok)} cases meet all three goals")
    return rows


def calibrate(seeds=(4, 5, 6), angles=(15, 20, 25, 30, 40, 50, 60, 75, 90), write: bool = False, size: int = 512,
              markers: int = 1500):
    """Each species' marker density and perception angle, so that its regrown trees match their originals.

    The density puts ``markers`` markers in the median level-4 RBV of the trees of ``seeds``.
    Then, for every angle, those trees are regrown from their own level-4 RBV and branch mask
    with that density; the score is the mean of |log(branching angle ratio)| + |log(biomass
    ratio)| + 10 max(0, 0.9 - sector radius ratio) (fill is a constraint, angle and biomass the
    goal). Among the angles within 0.05 of the best score (ties within the noise of three
    trees), the one nearest the species' own branching angle is chosen; it is printed and,
    with ``write``, stored in its preset.
    """
    import json

    from treeform.growth.bimodal import bimodal_grow
    from treeform.growth.phenomenological import grow
    from treeform.growth.species import SPECIES, load_species, species_path
    from treeform.metrics import average_branching_angle, biomass
    from treeform.structures import RadialBoundingVolume

    print("| species | markers / m³ | " + " | ".join(f"{a}°" for a in angles) + " | chosen |")
    print("|---|---|" + "---|" * (len(angles) + 1))
    for sp in SPECIES:
        p = load_species(sp)
        cases = []
        for seed in seeds:
            gt = grow(p, seed=seed)
            target = RadialBoundingVolume.from_skeleton(gt, level=4)
            _, mask, base, mpp = front_branch_mask(gt, target.physical_height, size)
            cases.append((seed, gt, target, mask, base, mpp))
        density = float(f"{markers / np.median([c[2].volume() for c in cases]):.3g}")
        scores = []
        for a in angles:
            s = []
            for seed, gt, target, mask, base, mpp in cases:
                rec = bimodal_grow(p, target, mask=mask, seed=seed + 100, mask_scale=mpp, mask_base=base,
                                   perception_angle=a, marker_density=density)
                got = RadialBoundingVolume.from_points(np.maximum(rec.positions, [-np.inf, 0.0, -np.inf]), level=4)
                fill = got.physical_radii.mean() / target.physical_radii.mean()
                s.append(abs(np.log(average_branching_angle(rec) / average_branching_angle(gt)))
                         + abs(np.log(biomass(rec) / biomass(gt))) + 10 * max(0.0, 0.9 - fill))
            scores.append(float(np.mean(s)))
        near = [a for a, x in zip(angles, scores) if x <= min(scores) + 0.05]
        best = min(near, key=lambda a: abs(a - p.branching_angle_mean))
        print(f"| {sp} | {density} | " + " | ".join(f"{x:.2f}" for x in scores) + f" | {best}° |", flush=True)
        if write:
            path = species_path(sp)
            data = json.loads(path.read_text())
            data["perception_angle"] = float(best)
            data["marker_density"] = density
            path.write_text(json.dumps(data, indent=2, ensure_ascii=False) + "\n")


if __name__ == "__main__":
    import sys

    if "--calibrate" in sys.argv:
        calibrate(write="--write" in sys.argv)
    elif "--own" in sys.argv:
        own_volume()
    else:
        main()
        own_volume()
