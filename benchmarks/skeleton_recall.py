"""2D foliage-skeleton recall on synthetic trees (seed 004 §3, issue 13).

What it measures: how well :func:`treeform.skeleton.foliage_skeleton` (tree mode) finds the
ground-truth first-order branches of trees grown by the phenomenological growth engine
(:func:`treeform.growth.phenomenological.grow`, each of the seven species presets, seeds
``--first-seed`` .. ``--first-seed + --cases - 1``, by default 4-6: the wood skeleton's constants
were chosen on seeds 1-2, so these are held out), rendered from the front (camera on +Z looking at the tree, elevation 0,
field of view 30 degrees, ``--height`` pixels tall, width from the tree's aspect) with leaves
on (species leaf cards on the twigs, ``medium`` LOD as the dataset generator) and leaves off
(the same tree, bark only). The skeleton (``levels=1``, ``seed=0``) gets, as the abs pipeline
does, the crown mask and trunk path of :func:`treeform.crown.layout.tree_layout` on the render's
exact foliage / wood labels ("layout", the main numbers), and also the whole silhouette with
``trunk=None`` ("raw").

Ground truth. The chains of :meth:`TreeSkeleton.chains` whose second node has order 1 (they
start on the trunk chain), projected with the render's camera (``Camera.project``: u = column,
v = row, y down). A chain is kept when its projected arc length is at least 10 % (``--min-gt``) of the tree's
projected height ``Hpx`` (the rows spanned by the projected skeleton nodes); shorter ones
(mostly branches pointing at the camera or stubs) are ignored. The same GT serves leaves on
and off.

Matching. Distances between a predicted first-order branch and a GT polyline, both
resampled to 32 points by arc length. Primary (``overlap``): both polylines cut to their
common length L = min of the two arc lengths, measured from their attachment ends, and the
mean of the two directed mean point-to-polyline distances over those parts; defined only
when the shorter is at least half as long as the longer (else no match), so a short stub
near the trunk cannot match a long branch. Also reported: ``sym``, the same symmetric mean
over the full polylines (stricter), and ``pred_to_gt``, the mean distance from the
predicted points to the GT polyline (lenient: any short prediction near a GT attachment
matches) and ``cover`` (a GT branch is found: the predicted points lie on it, mean
distance within the tolerance, and cover at least half of it, half of its resampled points
being within the tolerance of the prediction; where the branch leaves the trunk need not
agree: a branch that runs along the trunk before it diverges shows its attachment nowhere in
the image). A pair matches when its distance is at most ``--tol`` (default 5 %) of ``Hpx``
(``@2tol``: twice that); pairs are assigned one to one (Hungarian, scipy
``linear_sum_assignment``) and only pairs under the tolerance count. The skeleton's leader
(its last first-order branch, the area above the top cut, which continues the trunk) has no first-order GT: the trunk
chain's part above the highest kept first-order attachment is added as a GT "leader" that
predictions may match (so a correct leader is not a false positive) but recall counts only
the first-order GT. Precision = matched predicted first-order / predicted first-order,
recall = matched GT first-order / GT first-order, pooled over cases (micro averages);
``n_branches`` = kept GT first-order + 1 (the leader's area), capped at 32 (the abs method's
limit), and once more with the fixed default 5 (``--no-fixed`` skips it).

The abs reconstruction (:func:`treeform.methods.synthesis.pipeline.reconstruct`, ``candidates=8``,
the true species, the render's mask) also runs on the leaves-on render of the first tree of
each species (``--abs N``: of the first N species, 0 skips it; about 2 s each) and its eq. (3)
reprojection error is reported. ``--out DIR`` writes overlays (the skeleton by
:func:`treeform.skeleton.draw_skeleton`; predicted trunk brown, predicted first order red; GT
first-order branches green when matched (primary metric), blue when missed, the GT leader
orange) for the first tree of each species, leaves on / off, layout / raw.

Run: `.venv/bin/python benchmarks/skeleton_recall.py [--cases 3] [--first-seed 4] [--height 400] [--tol 0.05]
[--abs 7] [--out out/skeleton_recall]`; writes benchmarks/skeleton_recall.json.
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

from _common import machine

ROOT = Path(__file__).resolve().parents[1]
N_RESAMPLE = 32
MIN_GT_FRACTION = 0.10
N_CAP = 32
VARIANTS = ("layout", "raw", "wood", "woodonly")
METRICS = ("overlap", "sym", "pred_to_gt", "cover")
ALL_METRICS = METRICS + tuple(m + "@2tol" for m in METRICS)
MIN_LENGTH_RATIO = 0.5
MIN_COVER = 0.5


# ------------------------------------------------------------------------------ scene
def grow_tree(species: str, seed: int):
    """Skeleton, leaves-on mesh and leaves-off mesh of one species tree (dataset generator's leaves / LOD)."""
    from treeform.geometry import LOD_PRESETS, foliage_budget, tree_mesh
    from treeform.growth.leaves import twig_foliage, twig_nodes
    from treeform.growth.phenomenological import grow
    from treeform.growth.species import load_species, load_species_appearance
    from treeform.structures import Foliage

    sk = grow(load_species(species), seed=seed)
    look = load_species_appearance(species)
    budget = LOD_PRESETS["medium"]
    n_leaves = int(round(3.0 * len(twig_nodes(sk))))
    n_leaves, factor = foliage_budget(sk, n_leaves, max_triangles=budget)
    fol = twig_foliage(sk, leaf_color=look.leaf_color, size=look.leaf_size * factor, leaves=n_leaves, seed=seed)
    on = tree_mesh(sk, fol, max_triangles=budget, seed=seed)
    off = tree_mesh(sk, Foliage.empty(), max_triangles=budget, seed=seed)
    return sk, on, off


def front_camera(points: np.ndarray, height: int, fov_y: float = 30.0, margin: float = 1.08):
    """Camera on +Z looking at the bounding box's centre, the box filling ``1 / margin`` of the frame."""
    from treeform.structures import Camera

    lo, hi = points.min(0), points.max(0)
    c = 0.5 * (lo + hi)
    half_h = 0.5 * (hi[1] - lo[1]) * margin
    half_w = 0.5 * (hi[0] - lo[0]) * margin
    t = math.tan(math.radians(fov_y) / 2)
    dist = half_h / t + (hi[2] - c[2])
    width = int(min(2 * height, max(height // 2, math.ceil(height * half_w / half_h))))
    width += width % 2
    reach = float(np.linalg.norm(hi - lo))
    return Camera(width, height, fov_y, (c[0], c[1], c[2] + dist), tuple(c), (0.0, 1.0, 0.0),
                  near=max(dist - reach, 0.05), far=dist + reach)


def render(mesh, camera, supersample: int = 2):
    """Image, mask and labels of a render, supersampled so thin branches keep their pixels.

    The mesh is rendered at ``supersample`` times the camera's size and reduced by area: a
    pixel is tree when a quarter of it is covered (a photo shows a twig thinner than a pixel
    as a faint line), wood when the wood covers at least as much of it as the foliage.
    """
    import cv2

    from treeform.render import Renderer
    from treeform.structures import Camera

    k = int(supersample)
    big = Camera(camera.width * k, camera.height * k, camera.fov_y, camera.position, camera.target, camera.up,
                 near=camera.near, far=camera.far)
    r = Renderer(big, samples=1)
    try:
        res = r.render(mesh)
    finally:
        r.release()
    rgb = res.color[..., :3].astype(np.float64)
    a = res.color[..., 3:4].astype(np.float64) / 255.0
    image = np.clip(rgb * a + 255.0 * (1 - a), 0, 255).astype(np.float32)
    part_label = np.array([2 if p.name == "bark" else 1 for p in mesh.parts] + [0], np.uint8)
    labels = part_label[res.part]  # 0 background, 1 foliage, 2 wood
    size = (camera.width, camera.height)

    def area(x):
        return cv2.resize(x.astype(np.float32), size, interpolation=cv2.INTER_AREA)

    image = np.clip(np.rint(area(image)), 0, 255).astype(np.uint8) if k > 1 else image.astype(np.uint8)
    if k == 1:
        return image, res.mask, labels
    cover, leaf = area(res.mask), area(labels == 1)
    mask = cover >= 0.25
    out = np.where(mask, np.where(cover - leaf >= leaf, 2, 1), 0).astype(np.uint8)
    return image, mask, out


def skeleton_inputs(mask: np.ndarray, labels: np.ndarray, variant: str):
    """(silhouette, trunk) given to the skeleton: "layout" as the abs pipeline, "raw" the whole mask."""
    if variant == "raw":
        return mask, None
    if variant in ("wood", "woodonly"):
        return mask, None
    from treeform.crown.layout import tree_layout
    from treeform.structures import Segmentation

    lay = tree_layout(Segmentation(labels))
    trunk = None if lay.trunk_path is None or len(lay.trunk_path) < 2 else np.asarray(lay.trunk_path, float)
    return lay.crown_mask, trunk


# ------------------------------------------------------------------------------ geometry
def arc(poly: np.ndarray) -> np.ndarray:
    return np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(poly, axis=0), axis=1))])


