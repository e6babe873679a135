"""The visible branch graph: branch points -> shortest paths to the root -> a binned skeleton (seed 002 §4.3).

Seed 002 links its branch points into a graph, finds the shortest path of every point to
the root, and bins the points by their path length: the points of one bin that are
connected form one skeleton node at their centroid, linked to the node of the previous
bin their paths come from. Radii come from the images (here: the hull's thickness at the
node, the silhouette's half-width seen from the views).
"""

from __future__ import annotations

import numpy as np

from treeform._shared.errors import NoTreeFoundError
from treeform.structures import TreeSkeleton

__all__ = ["branch_skeleton"]


def _components(n: int, i: np.ndarray, j: np.ndarray) -> np.ndarray:
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    g = coo_matrix((np.ones(len(i)), (i, j)), shape=(n, n))
    return connected_components(g, directed=False)[1]


def branch_skeleton(points: np.ndarray, thickness: np.ndarray, *, link: float, gap: float, bin_width: float,
                    root: np.ndarray | None = None, min_branch_nodes: int = 3) -> TreeSkeleton:
    """Skeleton of the visible branches from their points (seed 002 §4.3).

    Parameters
    ----------
    points : ndarray, shape (B, 3)
        Branch points (Y up).
    thickness : ndarray, shape (B,)
        Local half-width of the branch at each point (metres): the node radii.
    link : float
        Points closer than this are neighbours in the graph (about two cell edges).
    gap : float
        Pieces of the graph not linked to the root's piece join it across at most this
        distance (the nearest pair of points), nearest first; farther pieces are dropped.
    bin_width : float
        Path length per skeleton node.
    root : ndarray, shape (3,), optional
        Where the trunk stands; default the lowest point. The graph's root is the branch
        point nearest to it in the largest piece the gaps join (where the mattes lost the
        lower trunk, the point nearest the foot can be a stray speck or a hedge's wood that
        nothing joins: the tree's branches are the largest network).
    min_branch_nodes : int
        Side branches (tip chains) with fewer nodes are pruned (binning noise).

    Returns
    -------
    TreeSkeleton
        Node 0 at the root point; radius from ``thickness``; order 0 everywhere (the caller
        orders the branches once the hidden ones are grown).

    Raises
    ------
    NoTreeFoundError
        No branch points.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra
    from scipy.spatial import cKDTree

    pts = np.asarray(points, np.float64).reshape(-1, 3)
    th = np.asarray(thickness, np.float64).reshape(-1)
    if len(pts) < 2:
        raise NoTreeFoundError("no branches found in the photos (no trunk seen from the views)")
    tree = cKDTree(pts)
    pairs = tree.query_pairs(link, output_type="ndarray")
    i, j = (pairs[:, 0], pairs[:, 1]) if len(pairs) else (np.zeros(0, int), np.zeros(0, int))
    # join the pieces across gaps of at most `gap`: a minimum spanning tree over the pieces, its
    # edges between representative points (one per piece and half-gap grid cell)
    comp = _components(len(pts), i, j)
    bi, bj = _bridges(pts, comp, gap)
    i, j = np.concatenate([i, bi]), np.concatenate([j, bj])
    joined = _components(len(pts), i, j)
    main = np.flatnonzero(joined == np.argmax(np.bincount(joined)))
    if root is None:
        r0 = int(main[np.argmin(pts[main, 1])])
    else:
        r0 = int(main[np.argmin(np.linalg.norm(pts[main] - np.asarray(root, float), axis=1))])
    w = np.linalg.norm(pts[i] - pts[j], axis=1) + 1e-9
    g = coo_matrix((np.concatenate([w, w]), (np.concatenate([i, j]), np.concatenate([j, i]))),
                   shape=(len(pts), len(pts))).tocsr()
    dist, pred = dijkstra(g, indices=r0, return_predecessors=True)
    reach = np.isfinite(dist)
    # bins of path length; within a bin, connected points form one node
    b = np.full(len(pts), -1)
    b[reach] = (dist[reach] / bin_width).astype(int)
    same = (b[i] == b[j]) & (b[i] >= 0)
    piece = _components(len(pts), i[same], j[same])
    key = np.where(reach, piece, -1)
    order = np.argsort(dist[reach], kind="stable")
    idx = np.flatnonzero(reach)[order]
    node_of_piece: dict[int, int] = {}
    node_members: list[list[int]] = []
    parent: list[int] = []
    for p in idx:
        k = int(key[p])
        if k in node_of_piece:
            node_members[node_of_piece[k]].append(p)
            continue
        # the first (closest to the root) point of a piece: its path comes from the parent node
        q = int(pred[p])
        par = -1 if q < 0 else node_of_piece.get(int(key[q]), -1)
        if par == -1 and node_members:
            par = 0
        node_of_piece[k] = len(node_members)
        node_members.append([p])
        parent.append(par)
    pos = np.array([pts[m].mean(0) for m in node_members])
    rad = np.array([float(np.median(th[m])) for m in node_members])
    pos[0] = pts[r0]
    par = np.array(parent, np.int64)
    keep = _prune_spurs(par, min_branch_nodes)
    return _subset(pos, par, rad, keep)


def _bridges(pts: np.ndarray, comp: np.ndarray, gap: float) -> tuple[np.ndarray, np.ndarray]:
    """Point pairs joining the pieces ``comp`` by a minimum spanning tree of gaps <= ``gap``."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import minimum_spanning_tree
    from scipy.spatial import cKDTree

    n_comp = int(comp.max()) + 1 if len(comp) else 0
    if n_comp < 2:
        return np.zeros(0, int), np.zeros(0, int)
    cell = np.floor(pts / (0.5 * gap)).astype(np.int64)
    key = np.column_stack([comp, cell])
    _, rep = np.unique(key, axis=0, return_index=True)
    pairs = cKDTree(pts[rep]).query_pairs(gap, output_type="ndarray")
    if not len(pairs):
        return np.zeros(0, int), np.zeros(0, int)
    a, b = rep[pairs[:, 0]], rep[pairs[:, 1]]
    cross = comp[a] != comp[b]
    a, b = a[cross], b[cross]
    if not len(a):
        return np.zeros(0, int), np.zeros(0, int)
    d = np.linalg.norm(pts[a] - pts[b], axis=1) + 1e-9
    # the shortest link between each pair of pieces
    ca, cb = np.minimum(comp[a], comp[b]), np.maximum(comp[a], comp[b])
    order = np.lexsort((d, cb, ca))
    first = np.ones(len(order), bool)
    first[1:] = (ca[order][1:] != ca[order][:-1]) | (cb[order][1:] != cb[order][:-1])
    sel = order[first]
    mst = minimum_spanning_tree(coo_matrix((d[sel], (ca[sel], cb[sel])), shape=(n_comp, n_comp))).tocoo()
    lookup = {(int(x), int(y)): k for x, y, k in zip(ca[sel], cb[sel], sel)}
    pick = np.array([lookup[(min(x, y), max(x, y))] for x, y in zip(mst.row, mst.col)], int)
    if not len(pick):
        return np.zeros(0, int), np.zeros(0, int)
    return a[pick], b[pick]


def _prune_spurs(parent: np.ndarray, min_nodes: int) -> np.ndarray:
    """Keep mask without the tip chains shorter than ``min_nodes`` that leave a fork."""
    n = len(parent)
    children = np.bincount(parent[1:], minlength=n)
    keep = np.ones(n, bool)
    for tip in np.flatnonzero(children == 0):
        chain = [tip]
        k = tip
        while parent[k] >= 0 and children[parent[k]] == 1:
            k = parent[k]
            chain.append(k)
        if parent[k] >= 0 and len(chain) < min_nodes:
            keep[chain] = False
    keep[0] = True
    return keep


def _subset(pos, parent, rad, keep) -> TreeSkeleton:
    new = np.cumsum(keep) - 1
    idx = np.flatnonzero(keep)
    par = parent[idx]
    par = np.where(par >= 0, new[np.maximum(par, 0)], -1)
    return TreeSkeleton(pos[idx], par, np.maximum(rad[idx], 1e-3))
