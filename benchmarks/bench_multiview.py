"""Multi-view route (issue 14) on a synthetic capture with ground truth.

    python benchmarks/bench_multiview.py [--views 24] [--size 1024] [--species oak] [--seed 0]
                                         [--mattes learned|classical|truth] [--capture DIR] [--out DIR]
                                         [--no-peer] [--bound] [--no-refine-poses]
                                         [--leaf-placement surface|segments]
                                         [--hidden-growth replication|colonization]

Makes (or reuses) a `treeform dataset capture`, runs `treeform multiview` on its photos and
scores the result against the truth:

- SfM: registration rate, camera position / rotation error after a similarity fit of the
  camera centres (`treeform.sfm.evaluate.pose_errors`), and how far each camera puts the true
  tree from where its true camera does (median over the views, pixels of the photos);
- skeleton: the reconstruction mapped into the truth's frame by that similarity; mean and
  95th-percentile distance from reconstructed branch points to the true branches and back,
  for branches of radius >= 2 cm (as % of the true height too); and ``skeleton_any_*``: each side's
  branches of radius >= 2 cm to every branch of the other (a limb whose true radius is just under
  the cut and whose estimate is over it counts as where it is, not as metres from the thick ones);
- novel views: silhouette IoU of the reconstruction against the true tree from cameras
  halfway between the input cameras;
- the scale the route chose (its height / the true height) and seconds per stage.

- the peer: pc-skeletor (PyPI; Laplacian-based contraction) on the same branch points the
  route's visible branch graph is built from, scored the same way (``--no-peer`` to skip;
  its own venv, made by ``benchmarks/peers/pc_skeletor_setup.sh`` on first use);

``--mattes truth`` feeds the capture's true labels as the per-view mattes (an oracle that
separates matting errors from the rest). ``--bound`` also scores, at the same novel views, the
exact visual hull of the true labels (5-cm cells) seen by the true cameras and by the route's SfM
cameras: what a reconstruction from perfect silhouettes can reach, with and without the SfM's
camera errors (a few minutes more).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def _dense(positions, parent, radius, min_radius, step):
    """Points every ``step`` along the skeleton's links to nodes of radius >= ``min_radius``."""
    k = np.flatnonzero((np.arange(len(parent)) > 0) & (np.asarray(radius) >= min_radius))
    return _dense_edges(positions, np.column_stack([np.asarray(parent)[k], k]), step)


PEERS = Path(__file__).resolve().parent / "peers"
PEER_POINTS = 50_000
"""At most this many branch points go to pc-skeletor (a seeded random subset)."""


def _pc_skeletor(points: np.ndarray, work: Path):
    """pc-skeletor's skeleton of ``points`` (nodes, edges, seconds), or None with a printed reason."""
    import subprocess

    py = PEERS / ".venv-pcs" / "bin" / "python"
    if not py.is_file():
        r = subprocess.run(["bash", str(PEERS / "pc_skeletor_setup.sh")], capture_output=True, text=True, check=False)
        if r.returncode != 0 or not py.is_file():
            print(f"peer skipped: {(r.stderr or r.stdout).strip().splitlines()[-1:]}", file=sys.stderr)
            return None
    if len(points) > PEER_POINTS:  # LBC's Laplacian grows past 16 GB of memory on ~600k points
        points = points[np.random.default_rng(0).choice(len(points), PEER_POINTS, replace=False)]
    np.save(work / "branch_points.npy", points)
    r = subprocess.run([str(py), str(PEERS / "pc_skeletor_run.py"), str(work / "branch_points.npy"),
                        str(work / "pcs.json")], capture_output=True, text=True, timeout=1800, check=False)
    if r.returncode != 0:
        print(f"peer failed: {r.stderr.strip().splitlines()[-1:]}", file=sys.stderr)
        return None
    out = json.loads((work / "pcs.json").read_text())
    return np.asarray(out["nodes"], np.float64).reshape(-1, 3), np.asarray(out["edges"], np.int64).reshape(-1, 2), \
        float(out["seconds"])