def resample(poly: np.ndarray, n: int = N_RESAMPLE) -> np.ndarray:
    s = arc(poly)
    if s[-1] <= 0:
        return np.repeat(poly[:1], n, axis=0)
    t = np.linspace(0.0, s[-1], n)
    return np.stack([np.interp(t, s, poly[:, 0]), np.interp(t, s, poly[:, 1])], axis=1)


def point_to_polyline(p: np.ndarray, poly: np.ndarray) -> np.ndarray:
    """Distance of each point (P, 2) to the polyline (K, 2)."""
    a, b = poly[:-1], poly[1:]
    ab = b - a
    L2 = np.maximum((ab ** 2).sum(1), 1e-12)
    t = np.clip(((p[:, None, :] - a[None]) * ab[None]).sum(2) / L2[None], 0.0, 1.0)
    q = a[None] + t[..., None] * ab[None]
    return np.linalg.norm(p[:, None, :] - q, axis=2).min(1)


def ground_truth(sk, camera, min_fraction: float = MIN_GT_FRACTION):
    """Projected first-order GT polylines (kept), the GT leader, the projected height and counts."""
    uv_all = camera.project(sk.positions)[:, :2]
    hpx = float(uv_all[:, 1].max() - uv_all[:, 1].min())
    chains = sk.chains()
    trunk = next(c for c in chains if c[0] == 0)
    first = [c for c in chains if len(c) >= 2 and sk.order[c[1]] == 1]
    kept, attach = [], []
    for c in first:
        poly = uv_all[c]
        if arc(poly)[-1] >= min_fraction * hpx:
            kept.append(poly)
            attach.append(int(np.flatnonzero(trunk == c[0])[0]) if c[0] in trunk else 0)
    k = max(attach) if attach else 0
    leader = uv_all[trunk[k:]]
    if len(leader) < 2 or arc(leader)[-1] < min_fraction * hpx:
        leader = None
    return kept, leader, hpx, len(first)


