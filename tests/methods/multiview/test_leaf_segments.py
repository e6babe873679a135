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


def test_rounds_of_synthesis_fill_the_bare_branches_within_the_budget():
    from scipy.spatial import cKDTree

    from treeform.methods.multiview.leaf_segments import fill_sparse

    sk = _y_tree()
    t = np.linspace(0.1, 1.9, 20)[:, None]
    pos = np.array([0, 2, 0]) + t * np.array([1, 1, 0]) / np.sqrt(2)
    node = np.full(20, 5)
    chains = {"limb2": set(range(7, 11)), "limb3": set(range(11, 15)), "leader": set(range(15, 18))}

    def bare(twig):
        return sorted(k for k, v in chains.items() if not v & set(twig.tolist()))

    one = fill_sparse(pos, node, sk, np.random.default_rng(0), budget=1000, rounds=1)
    three = fill_sparse(pos, node, sk, np.random.default_rng(0), budget=1000, rounds=3)
    assert len(bare(one[2])) == 2 and bare(three[2]) == []  # one round fills one of the three bare branches
    assert len(three[0]) > len(one[0]) and three[0].max() < 20  # copies of copies name the original leaves
    # the budget caps the copies; the same seed gives the same leaves
    capped = fill_sparse(pos, node, sk, np.random.default_rng(1), budget=25, rounds=3)
    again = fill_sparse(pos, node, sk, np.random.default_rng(1), budget=25, rounds=3)
    assert len(capped[0]) == 25 and all(np.array_equal(a, b) for a, b in zip(capped, again))
    # copies beyond the leaf volume go: a volume around limb 1 and the leader keeps those on limbs 2
    # and 3 only by the fork
    vol = cKDTree(np.concatenate([pos, [[0, 2 + s, 0] for s in np.linspace(0, 1.5, 16)]]))
    kept = fill_sparse(pos, node, sk, np.random.default_rng(0), budget=1000, rounds=3, volume=vol, reach=0.2)
    on_limbs = np.isin(kept[2], sorted(chains["limb2"] | chains["limb3"]))
    assert len(kept[0]) > 4 * on_limbs.sum() and (kept[1][on_limbs, 1] < 2.3).all()
    assert cKDTree(vol.data).query(kept[1])[0].max() <= 0.2
    assert len(fill_sparse(pos, node, sk, np.random.default_rng(0), budget=0)[0]) == 0