def _dense_edges(nodes, edges, step):
    """Points every ``step`` along a graph's edges (both ends included)."""
    out = []
    for a, b in edges:
        n = max(1, int(np.linalg.norm(nodes[b] - nodes[a]) / step))
        out.append(nodes[a] + (nodes[b] - nodes[a]) * np.linspace(0, 1, n + 1)[:, None])
    return np.concatenate(out) if out else np.zeros((0, 3))


def _mid_camera(Ta, Tb):
    """A camera halfway between two (OpenCV cam_to_world): mean centre, mean (re-orthonormalised) axes."""
    R = 0.5 * (Ta[:3, :3] + Tb[:3, :3])
    u, _, vt = np.linalg.svd(R)
    T = np.eye(4)
    T[:3, :3] = u @ vt
    T[:3, 3] = 0.5 * (Ta[:3, 3] + Tb[:3, 3])
    return T


def _exact_hull(Ks, cam_to_world, masks, box, step: float):
    """Cells (centres, edges) of the visual hull of ``masks``, exact to ``step`` (OpenCV cameras).

    An octree over ``box``: a cell goes when a view that holds it has no tree pixel within its
    footprint, stays whole when every such view's mask covers its footprint, and splits otherwise;
    at ``step`` a cell stays when its centre's pixel is tree in every view that holds it. (The
    route's ``carve_tree`` is conservative by design -- it keeps a cell with tree within its
    footprint plus 0.75 px at every level, so its hull is fatter; a bound wants the exact one.)
    """
    from scipy.ndimage import distance_transform_edt

    d_out = [distance_transform_edt(~m).astype(np.float32) for m in masks]
    d_in = [distance_transform_edt(m).astype(np.float32) for m in masks]
    W2C = [np.linalg.inv(np.asarray(T, float)) for T in cam_to_world]
    lo, hi = (np.asarray(b, float) for b in box)
    e = float((hi - lo).max()) / 32.0
    cells = np.stack(np.meshgrid(*[np.arange(lo[i] + e / 2, hi[i], e) for i in range(3)], indexing="ij"),
                     -1).reshape(-1, 3)
    pts, size = [], []
    while len(cells):
        empty, full = np.zeros(len(cells), bool), np.ones(len(cells), bool)
        for K, W, dout, din in zip(Ks, W2C, d_out, d_in):
            uvw = (cells @ W[:3, :3].T + W[:3, 3]) @ np.asarray(K, float).T
            z = np.maximum(uvw[:, 2], 1e-6)
            u, v = np.floor(uvw[:, 0] / z).astype(np.int64), np.floor(uvw[:, 1] / z).astype(np.int64)
            h, w = dout.shape
            held = (u >= 0) & (u < w) & (v >= 0) & (v < h) & (uvw[:, 2] > 0)
            uu, vv = np.clip(u, 0, w - 1), np.clip(v, 0, h - 1)
            r = 0.5 * np.sqrt(3) * e * K[0][0] / z if e > step else 0.0
            empty |= held & (dout[vv, uu] > r)
            full &= ~held | (din[vv, uu] > r)
        last = e <= step
        done = ~empty if last else ~empty & full
        pts.append(cells[done])
        size.append(np.full(int(done.sum()), e))
        if last:
            break
        off = np.stack(np.meshgrid(*[[-0.25, 0.25]] * 3, indexing="ij"), -1).reshape(-1, 3) * e
        cells = (cells[~empty & ~full][:, None, :] + off[None]).reshape(-1, 3)
        e /= 2.0
    return np.concatenate(pts), np.concatenate(size)


def _splat(points, size, cams):
    """Masks of cells (centres ``points``, edges ``size``) seen by ``cams`` = [(K, cam_to_world, (h, w))]."""
    from treeform.methods.multiview.coherence import splat_cells

    return [splat_cells(points, 0.5 * np.asarray(size, float), np.asarray(K, float), np.linalg.inv(T), shape)
            for K, T, shape in cams]