def distances(pred: list, gt: list, tol: float = np.inf) -> dict:
    """(P, G) distance matrices, name -> matrix (see the module docstring); ``cover`` at ``tol``."""
    P, G = len(pred), len(gt)
    d = {name: np.full((P, G), np.inf) for name in METRICS}
    for i, p in enumerate(pred):
        pr, lp = resample(p), arc(p)[-1]
        for j, g in enumerate(gt):
            gr, lg = resample(g), arc(g)[-1]
            a = point_to_polyline(pr, gr).mean()
            b = point_to_polyline(gr, pr).mean()
            d["pred_to_gt"][i, j], d["sym"][i, j] = a, 0.5 * (a + b)
            if (point_to_polyline(gr, pr) <= tol).mean() >= MIN_COVER:
                d["cover"][i, j] = a
            if min(lp, lg) >= MIN_LENGTH_RATIO * max(lp, lg):
                L = min(lp, lg)
                pc, gc = resample(truncate(p, L)), resample(truncate(g, L))
                d["overlap"][i, j] = 0.5 * (point_to_polyline(pc, gr).mean() + point_to_polyline(gc, pr).mean())
    return d


def truncate(poly: np.ndarray, length: float) -> np.ndarray:
    """The first ``length`` pixels of a polyline (from its attachment)."""
    s = arc(poly)
    k = int(np.searchsorted(s, length))
    if k >= len(poly):
        return poly
    t = (length - s[k - 1]) / max(s[k] - s[k - 1], 1e-12)
    return np.vstack([poly[:k], poly[k - 1] + t * (poly[k] - poly[k - 1])])


