"""Occluded branches by replication blocks (seed 002 §5.2, unconstrained growth).

The visible branches are the texture sample: any subtree of them is a candidate replication
block. Growth picks an endpoint of the tree (mostly at random, with priority to the branches
nearer the trunk), takes a random block, turns it about its primary branch by a random angle,
scales it so that its primary branch is as long as the end branch it replaces, and puts it in
that end branch's place; what falls outside the views' silhouettes (the carved hull) is cut
off. The constrained growth toward the 3D points that follows is the project's space
colonization with the paper's 90-degree influence cones.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Block", "replication_blocks", "grow_by_replication", "rotation_onto"]


@dataclass
class Block:
    """A subtree: ``positions`` (M, 3) relative to its root (row 0, at the origin), ``parent`` (M,)
    (-1 for the root), and its primary branch (the path from the root along the largest subtrees to
    a tip) as the vector ``primary`` from the root to that tip."""

    positions: np.ndarray
    parent: np.ndarray
    primary: np.ndarray


def _children(parent: np.ndarray) -> list[list[int]]:
    out = [[] for _ in range(len(parent))]
    for i, p in enumerate(parent):
        if p >= 0:
            out[p].append(i)
    return out


def _subtree_sizes(parent: np.ndarray) -> np.ndarray:
    size = np.ones(len(parent), np.int64)
    for i in range(len(parent) - 1, 0, -1):  # parents come before their children
        if parent[i] >= 0:
            size[parent[i]] += size[i]
    return size


def replication_blocks(positions, parent, *, min_nodes: int = 6, max_share: float = 0.5,
                       max_blocks: int = 64) -> list[Block]:
    """The candidate replication blocks of a skeleton: its subtrees rooted at a fork's child.

    Parameters
    ----------
    positions : ndarray, shape (N, 3)
    parent : ndarray, shape (N,), int (parents before children, -1 for the root)
    min_nodes : int
        Least nodes of a block (a twig of two nodes has no branching to copy).
    max_share : float
        Most of the skeleton's nodes a block may hold (the trunk's subtree is the tree).
    max_blocks : int
        At most this many, the largest.

    Returns
    -------
    list of Block
    """
    pos = np.asarray(positions, np.float64)
    par = np.asarray(parent, np.int64)
    n = len(par)
    if n < min_nodes:
        return []
    size = _subtree_sizes(par)
    kids = _children(par)
    roots = [v for v in range(1, n) if par[v] >= 0 and len(kids[par[v]]) >= 2
             and min_nodes <= size[v] <= max_share * n]
    roots.sort(key=lambda v: -size[v])
    blocks = []
    for v in roots[:max_blocks]:
        nodes = [v]
        k = 0
        while k < len(nodes):
            nodes.extend(kids[nodes[k]])
            k += 1
        nodes = np.array(sorted(nodes))  # parents first
        index = {int(u): i for i, u in enumerate(nodes)}
        # the block's root is v's parent (the fork): the block hangs where the end branch began
        bpos = np.vstack([pos[par[v]], pos[nodes]]) - pos[par[v]]
        bpar = np.array([-1] + [0 if u == v else index[int(par[u])] + 1 for u in nodes], np.int64)
        tip = v
        while kids[tip]:
            tip = max(kids[tip], key=lambda c: size[c])
        blocks.append(Block(bpos, bpar, pos[tip] - pos[par[v]]))
    return blocks


def rotation_onto(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(3, 3) rotation taking unit vector ``a`` onto unit vector ``b`` (about their common normal).

    >>> bool(np.allclose(rotation_onto(np.array([1.0, 0, 0]), np.array([0, 1.0, 0])) @ [1, 0, 0], [0, 1, 0]))
    True
    """
    v, c = np.cross(a, b), float(np.dot(a, b))
    if c < -1 + 1e-9:  # opposite: a half turn about any axis normal to a
        n = np.cross(a, [1.0, 0.0, 0.0] if abs(a[0]) < 0.9 else [0.0, 1.0, 0.0])
        n /= np.linalg.norm(n)
        return 2.0 * np.outer(n, n) - np.eye(3)
    vx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
    return np.eye(3) + vx + vx @ vx / (1.0 + c)