def _tree_displacement(mesh, sfm, truth, s, R, t, every: int = 20) -> np.ndarray:
    """Per registered view, the mean distance (pixels of the photo) between where its SfM camera and
    its true camera put the true tree's vertices (mapped into the SfM's frame by the similarity
    ``x -> s R x + t`` from the SfM's frame to the truth's). Sharper than the rotation error after a
    fit of the centres: a camera turned about its centre moves the tree by its focal times the angle."""
    P = np.concatenate([p.positions for p in mesh.parts if p.n_vertices])[::every]
    Ps = (P - t) @ R / s

    def proj(K, T, X):
        W = np.linalg.inv(np.asarray(T, float))
        uvw = (X @ W[:3, :3].T + W[:3, 3]) @ np.asarray(K, float).T
        return uvw[:, :2] / uvw[:, 2:]

    return np.array([np.linalg.norm(proj(sfm.K[i], sfm.cam_to_world[i], Ps) * (truth[n]["size"][0] / sfm.sizes[i, 0])
                                    - proj(truth[n]["K"], truth[n]["cam_to_world"], P), axis=1).mean()
                     for i, n in enumerate(sfm.names)])


def _render_mask(mesh, K, T, size, scale=0.5):
    from treeform.render import Renderer
    from treeform.sfm import SfmResult

    cam = SfmResult(["v"], [K], [T], [size], np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), []).render_camera(
        0, near=0.1, far=1000.0, scale=scale)
    r = Renderer(cam, samples=1)
    try:
        return r.render(mesh).mask > 0
    finally:
        r.release()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--views", type=int, default=24)
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--species", default="oak")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--mattes", default="learned", choices=("learned", "classical", "truth"))
    ap.add_argument("--capture", type=Path, default=None, help="reuse a capture folder (made if missing)")
    ap.add_argument("--out", type=Path, default=None, help="keep the reconstruction here")
    ap.add_argument("--json", type=Path, default=None, help="write the scores here")
    ap.add_argument("--no-peer", action="store_true", help="skip pc-skeletor")
    ap.add_argument("--no-refine-poses", action="store_true", help="keep the SfM's cameras (no silhouette coherence)")
    ap.add_argument("--leaf-texture", default="photo", choices=("photo", "procedural"))
    ap.add_argument("--leaf-placement", default="surface", choices=("surface", "segments"))
    ap.add_argument("--hidden-growth", default="replication", choices=("replication", "colonization"))
    ap.add_argument("--bound", action="store_true",
                    help="also score the visual hull of the capture's true mattes at the novel views, seen by the "
                         "true cameras and by the route's SfM cameras (what silhouettes alone can reach; minutes)")
    a = ap.parse_args(argv)

    from scipy.spatial import cKDTree

    from treeform.dataset.capture import _read_model, synthetic_capture
    from treeform.methods.multiview.pipeline import reconstruct_multiview
    from treeform.sfm.evaluate import pose_errors
    from treeform.structures import Mesh, MeshPart, TreeSkeleton

    tmp = Path(tempfile.mkdtemp(prefix="bench_mv_"))
    cap = a.capture or tmp / "capture"
    t0 = time.perf_counter()
    if not (cap / "images").is_dir():
        synthetic_capture(cap, views=a.views, size=a.size, species=a.species, seed=a.seed)
    t_capture = time.perf_counter() - t0
    truth = json.loads((cap / "truth" / "cameras.json").read_text())
    meta = json.loads((cap / "truth" / "meta.json").read_text())
    H = float(meta["height"])

    t0 = time.perf_counter()
    res = reconstruct_multiview(cap / "images", out=a.out or tmp / "out", leaf_texture=a.leaf_texture,
                                leaf_placement=a.leaf_placement, hidden_growth=a.hidden_growth,
                                segmenter=a.mattes if a.mattes != "truth"
                                else "learned", masks=cap / "truth" / "labels" if a.mattes == "truth" else None,
                                seed=a.seed, refine_poses=not a.no_refine_poses)
    t_total = time.perf_counter() - t0
    pe = pose_errors(res.sfm, truth)
    s, R, t = pe["scale"], np.asarray(pe["rotation"]), np.asarray(pe["translation"])
    scores = {"views": len(truth), "size": meta["size"], "species": meta["species"], "mattes": a.mattes,
              "leaf_placement": a.leaf_placement, "hidden_growth": a.hidden_growth,
              "registration_rate": pe["registration_rate"], "position_median_rel": pe["position_median_rel"],
              "position_max_rel": pe["position_max_rel"], "rotation_median_deg": pe["rotation_median_deg"],
              "rotation_max_deg": pe["rotation_max_deg"], "height_ratio": res.metrics["tree_height_m"] / H,
              "seconds_total": round(t_total, 2), "seconds_capture": round(t_capture, 2),
              "seconds": res.metrics["seconds"]}
    # skeleton, in the truth's frame
    sk = res.skeleton
    rec_pos = s * sk.positions @ R.T + t
    if (cap / "truth" / "skeleton.json").is_file():
        gt = TreeSkeleton.load(cap / "truth" / "skeleton.json")
        G = _dense(gt.positions, gt.parent, gt.radius, 0.02, 0.02)
        Rc = _dense(rec_pos, sk.parent, s * sk.radius, 0.02, 0.02)
        vis = int(res.metrics["visible_nodes"])
        Rv = _dense(rec_pos[:vis], sk.parent[:vis], np.full(vis, 1.0), 0.0, 0.02)
        if len(G) and len(Rc):
            d1, d2 = cKDTree(G).query(Rc)[0], cKDTree(Rc).query(G)[0]
            G_any = _dense(gt.positions, gt.parent, gt.radius, 0.0, 0.02)
            R_any = _dense(rec_pos, sk.parent, s * sk.radius, 0.0, 0.02)
            a1, a2 = cKDTree(G_any).query(Rc)[0], cKDTree(R_any).query(G)[0]
            dv = cKDTree(G).query(Rv)[0] if len(Rv) else np.array([np.nan])
            dv2 = cKDTree(Rv).query(G)[0] if len(Rv) else np.array([np.nan])
            scores.update({
                "skeleton_rec_to_gt_mean_pct": 100 * d1.mean() / H, "skeleton_rec_to_gt_p95_pct": 100 * np.percentile(d1, 95) / H,
                "skeleton_gt_to_rec_mean_pct": 100 * d2.mean() / H, "skeleton_gt_to_rec_p95_pct": 100 * np.percentile(d2, 95) / H,
                "skeleton_mean_pct": 100 * 0.5 * (d1.mean() + d2.mean()) / H,
                # each side's branches of radius >= 2 cm to every branch of the other: a limb whose true
                # radius is under the cut and whose estimate is over it is in place, not 1-2 m off
                "skeleton_any_rec_to_gt_mean_pct": 100 * a1.mean() / H,
                "skeleton_any_gt_to_rec_mean_pct": 100 * a2.mean() / H,
                "skeleton_any_mean_pct": 100 * 0.5 * (a1.mean() + a2.mean()) / H,
                "visible_rec_to_gt_mean_pct": 100 * float(np.mean(dv)) / H,
                "visible_gt_to_rec_mean_pct": 100 * float(np.mean(dv2)) / H,
                "visible_mean_pct": 100 * 0.5 * float(np.mean(dv) + np.mean(dv2)) / H})
            # the peer on the same branch points
            pts = res.carved.points[res.branch]
            peer = None if a.no_peer or len(pts) < 10 else _pc_skeletor(pts, tmp)
            if peer is not None:
                nodes, edges, secs = peer
                P = _dense_edges(s * nodes @ R.T + t, edges, 0.02)
                e1, e2 = cKDTree(G).query(P)[0], cKDTree(P).query(G)[0]
                e1a = cKDTree(G_any).query(P)[0]  # its skeleton has no radii: all of it is a query
                scores.update({"peer": "pc-skeletor 1.0.0 (LBC)", "peer_points": len(pts),
                               "peer_seconds": round(secs, 2),
                               "peer_rec_to_gt_mean_pct": 100 * e1.mean() / H,
                               "peer_gt_to_rec_mean_pct": 100 * e2.mean() / H,
                               "peer_mean_pct": 100 * 0.5 * (e1.mean() + e2.mean()) / H,
                               "peer_any_mean_pct": 100 * 0.5 * (e1a.mean() + e2.mean()) / H})
    # novel views halfway between the input cameras
    true_mesh = _read_model(cap / "truth" / "tree.glb")
    # each registered camera against its true one where it matters: where it puts the true tree
    scores["tree_displacement_median_px"] = float(np.median(_tree_displacement(true_mesh, res.sfm, truth, s, R, t)))
    rec = Mesh([MeshPart(s * p.positions @ R.T + t, p.normals @ R.T, p.uvs, p.colors, p.indices, p.material, p.name)
                for p in res.mesh.parts])
    names = sorted(truth)
    ious, extra, missed, novel_true, novel_cams = [], [], [], [], []
    for k in range(len(names)):
        A, B = truth[names[k]], truth[names[(k + 1) % len(names)]]
        T = _mid_camera(np.asarray(A["cam_to_world"]), np.asarray(B["cam_to_world"]))
        m_true = _render_mask(true_mesh, np.asarray(A["K"]), T, A["size"])
        m_rec = _render_mask(rec, np.asarray(A["K"]), T, A["size"])
        novel_true.append(m_true)
        novel_cams.append((np.diag([m_true.shape[1] / A["size"][0]] * 2 + [1.0]) @ np.asarray(A["K"], float), T,
                           m_true.shape))
        ious.append((m_true & m_rec).sum() / max((m_true | m_rec).sum(), 1))
        extra.append((m_rec & ~m_true).sum() / max(m_true.sum(), 1))
        missed.append((m_true & ~m_rec).sum() / max(m_true.sum(), 1))
        if k == 0 and a.out is not None:  # where the first novel view goes wrong: extra red, missed blue
            from PIL import Image

            vis = np.full(m_true.shape + (3,), 255, np.uint8)
            vis[m_true & m_rec] = (90, 150, 70)
            vis[m_rec & ~m_true] = (220, 40, 40)
            vis[m_true & ~m_rec] = (40, 80, 220)
            Image.fromarray(vis).save(a.out / "novel_view_00.png")
    if a.bound:  # the visual hull of the true labels, seen by the true cameras and by the SfM's
        from PIL import Image

        step = 0.05
        masks = [np.asarray(Image.open(cap / "truth" / "labels" / (Path(n).stem + ".png"))) > 0 for n in names]
        lo, hi = (np.asarray(b, float) for b in true_mesh.bounds())
        true_hull = _exact_hull([truth[n]["K"] for n in names], [truth[n]["cam_to_world"] for n in names], masks,
                                (lo - 0.5, hi + 0.5), step)
        # in the SfM's own frame, with its cameras, then mapped into the truth's by the similarity
        reg = [names.index(n) for n in res.sfm.names]
        corners = (np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
                   - t) @ R / s
        Ks = [np.diag([masks[i].shape[1] / w, masks[i].shape[1] / w, 1.0]) @ K
              for i, K, w in zip(reg, res.sfm.K, res.sfm.sizes[:, 0])]
        p_sfm, e_sfm = _exact_hull(Ks, res.sfm.cam_to_world, [masks[i] for i in reg],
                                   (corners.min(0) - 0.5 / s, corners.max(0) + 0.5 / s), step / s)
        for tag, (pts, size) in (("true_cameras", true_hull), ("sfm_cameras", (s * p_sfm @ R.T + t, s * e_sfm))):
            hull_masks = _splat(pts, size, novel_cams)
            scores[f"hull_bound_{tag}_iou_median"] = float(np.median(
                [(m & h).sum() / max((m | h).sum(), 1) for m, h in zip(novel_true, hull_masks)]))
            scores[f"hull_bound_{tag}_extra_median"] = float(np.median(
                [(h & ~m).sum() / max(m.sum(), 1) for m, h in zip(novel_true, hull_masks)]))
    scores["novel_view_iou_median"] = float(np.median(ious))
    scores["novel_view_iou_min"] = float(np.min(ious))
    # shares of the true silhouette's area: what the model adds, and what it misses
    scores["novel_view_extra_median"] = float(np.median(extra))
    scores["novel_view_missed_median"] = float(np.median(missed))
    scores = {k: (round(v, 4) if isinstance(v, float) else v) for k, v in scores.items()}
    print(json.dumps(scores, indent=1))
    if a.json:
        a.json.write_text(json.dumps(scores, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
