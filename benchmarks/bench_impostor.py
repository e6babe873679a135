"""Impostor fidelity (issue 15 item 7): the relief-mapped RDM impostor and the clipped billboard cloud against the full mesh.

Each tree (the bundled sample reconstructed by the envelope route; oak and pine grown by
``treeform grow``) gets its impostor (``make_impostor``: RDM + colour cubemap), and both the
full mesh (``tree.glb``, the project's mesh renderer, lit) and the relief impostor
(``render_rdm_impostor``, lit by the RDM's normal) are drawn by the same narrow-angle camera
from 8 azimuths (every 45°, 10° above the horizon) at several image sizes: the tree's height
in pixels, i.e. how far away it stands. Both are drawn 4x larger and area-averaged down
(what the eye sees at that distance: alpha-tested needles drawn at a few pixels vanish).
Scores per view: silhouette IoU (coverage >= 1/2), and SSIM of the two pictures over a
common grey background inside the union of the two silhouettes. ``cloud`` scores the near-tree
representation the same way: the clipped billboard cloud (144 leaflet billboards, seed 001 §4.2)
over the impostor's ``wood.glb``. The relief impostor marches the tree's opacity grid
(``opacity.npz``: it hits where half the light is blocked, so a porous crown's gaps stay open)
unless ``--opacity 0`` (the RDM's solid envelope, seed 001 §4.1 as published).

Run: `.venv/bin/python benchmarks/bench_impostor.py [--sizes 32,64,128,256] [--trees sample,oak,pine] [--opacity N]`
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from _common import machine

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "src" / "treeform" / "data" / "Celtis_occidentalis_1.jpg"
AZIMUTHS = tuple(range(0, 360, 45))
ELEVATION = 10.0
BACKGROUND = np.array([128, 128, 128], np.uint8)


def supersampled(draw, cam, factor: int = 4):
    """What ``draw(camera) -> RenderResult`` shows at ``cam``'s size, rendered ``factor`` times larger
    and area-averaged down: each pixel's coverage (the silhouette: coverage >= 1/2) and its mean
    colour over the covered part. Alpha-tested leaves drawn at a few pixels vanish or alias; this is
    what the eye sees of the tree at that distance."""
    import cv2

    from treeform.structures import Camera

    big = Camera(cam.width * factor, cam.height * factor, cam.fov_y, cam.position, cam.target, cam.up,
                 cam.near, cam.far)
    r = draw(big)
    m = r.mask.astype(np.float32)
    col = r.color[..., :3].astype(np.float32) * m[..., None]
    size = (cam.width, cam.height)
    cov = cv2.resize(m, size, interpolation=cv2.INTER_AREA)
    mean = cv2.resize(col, size, interpolation=cv2.INTER_AREA) / np.maximum(cov, 1e-6)[..., None]
    mask = cov >= 0.5
    img = np.where(mask[..., None], np.clip(np.rint(mean), 0, 255), BACKGROUND).astype(np.uint8)
    return mask, img


def make_trees(work: Path, names) -> dict:
    """Output folders (tree.glb) of the benchmark's trees."""
    out = {}
    for name in names:
        d = work / name
        if name == "sample":
            cmd = ["reconstruct", str(SAMPLE), "--out", str(d), "--seed", "0"]
        else:
            cmd = ["grow", "--species", name, "--seed", "1", "--out", str(d)]
        subprocess.run([str(ROOT / ".venv" / "bin" / "treeform"), *cmd], check=True, capture_output=True)
        out[name] = d
    return out


def _mesh_render(mesh, cam):
    from treeform.render import Renderer

    r = Renderer(cam, samples=1, background=(0.0, 0.0, 0.0, 0.0))
    try:
        return r.render(mesh)
    finally:
        r.release()


def _cloud_render(imp, cam):
    """The near-tree representation: the clipped billboard cloud (all 144 billboards) over ``wood.glb``."""
    from treeform.render import Renderer
    from treeform.render.cloud import CloudPass

    cloud = CloudPass(imp.rdm, imp.cloud_points, imp.cloud_size, imp.leaflets, color=imp.color)
    cloud.instances = [[0, 0, 0, 1, 0, len(imp.cloud_points)]]
    r = Renderer(cam, samples=1, background=(0.0, 0.0, 0.0, 0.0))
    try:
        return r.render_scene([(imp.wood, None)], passes=[cloud])
    finally:
        r.release()
        cloud.release()


def fidelity(tree_dir: Path, sizes, *, rdm_resolution: int = 128, colors: str = "synthesis",
             opacity: int | None = None) -> dict:
    """(``colors`` 'planar': the synthesized cubemap plus the front view as a billboard, seed 001 §4.1;
    'cloud': the clipped billboard cloud over the trunk and limbs, seed 001 §4.2.)"""
    planar_colors, cloud = colors == "planar", colors == "cloud"
    colors = "synthesis" if planar_colors or cloud else colors
    """Scores of the relief impostor against the full mesh of one tree (see the module's text)."""
    from treeform.structures.camera import box_camera
    from treeform.io.gltf import read_glb_mesh
    from treeform.methods.envelope.impostor import make_impostor
    from treeform.metrics import iou, ssim
    from treeform.render.impostor import render_rdm_impostor

    t0 = time.perf_counter()
    kw = {} if opacity is None else {"opacity_resolution": opacity}
    imp = make_impostor(tree_dir, out=False, rdm_resolution=rdm_resolution, colors=colors, **kw)
    t_imp = time.perf_counter() - t0
    mesh = read_glb_mesh(tree_dir / "tree.glb")
    pts = np.concatenate([p.positions for p in mesh.parts if p.n_vertices])
    lo, hi = pts.min(0), pts.max(0)
    rows = []
    for size in sizes:
        for az in AZIMUTHS:
            cam = box_camera(lo, hi, az, ELEVATION, size)
            ma, a = supersampled(lambda c: _mesh_render(mesh, c), cam)
            planar = imp.planar() if planar_colors else None
            if cloud:
                mb, b = supersampled(lambda c: _cloud_render(imp, c), cam)
            else:
                mb, b = supersampled(lambda c: render_rdm_impostor(imp.rdm, c, color=imp.color, planar=planar,
                                                                   opacity=imp.opacity), cam)
            union = ma | mb
            rows.append({"size": size, "azimuth": az, "iou": round(iou(mb, ma), 4),
                         "ssim": round(ssim(b, a, union), 4) if size >= 16 else None,
                         "coverage_full": round(float(ma.mean()), 4), "coverage_impostor": round(float(mb.mean()), 4)})
    return {"impostor_seconds": round(t_imp, 3), "views": rows}


