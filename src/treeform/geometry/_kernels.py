"""Compiled tree walks of the meshing (numba).

Imported lazily (importing numba costs a few tenths of a second). :func:`chain_layout` is
:meth:`TreeSkeleton.chains <treeform.structures.skeleton.TreeSkeleton.chains>` (the pure-Python
reference, which must stay importable without numba) as two flat arrays, the same chains in the
same order.
"""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, nogil=True)
def chain_layout(parent: np.ndarray, order: np.ndarray, radius: np.ndarray):
    """The skeleton's branch chains, concatenated: ``(nodes, lengths)``.

    Same walk as ``TreeSkeleton.chains``: a stack of chain starts, popped last-in first-out;
    each chain follows the child with the largest ``(same order as the node, radius, -index)``
    and pushes the other children (in index order) as chains that begin at their parent.

    Returns
    -------
    nodes : ndarray of int64, shape (N + C - 1,)
    lengths : ndarray of int64, shape (C,)
    """
    n = len(parent)
    # children of each node in increasing index order (CSR)
    ptr = np.zeros(n + 1, np.int64)
    for i in range(1, n):
        ptr[parent[i] + 1] += 1
    n_chains = 1
    for i in range(n):
        if ptr[i + 1] > 1:
            n_chains += ptr[i + 1] - 1
    for i in range(n):
        ptr[i + 1] += ptr[i]
    kids = np.empty(max(n - 1, 0), np.int64)
    fill = ptr[:-1].copy()
    for i in range(1, n):
        p = parent[i]
        kids[fill[p]] = i
        fill[p] += 1

    nodes = np.empty(n + n_chains - 1, np.int64)
    lengths = np.empty(n_chains, np.int64)
    stack_start = np.empty(n_chains, np.int64)
    stack_from = np.empty(n_chains, np.int64)
    stack_start[0] = 0
    stack_from[0] = -1
    top = 1
    pos = 0
    c = 0
    while top > 0:
        top -= 1
        node = stack_start[top]
        begin = pos
        if stack_from[top] >= 0:
            nodes[pos] = stack_from[top]
            pos += 1
        nodes[pos] = node
        pos += 1
        while ptr[node + 1] > ptr[node]:
            o = order[node]
            best = kids[ptr[node]]
            best_same = order[best] == o
            for j in range(ptr[node] + 1, ptr[node + 1]):
                k = kids[j]
                same = order[k] == o
                # the first maximum wins (Python's max); kids come in increasing index, so -index never does
                if (same and not best_same) or (same == best_same and radius[k] > radius[best]):
                    best = k
                    best_same = same
            for j in range(ptr[node], ptr[node + 1]):
                k = kids[j]
                if k != best:
                    stack_start[top] = k
                    stack_from[top] = node
                    top += 1
            nodes[pos] = best
            pos += 1
            node = best
        lengths[c] = pos - begin
        c += 1
    return nodes, lengths