def _axis_angle(axis: np.ndarray, angle: float) -> np.ndarray:
    x, y, z = axis
    c, s = np.cos(angle), np.sin(angle)
    k = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
    return np.eye(3) + s * k + (1 - c) * k @ k


def grow_by_replication(positions, parent, blocks: list[Block], inside, rng, *, rounds: int,
                        max_nodes: int = 4000) -> tuple[np.ndarray, np.ndarray, dict]:
    """Replace end branches by replication blocks, capped by ``inside`` (seed 002 §5.2).

    Parameters
    ----------
    positions, parent : the skeleton to grow (parents before children)
    blocks : list of Block
        From :func:`replication_blocks` of the visible branches.
    inside : callable
        ``inside(points (M, 3)) -> (M,) bool``: within the views' silhouettes (the carved hull).
    rng : numpy.random.Generator
    rounds : int
        End branches replaced (at most).
    max_nodes : int
        The growth stops at this many nodes.

    Returns
    -------
    (positions, parent, stats)
        The grown skeleton (parents before children) and ``{"replaced", "cut"}``: end branches
        replaced, block nodes cut off outside the hull.
    """
    pos = [np.asarray(p, np.float64) for p in np.asarray(positions, np.float64)]
    par = [int(p) for p in np.asarray(parent)]
    alive = [True] * len(par)
    stats = {"replaced": 0, "cut": 0}
    if not blocks:
        return np.asarray(positions, np.float64), np.asarray(parent, np.int64), stats
    for _ in range(int(rounds)):
        if sum(alive) >= max_nodes:
            break
        n = len(par)
        nkids = np.zeros(n, np.int64)
        for i in range(n):
            if alive[i] and par[i] >= 0:
                nkids[par[i]] += 1
        tips = [i for i in range(1, n) if alive[i] and nkids[i] == 0]
        if not tips:
            break
        # each tip's end branch: back to the last fork (or the root)
        ends = []
        depth = np.zeros(len(tips))
        for j, t in enumerate(tips):
            chain = [t]
            u = par[t]
            while u >= 0 and nkids[u] == 1 and par[u] >= 0:
                chain.append(u)
                u = par[u]
            fork = u if u >= 0 else chain.pop()
            d, w = 0, fork
            while par[w] >= 0:
                w, d = par[w], d + 1
            ends.append((fork, chain))
            depth[j] = d
        # mostly random, with priority to the branches nearer the trunk
        weight = 1.0 / (1.0 + depth)
        fork, chain = ends[rng.choice(len(ends), p=weight / weight.sum())]
        t = chain[0]
        vec = pos[t] - pos[fork]
        length = float(np.linalg.norm(vec))
        b = blocks[rng.integers(len(blocks))]
        blen = float(np.linalg.norm(b.primary))
        if length < 1e-9 or blen < 1e-9:
            continue
        d = vec / length
        R = _axis_angle(d, rng.uniform(0, 2 * np.pi)) @ rotation_onto(b.primary / blen, d)  # onto d, then about it
        new = pos[fork] + (length / blen) * b.positions @ R.T
        ok = np.asarray(inside(new[1:]), bool)
        keep = np.zeros(len(new), bool)
        keep[0] = True
        for i in range(1, len(new)):  # a node outside the hull goes with everything beyond it
            keep[i] = ok[i - 1] and keep[b.parent[i]]
        if keep.sum() <= 1:
            continue
        for u in chain:  # the end branch goes; the block's primary branch takes its place
            alive[u] = False
        index = {0: fork}
        for i in range(1, len(new)):
            if keep[i]:
                index[i] = len(par)
                pos.append(new[i])
                par.append(index[int(b.parent[i])])
                alive.append(True)
        stats["replaced"] += 1
        stats["cut"] += int((~keep).sum())
    alive = np.asarray(alive)
    remap = np.cumsum(alive) - 1
    P = np.asarray(pos)[alive]
    par = np.asarray(par)[alive]
    return P, np.where(par >= 0, remap[np.maximum(par, 0)], -1).astype(np.int64), stats