def match(d: np.ndarray, tol: float) -> list[tuple[int, int]]:
    from scipy.optimize import linear_sum_assignment

    if d.size == 0:
        return []
    big = 1e6
    cost = np.where(d <= tol, d, big)  # inf (length test failed) -> big
    rows, cols = linear_sum_assignment(cost)
    return [(int(i), int(j)) for i, j in zip(rows, cols) if d[i, j] <= tol]


def evaluate(sk2, gt: list, leader, tol: float) -> dict:
    """Precision / recall counts of one skeleton against one GT set (see the module docstring)."""
    pred = [np.asarray(b, float) for b, o in zip(sk2.branches, sk2.order) if o == 1]
    targets = gt + ([leader] if leader is not None else [])
    out = {"pred": len(pred), "gt": len(gt)}
    pairs_all = {}
    dist = {t: distances(pred, targets, t) for t in (tol, 2 * tol)}
    for name in METRICS:
        for suffix, t in (("", tol), ("@2tol", 2 * tol)):
            pairs = match(dist[t][name], t)
            out[name + suffix] = {"matched_pred": len(pairs), "matched_gt": sum(1 for _, j in pairs if j < len(gt))}
            pairs_all[name + suffix] = pairs
    return out, pred, pairs_all


# ------------------------------------------------------------------------------ overlay
def overlay(image, mask, sk2, gt, leader, pairs, path):
    import cv2

    from treeform.skeleton import draw_skeleton

    grey = np.where(mask[..., None], (0.35 * image + 0.65 * 200).astype(np.uint8), 255).astype(np.uint8)
    over = draw_skeleton(grey, sk2, show_partition=False)
    hit = {j for _, j in pairs}
    for j, g in enumerate(gt):
        col = (0, 170, 0) if j in hit else (0, 60, 255)
        cv2.polylines(over, [np.round(g).astype(np.int32).reshape(-1, 1, 2)], False, col, 2, cv2.LINE_AA)
    if leader is not None:
        cv2.polylines(over, [np.round(leader).astype(np.int32).reshape(-1, 1, 2)], False, (255, 140, 0), 2,
                      cv2.LINE_AA)
    cv2.imwrite(str(path), cv2.cvtColor(over, cv2.COLOR_RGB2BGR))


# ------------------------------------------------------------------------------ main
def ratio(a, b):
    return a / b if b else float("nan")


def summarise(rows: list, key: str, metric: str) -> dict:
    rs = [r for r in rows if key in r]
    mp = sum(r[key][metric]["matched_pred"] for r in rs)
    mg = sum(r[key][metric]["matched_gt"] for r in rs)
    npred = sum(r[key]["pred"] for r in rs)
    ngt = sum(r[key]["gt"] for r in rs)
    return {"cases": len(rs), "gt": ngt, "pred": npred, "precision": ratio(mp, npred), "recall": ratio(mg, ngt),
            "mean_gt": ratio(ngt, len(rs)),
            "case_recall_mean": float(np.mean([ratio(r[key][metric]["matched_gt"], r[key]["gt"]) for r in rs
                                               if r[key]["gt"]])) if rs else float("nan")}


