"""Joints of a tree skeleton: where its branches turn when the wind bends them."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from treeform._shared.checks import check_int
from treeform.structures.skeleton import TreeSkeleton


@dataclass
class TreeJoints:
    """Joints of a skeleton and the joint each node moves with.

    Attributes
    ----------
    pivots : ndarray, shape (J, 3)
        Rest position of each joint: the node its segment hangs from.
    parent : ndarray, shape (J,), int64
        Parent joint (-1 for joint 0, the trunk's base); parents precede children.
    pivot_node : ndarray, shape (J,), int64
        Skeleton node at each pivot.
    node_joint : ndarray, shape (N,), int64
        Joint of every skeleton node.
    """

    pivots: np.ndarray
    parent: np.ndarray
    pivot_node: np.ndarray
    node_joint: np.ndarray

    @property
    def n_joints(self) -> int:
        return len(self.pivots)


def tree_joints(skeleton: TreeSkeleton, *, max_joints: int = 96, per_branch: int = 3) -> TreeJoints:
    """Split a skeleton's branches into rigid segments, each turning about the node it hangs from.

    The trunk and the thickest branches (by radius at their base, as many as fit in
    ``max_joints``) are cut into up to ``per_branch`` segments of equal length; a segment's
    joint turns about the node before its first node (for a branch's first segment, the
    node of its parent branch it grows from), so a bent branch stays attached. Thinner
    branches move with the joint of the node they grow from.

    Parameters
    ----------
    skeleton : TreeSkeleton
    max_joints : int
        At most this many joints (at least ``per_branch``).
    per_branch : int
        Segments per jointed branch (bending along a branch, not only at its base).

    Returns
    -------
    TreeJoints

    Examples
    --------
    >>> s = TreeSkeleton(np.array([[0, 0, 0], [0, 1, 0], [0, 2, 0], [0.5, 2.5, 0.]]), np.array([-1, 0, 1, 1]),
    ...                  radius=np.array([0.2, 0.15, 0.1, 0.05]))
    >>> j = tree_joints(s, max_joints=4, per_branch=2)
    >>> j.parent.tolist(), j.node_joint.tolist()
    ([-1, 0, 0], [0, 0, 1, 2])
    """
    per_branch = check_int(per_branch, "per_branch", 1, 16)
    max_joints = check_int(max_joints, "max_joints", per_branch, 1024)
    chains = skeleton.chains()
    own = [c if c[0] == 0 and k == 0 else c[1:] for k, c in enumerate(chains)]
    # the trunk (chain 0) always; then the thickest branches by their base radius
    base_r = np.array([skeleton.radius[o[0]] if len(o) else 0.0 for o in own])
    budget = max_joints - min(per_branch, len(own[0]))
    chosen = {0}
    for k in np.argsort(-base_r, kind="stable"):
        if k == 0 or len(own[k]) == 0:
            continue
        n = min(per_branch, len(own[k]))
        if n > budget:
            break
        chosen.add(int(k))
        budget -= n
    seg = skeleton.segment_lengths()
    node_joint = np.full(skeleton.n_nodes, -1, np.int64)
    pivots, parent, pivot_node = [], [], []
    for k, (chain, nodes) in enumerate(zip(chains, own)):  # parent chains come first
        if len(nodes) == 0:
            continue
        if k not in chosen:
            node_joint[nodes] = node_joint[chain[0]]
            continue
        n = min(per_branch, len(nodes))
        s = np.cumsum(seg[nodes]) if k else np.cumsum(np.r_[0.0, seg[nodes[1:]]])
        part = np.minimum((s / max(s[-1], 1e-12) * n - 1e-9).astype(np.int64), n - 1) if s[-1] > 0 \
            else np.zeros(len(nodes), np.int64)
        part = np.maximum.accumulate(np.maximum(part, 0))
        for p in range(n):
            members = nodes[part == p]
            if len(members) == 0:
                continue
            first = int(members[0])
            hang = int(skeleton.parent[first]) if first != 0 else 0
            pivot_node.append(hang)
            pivots.append(skeleton.positions[hang])
            parent.append(int(node_joint[hang]) if first != 0 else -1)
            node_joint[members] = len(pivots) - 1
    return TreeJoints(np.asarray(pivots, np.float64).reshape(-1, 3), np.asarray(parent, np.int64),
                      np.asarray(pivot_node, np.int64), node_joint)
