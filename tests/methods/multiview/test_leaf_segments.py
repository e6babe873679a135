"""Seed 002 §6.2: the synthesis of the sparse branches' leaves."""

import numpy as np

from treeform.methods.multiview.leaf_segments import synthesize_sparse
from treeform.structures import TreeSkeleton


def _y_tree():
    """A trunk (0-2) forking at node 2 into three straight limbs of 4 nodes (3-6, 7-10, 11-14) and a
    thicker leader going on up (15-17): the trunk's chain is the leader's, each limb its own branch."""
    pos = [[0, 0, 0], [0, 1, 0], [0, 2, 0]]
    par = [-1, 0, 1]
    for d in ([1, 1, 0], [-1, 1, 0], [0, 1, 1]):
        d = np.array(d, float) / np.linalg.norm(d)
        for s in range(1, 5):
            pos.append(list(np.array([0, 2, 0]) + 0.5 * s * d))
            par.append(2 if s == 1 else len(pos) - 2)
    for s in range(1, 4):
        pos.append([0, 2 + 0.5 * s, 0])
        par.append(2 if s == 1 else len(pos) - 2)
    radius = np.full(len(pos), 0.05)
    radius[[0, 1, 2, 15, 16, 17]] = 0.1
    return TreeSkeleton(np.array(pos, float), np.array(par), radius, np.zeros(len(pos), int))


def test_the_sparsest_branch_gets_the_densest_branchs_leaves():
    sk = _y_tree()
    rng = np.random.default_rng(0)
    # 20 leaves along limb 1, 4 on limb 3, none on limb 2
    t = np.linspace(0.1, 1.9, 20)[:, None]
    d1 = np.array([1, 1, 0]) / np.sqrt(2)
    p1 = np.array([0, 2, 0]) + t * d1 + [0, 0, 0.1]
    p3 = np.array([0, 2, 0]) + np.linspace(0.5, 1.5, 4)[:, None] * np.array([0, 1, 1]) / np.sqrt(2)
    pos = np.concatenate([p1, p3])
    node = np.concatenate([np.full(20, 5), np.full(4, 13)])
    idx, new_pos, new_node = synthesize_sparse(pos, node, sk, rng)
    assert len(idx) == 20 and set(idx) == set(range(20))  # limb 1's leaves, copied
    assert set(new_node) <= set(range(7, 11))               # onto limb 2
    d2 = np.array([-1, 1, 0]) / np.sqrt(2)
    along = (new_pos - [0, 2, 0]) @ d2
    assert along.min() > 0 and along.max() < 2.1            # along limb 2, not beyond it
    off = np.linalg.norm((new_pos - [0, 2, 0]) - along[:, None] * d2, axis=1)
    assert off.max() < 0.15                                  # as close to it as they were to limb 1
    # a limb outside the crown's leaf volume stays bare
    inside = np.ones(sk.n_nodes, bool)
    inside[7:11] = False
    idx2, _, node2 = synthesize_sparse(pos, node, sk, np.random.default_rng(0), inside=inside)
    assert len(idx2) and not set(node2) & set(range(7, 11))  # the next sparsest (the bare leader) gets them
