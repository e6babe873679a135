"""Smooth branch curves: a polyline skeleton as clamped cubic B-splines (seed 004 §4).

Seed paper 004 models every branch as a generalized cylinder along a degree-3 B-spline
through the branch's control nodes, with a radius at each node. :func:`bspline_skeleton`
turns a coarse skeleton (a few nodes per branch, e.g. from an L-system) into a dense one
whose branches follow such curves, ready for :func:`~treeform.geometry.branch_mesh` /
:func:`~treeform.geometry.tree_mesh`.

Each branch chain (:meth:`TreeSkeleton.chains <treeform.structures.skeleton.TreeSkeleton.chains>`)
is the control polygon of a clamped (open-uniform knot vector) B-spline of degree
``min(3, n_ctrl - 1)``: the curve starts and ends on the chain's first and last nodes, is C²
in between, and stays in the convex hull of its control points. The curve is sampled in
Greville parameter space: the Greville abscissa ``ξ_j`` is the parameter that "belongs" to
control point ``j``, and ``samples_per_segment`` points split every ``[ξ_j, ξ_{j+1}]``
evenly, so a side branch can start exactly on its parent's curve point ``C(ξ_j)`` at its
attachment node ``j``.

Everything is vectorized over all samples of all chains: the basis functions are cached
per control-point count, and the only sequential step, each side chain's start moving
with its parent's curve, is resolved by pointer jumping over the chain tree.
"""

from __future__ import annotations

import functools

import numpy as np

from treeform._shared.checks import check_int
from treeform._shared.errors import InputError
from treeform.structures.skeleton import TreeSkeleton

__all__ = ["bspline_skeleton"]

_MAX_DEGREE = 3


# --------------------------------------------------------------------------- basis
def _knots(n: int) -> tuple[np.ndarray, int]:
    """Clamped open-uniform knot vector of ``n >= 2`` control points and its degree."""
    p = min(_MAX_DEGREE, n - 1)
    return np.concatenate([np.zeros(p), np.linspace(0.0, 1.0, n - p + 1), np.ones(p)]), p


def _greville(knots: np.ndarray, n: int, p: int) -> np.ndarray:
    """(n,) Greville abscissae: the mean of the ``p`` knots after each control point's first."""
    idx = np.arange(n)[:, None] + np.arange(1, p + 1)
    xi = knots[idx].mean(axis=1)
    xi[0], xi[-1] = 0.0, 1.0
    return xi


