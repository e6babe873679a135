"""Seed 002 §5.2: replication blocks from the visible branches, grown into the hull."""

import numpy as np

from treeform.methods.multiview.replication import grow_by_replication, replication_blocks


def _visible():
    """A trunk to (0, 2, 0) forking into two limbs, each of which forks again (13 nodes)."""
    pos, par = [[0, 0, 0], [0, 1, 0], [0, 2, 0]], [-1, 0, 1]

    def limb(start, d, n):
        p = start
        for _ in range(n):
            pos.append(list(np.asarray(pos[p]) + d))
            par.append(p)
            p = len(pos) - 1
        return p

    for sx in (1, -1):
        end = limb(2, np.array([0.5 * sx, 0.5, 0]), 2)
        limb(end, np.array([0.4 * sx, 0.4, 0.2]), 2)
        limb(end, np.array([0.4 * sx, 0.4, -0.2]), 2)
    return np.array(pos, float), np.array(par)


def test_blocks_are_the_visible_subtrees():
    pos, par = _visible()
    blocks = replication_blocks(pos, par, min_nodes=4)
    assert len(blocks) == 2                                  # the two limbs with their forks
    for b in blocks:
        assert np.allclose(b.positions[0], 0) and b.parent[0] == -1
        assert (b.parent[1:] < np.arange(1, len(b.parent))).all()    # parents first
        assert np.linalg.norm(b.primary) > 1.0               # root (the fork) to a tip
    assert replication_blocks(pos, par, min_nodes=50) == []


def test_growth_replaces_end_branches_inside_the_hull():
    pos, par = _visible()
    blocks = replication_blocks(pos, par, min_nodes=4)
    rng = np.random.default_rng(0)

    def inside(p):  # a hull: the ball of radius 4 about (0, 3, 0)
        return np.linalg.norm(p - [0, 3, 0], axis=1) < 4.0

    P, Q, st = grow_by_replication(pos, par, blocks, inside, rng, rounds=6)
    assert st["replaced"] >= 1 and len(P) > len(pos)
    assert (Q[1:] < np.arange(1, len(Q))).all() and Q[0] == -1   # one tree, parents first
    orig = {tuple(np.round(p, 9)) for p in pos}
    new = np.array([tuple(np.round(p, 9)) not in orig for p in P])
    assert new.any() and inside(P[new]).all()                      # what grew lies in the hull
    assert np.allclose(P[:3], pos[:3])                             # the trunk stays
    again = grow_by_replication(pos, par, blocks, inside, np.random.default_rng(0), rounds=6)
    assert np.array_equal(again[0], P) and np.array_equal(again[1], Q)
    # a hull that holds nothing new: nothing is replaced
    P2, Q2, st2 = grow_by_replication(pos, par, blocks, lambda p: np.zeros(len(p), bool), rng, rounds=6)
    assert st2["replaced"] == 0 and np.array_equal(P2, pos) and np.array_equal(Q2, par)
    # the node budget
    P3, _, _ = grow_by_replication(pos, par, blocks, inside, np.random.default_rng(1), rounds=50, max_nodes=20)
    assert len(P3) < 20 + max(len(b.positions) for b in blocks)
