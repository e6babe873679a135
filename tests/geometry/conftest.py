"""Skeletons and foliage made programmatically for the geometry tests."""

from __future__ import annotations

import numpy as np
import pytest

from treeform.structures import Foliage, TreeSkeleton


def y_tree() -> TreeSkeleton:
    """Trunk 0-1, forking at node 1 into two branches (chains [0, 1, 3] and [1, 2])."""
    pos = np.array([[0, 0, 0], [0, 1, 0], [-0.5, 1.8, 0.1], [0.6, 1.7, -0.1]], float)
    return TreeSkeleton(pos, np.array([-1, 0, 1, 1]), np.array([0.1, 0.08, 0.03, 0.04]))


def random_parent_tree(n: int = 300, seed: int = 0) -> TreeSkeleton:
    """A random parent array (parent[i] < i) with upward-ish random segments and pipe-model radii."""
    rng = np.random.default_rng(seed)
    parent = np.concatenate([[-1], (rng.random(n - 1) * np.arange(1, n)).astype(np.int64)])
    step = rng.normal(size=(n, 3)) * 0.15 + [0.0, 0.25, 0.0]
    pos = np.zeros((n, 3))
    for i in range(1, n):
        pos[i] = pos[parent[i]] + step[i]
    return TreeSkeleton(pos, parent, _pipe_radii(parent, 0.004))


def _pipe_radii(parent: np.ndarray, tip_radius: float) -> np.ndarray:
    """Pipe model: r² of a node = sum of its children's r² (tips get ``tip_radius``)."""
    n = len(parent)
    r2 = np.zeros(n)
    has_child = np.zeros(n, bool)
    has_child[parent[1:]] = True
    r2[~has_child] = tip_radius**2
    for i in range(n - 1, 0, -1):
        r2[parent[i]] += r2[i]
    return np.sqrt(r2)


def grown_tree(n_nodes: int = 5000, seed: int = 0) -> TreeSkeleton:
    """A plausible tree: a trunk and laterals that keep growing and branching, up to n_nodes."""
    rng = np.random.default_rng(seed)
    pos = [np.zeros(3)]
    parent = [-1]
    order = [0]
    tips = [(0, np.array([0.0, 1.0, 0.0]), 0)]  # (node, heading, order)
    while len(pos) < n_nodes and tips:
        new_tips = []
        for node, head, o in tips:
            if len(pos) >= n_nodes:
                break
            head = head + rng.normal(size=3) * 0.15 + [0.0, 0.05, 0.0]
            head /= np.linalg.norm(head)
            pos.append(pos[node] + head * (0.12 if o else 0.2))
            parent.append(node)
            order.append(o)
            me = len(pos) - 1
            new_tips.append((me, head, o))
            if rng.random() < (0.25 if o < 3 else 0.0) and len(pos) > 5:
                side = np.cross(head, rng.normal(size=3))
                side = side / np.linalg.norm(side) + 0.3 * head
                new_tips.append((me, side / np.linalg.norm(side), o + 1))
        tips = new_tips
    parent = np.array(parent)
    return TreeSkeleton(np.array(pos), parent, _pipe_radii(parent, 0.003), np.array(order))


def random_foliage(skeleton: TreeSkeleton, m: int, seed: int = 0) -> Foliage:
    """m leaves scattered around random nodes, random orientation, greenish colours."""
    rng = np.random.default_rng(seed)
    node = rng.integers(0, skeleton.n_nodes, m)
    pos = skeleton.positions[node] + rng.normal(size=(m, 3)) * 0.1
    n = rng.normal(size=(m, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    up = np.cross(n, rng.normal(size=(m, 3)))
    up /= np.linalg.norm(up, axis=1, keepdims=True)
    col = np.clip(np.array([0.2, 0.45, 0.12]) + rng.normal(size=(m, 3)) * 0.05, 0, 1)
    return Foliage(pos, n, up, rng.uniform(0.1, 0.3, m), col, node)


@pytest.fixture(scope="session")
def big_tree():
    """~5k nodes and 20k leaves."""
    s = grown_tree(5000, seed=1)
    return s, random_foliage(s, 20_000, seed=2)