def main():
    from treeform._shared.errors import TreeformError
    from treeform.growth.species import SPECIES
    from treeform.skeleton import foliage_skeleton
    from treeform.skeleton.wood import wood_skeleton

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cases", type=int, default=3, help="trees (growth seeds S..S+N-1) per species")
    ap.add_argument("--first-seed", type=int, default=4,
                    help="first growth seed S (the wood skeleton's constants were chosen on seeds 1-2: 4+ is held out)")
    ap.add_argument("--species", default="all")
    ap.add_argument("--height", type=int, default=400, help="render height in pixels")
    ap.add_argument("--tol", type=float, default=0.05, help="match tolerance, fraction of the tree's height")
    ap.add_argument("--min-gt", type=float, default=MIN_GT_FRACTION,
                    help="shortest GT branch kept, fraction of the tree's projected height")
    ap.add_argument("--no-fixed", action="store_true", help="skip the n_branches = 5 run")
    ap.add_argument("--abs", type=int, default=7,
                    help="abs reconstructions (reprojection error) on the first tree of N species (0: none)")
    ap.add_argument("--out", default=None, help="folder for overlay PNGs")
    ap.add_argument("--json", default=str(ROOT / "benchmarks" / "skeleton_recall.json"))
    args = ap.parse_args()
    species = list(SPECIES) if args.species == "all" else args.species.split(",")
    out = Path(args.out) if args.out else None
    if out:
        out.mkdir(parents=True, exist_ok=True)

    t_start = time.perf_counter()
    rows, abs_rows, renders = [], [], []
    for sp in species:
        for seed in range(args.first_seed, args.first_seed + args.cases):
            sk, mesh_on, mesh_off = grow_tree(sp, seed)
            pts = np.concatenate([p.positions for p in mesh_on.parts if p.n_vertices]).astype(np.float64)
            cam = front_camera(pts, args.height)
            gt, leader, hpx, n_first = ground_truth(sk, cam, args.min_gt)
            tol = args.tol * hpx
            n = int(min(N_CAP, max(1, len(gt) + 1)))
            for leaves, mesh in (("on", mesh_on), ("off", mesh_off)):
                image, mask, labels = render(mesh, cam)
                row = {"species": sp, "seed": seed, "leaves": leaves, "size": [cam.height, cam.width],
                       "tree_height_px": round(hpx, 1), "tol_px": round(tol, 2), "first_order_all": n_first,
                       "gt_kept": len(gt), "n_branches": n}
                t0 = time.perf_counter()
                for variant in VARIANTS:
                    try:
                        sil, trunk = skeleton_inputs(mask, labels, variant)
                    except TreeformError as exc:
                        sil, trunk = None, str(exc)
                    for kind, nb in (("gt_n", n), ("fixed5", 5)):
                        if kind == "fixed5" and args.no_fixed:
                            continue
                        key = f"{variant}/{kind}"
                        try:
                            if sil is None:
                                raise TreeformError(trunk)
                            if variant in ("wood", "woodonly"):
                                if kind == "fixed5":
                                    continue
                                sk2 = wood_skeleton(sil, labels == 2, trunk=trunk, levels=1,
                                                    crown_tips=variant == "wood")
                            else:
                                sk2 = foliage_skeleton(sil, n_branches=nb, mode="tree", trunk=trunk, levels=1,
                                                       seed=0)
                        except TreeformError as exc:
                            row[key] = {"error": str(exc), "pred": 0, "gt": len(gt),
                                        **{m: {"matched_pred": 0, "matched_gt": 0} for m in ALL_METRICS}}
                            continue
                        res, _, pairs = evaluate(sk2, gt, leader, tol)
                        row[key] = res
                        if kind == "gt_n" and out is not None and seed == args.first_seed and variant != "woodonly":
                            overlay(image, sil, sk2, gt, leader, pairs["cover"],
                                    out / f"{sp}_{seed}_{leaves}_{variant}.png")
                row["skeleton_seconds"] = round(time.perf_counter() - t0, 3)
                rows.append(row)
                g, r = row["layout/gt_n"], row["raw/gt_n"]
                print(f"{sp:7s} seed {seed} leaves {leaves:3s}  GT {len(gt):2d}/{n_first:2d}  n {n:2d}  "
                      f"layout: pred {g['pred']:2d} matched gt {g['overlap']['matched_gt']:2d} "
                      f"(2tol {g['overlap@2tol']['matched_gt']:2d}, pred->gt {g['pred_to_gt']['matched_gt']:2d})  "
                      f"raw: pred {r['pred']:2d} matched gt {r['overlap']['matched_gt']:2d}  "
                      f"wood: pred {row['wood/gt_n']['pred']:2d} matched gt {row['wood/gt_n']['overlap']['matched_gt']:2d} "
                      f"(woodonly {row['woodonly/gt_n']['overlap']['matched_gt']:2d})  tol {tol:5.1f} px"
                      + (f"  [{g['error']}]" if "error" in g else ""), flush=True)
                if leaves == "on" and seed == args.first_seed and len(renders) < args.abs:
                    renders.append((sp, seed, image, mask))

    for sp, seed, image, mask in renders:
        from treeform.methods.synthesis.pipeline import reconstruct

        t0 = time.perf_counter()
        try:
            rec = reconstruct(image, mask=(mask * 255).astype(np.uint8), candidates=8, species=sp, seed=0)
            err = float(rec.metrics["reprojection_error"])
        except TreeformError as exc:
            abs_rows.append({"species": sp, "seed": seed, "error": str(exc)})
            continue
        abs_rows.append({"species": sp, "seed": seed, "reprojection_error": err,
                         "seconds": round(time.perf_counter() - t0, 2)})
        print(f"abs {sp:7s} seed {seed}: reprojection error {100 * err:.1f} %  ({abs_rows[-1]['seconds']} s)")

    summary = {}
    groups = [(sp, [r for r in rows if r["species"] == sp]) for sp in species] + [("overall", rows)]
    keys = [f"{v}/{k}" for v in VARIANTS for k in ("gt_n", "fixed5")]
    for name, rs in groups:
        summary[name] = {}
        for leaves in ("on", "off"):
            sub = [r for r in rs if r["leaves"] == leaves]
            summary[name][leaves] = {f"{key}/{metric}": summarise(sub, key, metric)
                                     for key in keys for metric in ALL_METRICS if any(key in r for r in sub)}

    def fmt(x):
        return "n/a" if x != x else f"{100 * x:.0f} %"

    def get(s, leaves, key, what):
        return s[leaves].get(key, {}).get(what, float("nan"))

    print(f"\n2D skeletons vs GT first-order branches, precision / recall pooled over the cases (tolerance "
          f"{100 * args.tol:.0f} % of the tree's height). foliage: seed 004 §3 on the abs pipeline's inputs "
          f"(tree_layout crown mask + trunk, n_branches = GT + 1); wood: wood_skeleton on the render's mask and "
          f"wood labels (woodonly: without crown tips); raw: the foliage skeleton on the whole mask, trunk=None. "
          f"overlap: from the attachment, over the common length; cover: on the GT branch, covering half of it.\n")
    rowsets = [("foliage", "layout/gt_n"), ("foliage, n = 5", "layout/fixed5"), ("foliage raw", "raw/gt_n"),
               ("wood", "wood/gt_n"), ("woodonly", "woodonly/gt_n")]
    print("| species | skeleton | mean GT | overlap on P / R | overlap off P / R | cover on P / R | cover off P / R "
          "| cover@2tol on R | cover@2tol off R |")
    print("|---|---|---|---|---|---|---|---|---|")
    for name, _ in groups:
        s = summary[name]
        for label, key in rowsets:
            if f"{key}/overlap" not in s["on"]:
                continue
            cells = [f"{fmt(get(s, lv, f'{key}/{m}', 'precision'))} / {fmt(get(s, lv, f'{key}/{m}', 'recall'))}"
                     for m in ("overlap", "cover") for lv in ("on", "off")]
            cells += [fmt(get(s, lv, f"{key}/cover@2tol", "recall")) for lv in ("on", "off")]
            print(f"| {name} | {label} | {s['on'][f'{key}/overlap']['mean_gt']:.1f} | " + " | ".join(cells) + " |")
    if abs_rows:
        errs = [r["reprojection_error"] for r in abs_rows if "reprojection_error" in r]
        if errs:
            print(f"\nabs reprojection error (eq. 3), {len(errs)} leaves-on renders: mean {100 * np.mean(errs):.1f} %, "
                  f"median {100 * np.median(errs):.1f} %")
    total = time.perf_counter() - t_start
    print(f"\n{total:.0f} s on {machine()}")
    doc = {"machine": machine(), "seconds": round(total, 1),
           "settings": {"cases": args.cases, "first_seed": args.first_seed, "height": args.height, "tol": args.tol,
                        "min_gt_fraction": args.min_gt, "n_cap": N_CAP, "resample": N_RESAMPLE,
                        "skeleton": {"mode": "tree", "trunk": None, "levels": 1, "seed": 0}},
           "summary": summary, "cases": rows, "abs": abs_rows}
    Path(args.json).write_text(json.dumps(doc, default=float, separators=(",", ":")))


if __name__ == "__main__":
    main()
