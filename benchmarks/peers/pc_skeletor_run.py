"""Run pc-skeletor's Laplacian-based contraction (LBC) on one point cloud; write its skeleton graph.

Run with the peer venv made by ``benchmarks/peers/pc_skeletor_setup.sh`` (never the project venv):

    benchmarks/peers/.venv-pcs/bin/python benchmarks/peers/pc_skeletor_run.py IN.npy OUT.json \
        [--down-sample S] [--init-contraction C] [--init-attraction A] \
        [--max-contraction MC] [--max-attraction MA] [--max-iterations K] [--keep-origin]

IN.npy: (N, 3) float array of branch-surface points (metres, Y up). OUT.json:

    {"nodes": [[x, y, z], ...], "edges": [[i, j], ...], "seconds": float, "params": {...},
     "topology": {"nodes": [...], "edges": [...]}, "n_points_in": int, "n_points_used": int,
     "versions": {...}}

``nodes``/``edges`` are LBC's skeletal graph (``lbc.skeleton_graph``: a minimum spanning tree,
built by mistree, over a farthest-point sample of 10% of the contracted points); ``topology`` is
pc-skeletor's simplified graph (``lbc.topology_graph``: degree-2 nodes fused away, so only
junctions and tips). Node ids are 0..n-1 in the order of ``nodes``. ``seconds`` is the wall time
of LBC construction (voxel down-sample + outlier filter) + ``extract_skeleton()`` (the
contraction) + ``extract_topology()``; loading the file and the imports are not counted.

LBC parameters default to pc-skeletor 1.0.0's own defaults (init_contraction=1,
init_attraction=0.5, max_contraction=2048, max_attraction=1024, amplification 'auto',
max 20 iterations, statistical outlier filter 20 nb / 2.0 std), with ``--down-sample`` the voxel
size in metres (pc-skeletor's README uses 0.008 on its ~1 m example tree; -1 = no down-sampling).

pc-skeletor's extract_topology() drops every contracted point within 1 cm of the coordinate
origin (it treats them as a contraction artifact). Trees standing at the origin would lose
their trunk base to that, so the cloud is shifted by the negated centroid before LBC and the
result shifted back (``--keep-origin`` turns that off). No GUI/visualiser is ever opened.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import logging
import sys
import time

import numpy as np


def _versions() -> dict:
    import importlib.metadata as md

    out = {}
    for name in ("pc-skeletor", "open3d", "robust-laplacian", "mistree", "numpy", "scipy", "networkx"):
        try:
            out[name] = md.version(name)
        except md.PackageNotFoundError:  # pragma: no cover - setup script installs all of them
            out[name] = None
    return out


def _graph_to_lists(graph, shift: np.ndarray) -> tuple[list, list]:
    """networkx graph with node attribute 'pos' -> (nodes [[x,y,z]], edges [[i,j]]) with ids 0..n-1."""
    order = sorted(graph.nodes)
    index = {node: i for i, node in enumerate(order)}
    nodes = [(np.asarray(graph.nodes[n]["pos"], dtype=float).reshape(3) - shift).tolist() for n in order]
    edges = sorted({tuple(sorted((index[a], index[b]))) for a, b in graph.edges if a != b})
    return nodes, [list(e) for e in edges]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("input", help="(N,3) float .npy of points, metres, Y up")
    ap.add_argument("output", help="output .json")
    ap.add_argument("--down-sample", type=float, default=-1.0,
                    help="voxel size in metres for open3d voxel_down_sample before contraction (-1: none)")
    ap.add_argument("--init-contraction", type=float, default=1.0)
    ap.add_argument("--init-attraction", type=float, default=0.5)
    ap.add_argument("--max-contraction", type=float, default=2048)
    ap.add_argument("--max-attraction", type=float, default=1024)
    ap.add_argument("--max-iterations", type=int, default=20)
    ap.add_argument("--keep-origin", action="store_true",
                    help="do not centre the cloud (pc-skeletor then drops contracted points within 1 cm of 0)")
    args = ap.parse_args(argv)

    np.random.seed(0)

    pts = np.load(args.input)
    pts = np.asarray(pts, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0:
        print(f"pc_skeletor_run: expected a non-empty (N,3) array in {args.input}, got {pts.shape}", file=sys.stderr)
        return 2
    pts = pts[np.isfinite(pts).all(axis=1)]

    # pc-skeletor prints progress (tqdm, print, logging) - keep stdout clean, send it to stderr
    with contextlib.redirect_stdout(sys.stderr):
        import open3d as o3d

        o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
        from pc_skeletor.laplacian import (
            LBC,  # submodule import: no GUI, no dataset download
        )

        # configure the root logger first so pc-skeletor's logging.basicConfig(level=INFO) is a no-op
        logging.basicConfig(format="%(message)s", level=logging.WARNING)

        shift = np.zeros(3) if args.keep_origin else -pts.mean(axis=0)
        pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts + shift))

        params = dict(
            init_contraction=args.init_contraction,
            init_attraction=args.init_attraction,
            max_contraction=args.max_contraction,
            max_attraction=args.max_attraction,
            step_wise_contraction_amplification="auto",
            termination_ratio=0.003,
            max_iteration_steps=args.max_iterations,
            down_sample=args.down_sample,
            filter_nb_neighbors=20,
            filter_std_ratio=2.0,
        )
        t0 = time.perf_counter()
        lbc = LBC(point_cloud=pcd, debug=False, verbose=False, **params)
        n_used = len(lbc.pcd.points)
        lbc.extract_skeleton()
        lbc.extract_topology()
        seconds = time.perf_counter() - t0

    nodes, edges = _graph_to_lists(lbc.skeleton_graph, shift)
    t_nodes, t_edges = _graph_to_lists(lbc.topology_graph, shift)
    params["amplification_used"] = getattr(lbc, "param_contraction_amplification", None)
    params["centred"] = not args.keep_origin
    out = {
        "nodes": nodes,
        "edges": edges,
        "seconds": seconds,
        "params": params,
        "topology": {"nodes": t_nodes, "edges": t_edges},
        "n_points_in": len(pts),
        "n_points_used": int(n_used),
        "versions": _versions(),
    }
    with open(args.output, "w") as f:
        json.dump(out, f)
    print(f"pc-skeletor LBC: {len(pts)} pts -> {n_used} used -> {len(nodes)} nodes, {len(edges)} edges "
          f"({len(t_nodes)} topology nodes) in {seconds:.2f}s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