def figure(trees: dict, path: Path, *, rdm_resolution: int = 128, size: int = 160) -> None:
    """One row per tree: the full mesh, the relief impostor without and with its opacity grid (baked colours)."""
    from PIL import Image, ImageDraw

    from treeform.io.gltf import read_glb_mesh
    from treeform.methods.envelope.impostor import make_impostor
    from treeform.render.impostor import render_rdm_impostor
    from treeform.structures.camera import box_camera

    rows = []
    for name, d in trees.items():
        imp = make_impostor(d, out=False, rdm_resolution=rdm_resolution, colors="baked")
        mesh = read_glb_mesh(d / "tree.glb")
        pts = np.concatenate([p.positions for p in mesh.parts if p.n_vertices])
        cam = box_camera(pts.min(0), pts.max(0), 45, ELEVATION, size)
        panels = [supersampled(lambda c: _mesh_render(mesh, c), cam)[1],
                  supersampled(lambda c: render_rdm_impostor(imp.rdm, c, color=imp.color), cam)[1],
                  supersampled(lambda c: render_rdm_impostor(imp.rdm, c, color=imp.color, opacity=imp.opacity), cam)[1]]
        rows.append(np.hstack(panels))
    im = Image.fromarray(np.vstack(rows)).resize((3 * 2 * size, len(rows) * 2 * size), Image.LANCZOS)
    draw = ImageDraw.Draw(im)
    for k, label in enumerate(("full mesh", "relief of the RDM", "relief through the opacity grid")):
        draw.text((k * 2 * size + 6, 4), label, fill=(255, 255, 255))
    path.parent.mkdir(parents=True, exist_ok=True)
    im.convert("RGB").save(path, quality=88)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="32,64,128,256")
    ap.add_argument("--trees", default="sample,oak,pine")
    ap.add_argument("--rdm", type=int, default=128, help="RDM face resolution")
    ap.add_argument("--colors", default="synthesis,planar,baked,cloud",
                    help="what to score: the relief impostor with make_impostor's colors or planar (the front view "
                         "as a billboard), or cloud (the clipped billboard cloud over the wood)")
    ap.add_argument("--opacity", type=int, default=None,
                    help="voxels along the opacity grid's edge (default make_impostor's; 0: none, the RDM's solid relief)")
    ap.add_argument("--keep", type=Path, default=None, help="keep the trees here (default: a temporary folder)")
    ap.add_argument("--figure", type=Path, default=None,
                    help="also write a picture: per tree, the mesh | the RDM's relief | the relief through the opacity "
                         "grid, from 45 deg at 160 px (e.g. docs/images/impostor_opacity.jpg)")
    args = ap.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    with tempfile.TemporaryDirectory() as tmp:
        work = args.keep or Path(tmp)
        trees = make_trees(work, args.trees.split(","))
        res = {f"{name} ({c})": fidelity(d, sizes, rdm_resolution=args.rdm, colors=c, opacity=args.opacity)
               for name, d in trees.items() for c in args.colors.split(",")}
        if args.figure:
            figure(trees, args.figure, rdm_resolution=args.rdm)
    print(f"# Impostor fidelity: relief-mapped RDM ({args.rdm}² faces, opacity grid "
          f"{'default' if args.opacity is None else args.opacity}) vs full mesh, 8 azimuths, "
          f"{ELEVATION:.0f}° up\n\nmachine: {machine()}\n")
    print("| tree | tree height (px) | silhouette IoU, median (min) | SSIM, median (min) |\n|---|---|---|---|")
    summary = {}
    for name, r in res.items():
        for size in sizes:
            v = [x for x in r["views"] if x["size"] == size]
            i = np.array([x["iou"] for x in v])
            s = np.array([x["ssim"] for x in v if x["ssim"] is not None])
            summary[f"{name}@{size}"] = {"iou_median": float(np.median(i)), "iou_min": float(i.min()),
                                         "ssim_median": float(np.median(s)) if len(s) else None}
            ss = f"{np.median(s):.3f} ({s.min():.3f})" if len(s) else "-"
            print(f"| {name} | {size} | {np.median(i):.3f} ({i.min():.3f}) | {ss} |")
    (ROOT / "out").mkdir(exist_ok=True)
    (ROOT / "out" / "bench_impostor.json").write_text(json.dumps({"machine": machine(), "summary": summary,
                                                                   "trees": res}, indent=1))


if __name__ == "__main__":
    sys.exit(main())