@nb.njit(cache=True, nogil=True)
def card_corners(positions: np.ndarray, normals: np.ndarray, up: np.ndarray, half: np.ndarray):
    """The four corners and the normal of every leaf card, as float32 vertex arrays.

    :func:`treeform.geometry.leaves.card_frames` and the corner sums of
    :func:`treeform.geometry.leaves.leaf_cards` in one pass, operation for operation (the same
    bits): ``n = normal / |normal|``, ``u = unit(up - (up·n) n)`` (where that vanishes, ``(0, 1, 0)``
    or, for a normal near ±y, ``(1, 0, 0)`` projected the same way), ``r = u × n``; corners
    ``c ∓ half·r ∓ half·u`` counter-clockwise from the bottom left.

    Returns
    -------
    corners : ndarray, shape (4·M, 3), float32
    card_normals : ndarray, shape (4·M, 3), float32
    ok : bool
        False if a normal is shorter than 1e-12 (then the arrays are meaningless).
    """
    m = positions.shape[0]
    pos = np.empty((4 * m, 3), np.float32)
    nrm = np.empty((4 * m, 3), np.float32)
    for i in range(m):
        n0, n1, n2 = normals[i, 0], normals[i, 1], normals[i, 2]
        nl = np.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
        if nl < 1e-12:
            return pos, nrm, False
        if nl > 0:
            n0, n1, n2 = n0 / nl, n1 / nl, n2 / nl
        a0, a1, a2 = up[i, 0], up[i, 1], up[i, 2]
        d = a0 * n0 + a1 * n1 + a2 * n2
        u0, u1, u2 = a0 - d * n0, a1 - d * n1, a2 - d * n2
        ul = np.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
        if ul < 1e-9:  # up parallel to the normal: any in-plane direction will do
            if abs(n1) < 0.9:
                a0, a1, a2 = 0.0, 1.0, 0.0
            else:
                a0, a1, a2 = 1.0, 0.0, 0.0
            d = a0 * n0 + a1 * n1 + a2 * n2
            u0, u1, u2 = a0 - d * n0, a1 - d * n1, a2 - d * n2
            ul = np.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
        u0, u1, u2 = u0 / ul, u1 / ul, u2 / ul
        r0, r1, r2 = u1 * n2 - u2 * n1, u2 * n0 - u0 * n2, u0 * n1 - u1 * n0
        h = half[i]
        hr0, hr1, hr2 = h * r0, h * r1, h * r2
        hu0, hu1, hu2 = h * u0, h * u1, h * u2
        c0, c1, c2 = positions[i, 0], positions[i, 1], positions[i, 2]
        k = 4 * i
        pos[k, 0], pos[k, 1], pos[k, 2] = c0 - hr0 - hu0, c1 - hr1 - hu1, c2 - hr2 - hu2
        pos[k + 1, 0], pos[k + 1, 1], pos[k + 1, 2] = c0 + hr0 - hu0, c1 + hr1 - hu1, c2 + hr2 - hu2
        pos[k + 2, 0], pos[k + 2, 1], pos[k + 2, 2] = c0 + hr0 + hu0, c1 + hr1 + hu1, c2 + hr2 + hu2
        pos[k + 3, 0], pos[k + 3, 1], pos[k + 3, 2] = c0 - hr0 + hu0, c1 - hr1 + hu1, c2 - hr2 + hu2
        for j in range(4):
            nrm[k + j, 0], nrm[k + j, 1], nrm[k + j, 2] = n0, n1, n2
    return pos, nrm, True


@nb.njit(cache=True, nogil=True)
def prefix_rotations(q: np.ndarray, pos_in: np.ndarray, max_len: int) -> None:
    """In place: each ring's rotation becomes the product of its chain's rotations up to it.

    The segmented Hillis-Steele scan of :func:`treeform.geometry.tubes._tubes`, pass for pass
    and operation for operation (the same bits): for ``step = 1, 2, 4, ... < max_len`` every
    ring ``k`` with ``pos_in[k] >= step`` takes ``normalize(q[k] · q[k - step])`` (later rotations
    on the left) of the previous pass; going down the rings lets one array hold both passes.
    """
    step = 1
    while step < max_len:
        for k in range(q.shape[0] - 1, -1, -1):
            if pos_in[k] < step:
                continue
            aw, ax, ay, az = q[k, 0], q[k, 1], q[k, 2], q[k, 3]
            j = k - step
            bw, bx, by, bz = q[j, 0], q[j, 1], q[j, 2], q[j, 3]
            w = aw * bw - ax * bx - ay * by - az * bz
            x = aw * bx + ax * bw + ay * bz - az * by
            y = aw * by - ax * bz + ay * bw + az * bx
            z = aw * bz + ax * by - ay * bx + az * bw
            n = np.sqrt(w * w + x * x + y * y + z * z)
            q[k, 0], q[k, 1], q[k, 2], q[k, 3] = w / n, x / n, y / n, z / n
        step *= 2
