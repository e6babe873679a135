"""Skin weights: which joint moves each vertex of a tree mesh."""

from __future__ import annotations

import numpy as np

from treeform._shared.errors import InputError
from treeform.structures.skeleton import TreeSkeleton

RIGID_PIECE = 64
"""A connected piece of a mesh with at most this many vertices (a leaf card, a cluster) moves
as one with a single joint; larger pieces (branch tubes) are skinned vertex by vertex."""


BLEND = 6.0
"""Length, in radii of the branch at the pivot, over which a tube's skin blends from the parent
joint to its own."""


def _pieces(n: int, indices: np.ndarray) -> np.ndarray:
    """(V,) connected-piece label of every vertex of a triangle list."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    t = indices.reshape(-1, 3)
    a = np.concatenate([t[:, 0], t[:, 1], t[:, 2]])
    b = np.concatenate([t[:, 1], t[:, 2], t[:, 0]])
    g = coo_matrix((np.ones(len(a), np.int8), (a, b)), shape=(n, n))
    return connected_components(g, directed=False)[1]


def _nearest_segment_node(points: np.ndarray, skeleton: TreeSkeleton, *, k: int = 8):
    """(P,) the node whose segment (from its parent to it) lies nearest each point, in units of
    the segment's radius, so a vertex on a tube's surface goes to its own branch, not to a
    thinner branch starting close by; and (P,) where along that segment it lies (0 at the
    parent, 1 at the node)."""
    from scipy.spatial import cKDTree

    pos, par = skeleton.positions, skeleton.parent
    mid = pos.copy()
    mid[1:] = 0.5 * (pos[1:] + pos[par[1:]])
    k = min(k, skeleton.n_nodes)
    _, cand = cKDTree(mid).query(points, k=k)
    cand = cand.reshape(len(points), k)
    a = pos[np.maximum(par[cand], 0)]
    b = pos[cand]
    ab = b - a
    t = np.clip(np.einsum("pki,pki->pk", points[:, None] - a, ab) / np.maximum(np.einsum("pki,pki->pk", ab, ab),
                                                                              1e-18), 0.0, 1.0)
    d = np.linalg.norm(points[:, None] - (a + t[..., None] * ab), axis=2)
    r = np.maximum(skeleton.radius[cand], 1e-3)
    best = np.argmin(d / r, axis=1)
    rows = np.arange(len(points))
    return cand[rows, best], t[rows, best]


def skin_weights(positions: np.ndarray, indices: np.ndarray, skeleton: TreeSkeleton,
                 joints) -> tuple[np.ndarray, np.ndarray]:
    """The joints and weights of every vertex of a mesh part laid over ``skeleton``.

    Small connected pieces (at most :data:`RIGID_PIECE` vertices: leaf cards and clusters)
    move rigidly with the joint of the node nearest their centre. The vertices of larger
    pieces (branch tubes) follow the branch segment they lie on (nearest in units of its
    radius); within :data:`BLEND` radii of a joint's pivot (at least its first segment)
    they blend linearly from the parent joint to their own, so a bending branch curves
    instead of creasing at the joint.

    Parameters
    ----------
    positions : ndarray, shape (V, 3)
    indices : ndarray, shape (F, 3), int
    skeleton : TreeSkeleton
    joints : TreeJoints
        :func:`~treeform.animate.joints.tree_joints` of ``skeleton``.

    Returns
    -------
    joint : ndarray, shape (V, 2), int64
    weight : ndarray, shape (V, 2), float64
        Two joints per vertex and their weights (summing to 1).
    """
    from scipy.spatial import cKDTree

    node_joint = joints.node_joint
    pos = np.asarray(positions, np.float64).reshape(-1, 3)
    idx = np.asarray(indices, np.int64).reshape(-1, 3)
    if len(idx) and (idx.min() < 0 or idx.max() >= len(pos)):
        raise InputError("skin_weights: an index points past the vertices")
    if len(node_joint) != skeleton.n_nodes:
        raise InputError(f"skin_weights: node_joint has {len(node_joint)} entries for {skeleton.n_nodes} nodes")
    joint = np.zeros((len(pos), 2), np.int64)
    weight = np.zeros((len(pos), 2))
    weight[:, 0] = 1.0
    if len(pos) == 0:
        return joint, weight
    piece = _pieces(len(pos), idx) if len(idx) else np.arange(len(pos))
    size = np.bincount(piece)
    small = size[piece] <= RIGID_PIECE
    if small.any():
        sums = np.zeros((len(size), 3))
        np.add.at(sums, piece[small], pos[small])
        centres = sums / np.maximum(size, 1)[:, None]
        used = np.unique(piece[small])
        _, near = cKDTree(skeleton.positions).query(centres[used])
        joint_of = np.zeros(len(size), np.int64)
        joint_of[used] = node_joint[near]
        joint[small] = joint_of[piece[small]][:, None]
    big = np.flatnonzero(~small)
    if len(big):
        node, t = _nearest_segment_node(pos[big], skeleton)
        j = node_joint[node]
        joint[big] = j[:, None]
        # near its pivot a joint's tube blends from the parent joint to its own, over BLEND radii of
        # the pivot's branch (at least its first segment), measured along the axis from the pivot
        a = skeleton.positions[np.maximum(skeleton.parent[node], 0)]
        on_axis = a + t[:, None] * (skeleton.positions[node] - a)
        pv = joints.pivot_node[j]
        d = np.linalg.norm(on_axis - skeleton.positions[pv], axis=1)
        first = skeleton.parent[node] == pv
        reach = np.maximum(BLEND * skeleton.radius[pv], np.where(first, skeleton.segment_lengths()[node], 0.0))
        w = np.clip(d / np.maximum(reach, 1e-9), 0.0, 1.0)
        blend = (w < 1.0) & (joints.parent[j] >= 0)
        joint[big[blend], 1] = joints.parent[j[blend]]
        weight[big[blend], 0] = w[blend]
        weight[big[blend], 1] = 1.0 - w[blend]
    return joint, weight