@functools.lru_cache(maxsize=512)
def _chain_table(n: int, s: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Sampling of a chain of ``n >= 2`` control points, ``s`` samples per segment.

    Returns ``(first, weights, nearest)`` for the ``m = (n - 1)·s + 1`` samples: ``weights``
    (m, 4) are the nonzero basis functions of the controls ``first + 0..3`` (zero-padded for
    degree < 3; Cox-de Boor, The NURBS Book A2.2); ``nearest`` (m,) is the control point
    nearest in parameter (its Greville abscissa). Sample ``j·s`` is the curve at ``ξ_j``.
    """
    knots, p = _knots(n)
    xi = _greville(knots, n, p)
    frac = np.arange(s) / s
    u = np.concatenate([(xi[:-1, None] + frac * np.diff(xi)[:, None]).ravel(), [1.0]])
    m = len(u)
    span = np.clip(np.searchsorted(knots, u, side="right") - 1, p, n - 1)
    basis = np.zeros((m, _MAX_DEGREE + 1))
    basis[:, 0] = 1.0
    left = np.zeros((m, p + 1))
    right = np.zeros((m, p + 1))
    for j in range(1, p + 1):
        left[:, j] = u - knots[span + 1 - j]
        right[:, j] = knots[span + j] - u
        saved = np.zeros(m)
        for r in range(j):
            tmp = basis[:, r] / (right[:, r + 1] + left[:, j - r])
            basis[:, r] = saved + right[:, r + 1] * tmp
            saved = left[:, j - r] * tmp
        basis[:, j] = saved
    first = span - p
    # the clamped curve interpolates its end controls: make both ends exact
    basis[0], basis[-1] = 0.0, 0.0
    basis[0, 0] = 1.0
    basis[-1, p] = 1.0
    nearest = np.repeat(np.arange(n - 1), s) + np.tile(2 * np.arange(s) >= s, n - 1)
    nearest = np.concatenate([nearest, [n - 1]])
    for a in (first, basis, nearest):
        a.flags.writeable = False
    return first, basis, nearest


# --------------------------------------------------------------------------- chains
def _chains(skeleton: TreeSkeleton):
    """The skeleton's chains ``(flat, lens)`` in an order where each chain's parent chain comes first.

    Also returns, per non-root chain, the chain that owns its attachment node and that
    node's index in it.
    """
    from treeform.geometry import tubes

    flat, lens = tubes._chain_arrays(skeleton)
    for _ in range(2):
        att_chain, att_local = _attachments(skeleton.n_nodes, flat, lens)
        if np.all(att_chain < np.arange(1, len(lens))):
            return flat, lens, att_chain, att_local
        flat, lens = _parents_first(flat, lens, att_chain)
    raise AssertionError("chain order: a parent chain after its child")  # pragma: no cover


def _attachments(n_nodes: int, flat: np.ndarray, lens: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For chains 1.. : the chain owning the attachment node (a chain's first node) and its index there."""
    start = np.cumsum(lens) - lens
    cid = np.repeat(np.arange(len(lens)), lens)
    local = np.arange(len(flat)) - start[cid]
    own = np.ones(len(flat), bool)
    own[start[1:]] = False  # a side chain's first node belongs to its parent chain
    owner = np.zeros(n_nodes, np.int64)
    where = np.zeros(n_nodes, np.int64)
    owner[flat[own]] = cid[own]
    where[flat[own]] = local[own]
    att = flat[start[1:]]
    return owner[att], where[att]


def _parents_first(flat: np.ndarray, lens: np.ndarray, att_chain: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Reorder chains by depth in the chain tree (stable), so parent chains precede children."""
    up = np.concatenate([[0], att_chain])
    depth = np.zeros(len(lens), np.int64)
    cur = up.copy()
    for _ in range(len(lens)):
        live = cur != 0
        if not live.any():
            break
        depth += live
        cur = up[cur]
    depth[1:] += 1
    perm = np.argsort(depth, kind="stable")
    start = np.cumsum(lens) - lens
    flat = np.concatenate([flat[start[c]:start[c] + lens[c]] for c in perm])
    return flat, lens[perm]


# --------------------------------------------------------------------------- public
def bspline_skeleton(skeleton: TreeSkeleton, *, samples_per_segment: int = 3) -> TreeSkeleton:
    """Smooth every branch of a skeleton into a clamped cubic B-spline (seed 004 §4) and resample it.

    Each chain of :meth:`~treeform.structures.skeleton.TreeSkeleton.chains` (positions and radii
    of its ``n`` nodes) is the control polygon of a clamped B-spline of degree ``min(3, n - 1)``
    (two nodes: the straight segment). The curve keeps the chain's first and last points (the
    root and every tip stay where they are, with their radii), is smooth in between and lies in
    the convex hull of the control points, so radii stay positive where the input's were. It is
    not an interpolating spline: inner nodes act as control points, and the curve cuts their
    corners.

    Every chain is sampled at ``samples_per_segment`` points per control-polygon segment,
    evenly in the Greville parameter space, so each control point ``j`` has a sample at its
    Greville abscissa ``ξ_j``. A side chain starts at its parent's sample at the attachment
    node's ``ξ_j`` (its first control point moves there), so branches stay joined on the
    smoothed parent curve.

    Parameters
    ----------
    skeleton : TreeSkeleton
        N nodes (the control polygon), C chains.
    samples_per_segment : int
        New nodes per control-polygon segment, 1..32; 1 keeps the node count (every node moves
        to its Greville point on the curve).

    Returns
    -------
    TreeSkeleton
        ``1 + (N - 1) * samples_per_segment`` nodes, chains in the input's chain order (node 0
        is the input root, unchanged); the same tips (count and positions) and tip radii.
        ``order`` and ``age`` of each sample come from the chain's control point nearest in
        parameter; ``meta`` is a copy with ``"bspline_samples_per_segment"`` added.

    Raises
    ------
    InputError
        ``skeleton`` is not a TreeSkeleton or ``samples_per_segment`` not an integer in 1..32.

    Examples
    --------
    >>> s = TreeSkeleton(np.array([[0, 0, 0], [0, 1, 0], [1, 2, 0.]]), np.array([-1, 0, 1]),
    ...                  np.array([0.1, 0.08, 0.02]))
    >>> b = bspline_skeleton(s, samples_per_segment=4)
    >>> b.n_nodes, b.positions[-1].tolist(), float(b.radius[-1])
    (9, [1.0, 2.0, 0.0], 0.02)
    >>> b.positions[4].round(3).tolist()  # the corner at (0, 1) is cut
    [0.25, 1.0, 0.0]
    """
    if not isinstance(skeleton, TreeSkeleton):
        raise InputError(f"skeleton: expected a TreeSkeleton, got {type(skeleton).__name__}")
    s = check_int(samples_per_segment, "samples_per_segment", 1, 32)
    meta = dict(skeleton.meta)
    meta["bspline_samples_per_segment"] = s
    if skeleton.n_nodes < 2:
        return TreeSkeleton(skeleton.positions.copy(), skeleton.parent.copy(), skeleton.radius.copy(),
                            skeleton.order.copy(), skeleton.age.copy(), meta)

    flat, lens, att_chain, att_local = _chains(skeleton)
    n_chains = len(lens)
    start = np.cumsum(lens) - lens
    # the sample tables of all chains, concatenated (one table per distinct control count)
    sizes, inverse = np.unique(lens, return_inverse=True)
    tables = [_chain_table(int(n), s) for n in sizes]
    tab_len = (sizes - 1) * s + 1
    tab_off = np.cumsum(tab_len) - tab_len
    t_first = np.concatenate([t[0] for t in tables])
    t_basis = np.concatenate([t[1] for t in tables])
    t_near = np.concatenate([t[2] for t in tables])

    rows = (lens - 1) * s + 1
    row_start = np.cumsum(rows) - rows
    cid = np.repeat(np.arange(n_chains), rows)
    k = np.arange(len(cid)) - row_start[cid]
    t = tab_off[inverse][cid] + k
    first, basis = t_first[t], t_basis[t]

    # uncorrected curves: every chain with its own (unmoved) control points, radius as a 4th coordinate
    ctrl = np.concatenate([skeleton.positions, skeleton.radius[:, None]], axis=1)
    last = (start + lens - 1)[cid]
    gather = np.minimum(start[cid][:, None] + first[:, None] + np.arange(_MAX_DEGREE + 1), last[:, None])
    vals = np.einsum("rk,rkd->rd", basis, ctrl[flat[gather]])

    # a side chain's first control moves by delta_c onto its parent's curve; the parent's own
    # first control may have moved too: delta_c = a_c + w_c · delta_parent (pointer jumping)
    w0 = np.where(first == 0, basis[:, 0], 0.0)  # weight of the chain's first control per sample
    att_row = row_start[att_chain] + att_local * s
    a = np.zeros((n_chains, 4))
    a[1:] = vals[att_row] - ctrl[flat[start[1:]]]
    w = np.zeros(n_chains)
    w[1:] = np.where(att_chain > 0, w0[att_row], 0.0)
    up = np.concatenate([[0], att_chain])
    while w.any():
        a = a + w[:, None] * a[up]
        w = w * w[up]
        up = up[up]
    vals += w0[:, None] * a[cid]

    # a side chain's first sample is its parent's sample: not a node of its own
    emitted = np.ones(len(cid), bool)
    emitted[row_start[1:]] = False
    row_to_out = np.cumsum(emitted) - 1
    row_to_out[row_start[1:]] = row_to_out[att_row]
    parent = np.empty(len(cid), np.int64)
    parent[0] = -1
    parent[1:] = row_to_out[:-1]
    near = t_near[t]
    near = np.where(cid > 0, np.maximum(near, 1), near)  # a side chain's own nodes, not the parent's
    src = flat[start[cid] + near]
    out = vals[emitted]
    return TreeSkeleton(out[:, :3], parent[emitted], np.maximum(out[:, 3], 0.0), skeleton.order[src][emitted],
                        skeleton.age[src][emitted], meta)
