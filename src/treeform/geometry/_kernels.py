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


@nb.njit(cache=True, nogil=True, error_model="numpy")
def _perpendicular(tx, ty, tz):
    """:func:`treeform.geometry.tubes._any_perpendicular` of one unit vector, operation for operation."""
    if abs(tx) < 0.9:
        rx, ry, rz = 1.0, 0.0, 0.0
    else:
        rx, ry, rz = 0.0, 0.0, 1.0
    s = rx * tx + ry * ty + rz * tz
    px, py, pz = rx - s * tx, ry - s * ty, rz - s * tz
    n = np.sqrt(px * px + py * py + pz * pz)
    return px / n, py / n, pz / n


@nb.njit(cache=True, nogil=True, error_model="numpy")
def tube_frames(P, r, start, lens, pos_in, min_radius):
    """Ring frames of :func:`treeform.geometry.tubes._tubes`: tangents ``T``, rotation-minimizing
    ``U``, ``V = T × U``, taper slope and ``v`` coordinate of every ring (its NumPy steps, the same
    operations in the same order, so the same bits).

    Parameters
    ----------
    P : (R, 3) float64 ring centres (chains concatenated); r : (R,) ring radii
    start, lens : (C,) int64 first ring and ring count of each chain (every count >= 2)
    pos_in : (R,) int64 index of each ring within its chain
    min_radius : float, the smallest ring radius (the v coordinate's divisor)

    Returns
    -------
    T, U, V : (R, 3) float64; slope, vcoord : (R,) float64
    """
    n = P.shape[0]
    n_chains = len(lens)
    chain_of = np.empty(n, np.int64)
    for c in range(n_chains):
        for k in range(start[c], start[c] + lens[c]):
            chain_of[k] = c
    seg = np.zeros((n, 3))
    seg_len = np.zeros(n)
    for k in range(n - 1):
        for a in range(3):
            seg[k, a] = P[k + 1, a] - P[k, a]
    for k in range(n):
        seg_len[k] = np.sqrt(seg[k, 0] * seg[k, 0] + seg[k, 1] * seg[k, 1] + seg[k, 2] * seg[k, 2])
    last = np.empty(n, np.bool_)
    for k in range(n):
        last[k] = pos_in[k] == lens[chain_of[k]] - 1
    valid = np.empty(n, np.bool_)
    D = np.zeros((n, 3))
    all_valid = True
    for k in range(n):
        valid[k] = (not last[k]) and seg_len[k] > 1e-9
        if valid[k]:
            for a in range(3):
                D[k, a] = seg[k, a] / seg_len[k]
        elif not last[k]:
            all_valid = False
    if not all_valid:  # zero-length segments take the nearest valid direction of their chain
        fwd = np.empty(n, np.int64)
        bwd = np.empty(n, np.int64)
        m = -1
        for k in range(n):
            if valid[k]:
                m = k
            fwd[k] = m
        m = n
        for k in range(n - 1, -1, -1):
            if valid[k]:
                m = k
            bwd[k] = m
        for k in range(n):
            if last[k] or valid[k]:
                continue
            src = -1
            if fwd[k] >= 0 and chain_of[fwd[k]] == chain_of[k]:
                src = fwd[k]
            elif bwd[k] < n and chain_of[bwd[k]] == chain_of[k]:
                src = bwd[k]
            if src >= 0:
                for a in range(3):
                    D[k, a] = D[src, a]
            else:
                D[k, 0], D[k, 1], D[k, 2] = 0.0, 1.0, 0.0
    T = np.empty((n, 3))
    for k in range(n):
        for a in range(3):
            if pos_in[k] == 0:
                T[k, a] = D[k, a]
            elif last[k]:
                T[k, a] = D[k - 1, a]
            else:
                T[k, a] = D[k, a] + D[k - 1, a]
        tn = np.sqrt(T[k, 0] * T[k, 0] + T[k, 1] * T[k, 1] + T[k, 2] * T[k, 2])
        if tn < 1e-6:  # a reversal: the outgoing direction
            for a in range(3):
                T[k, a] = D[k, a]
        tn = np.sqrt(T[k, 0] * T[k, 0] + T[k, 1] * T[k, 1] + T[k, 2] * T[k, 2])
        for a in range(3):
            T[k, a] = T[k, a] / tn
    # shortest-arc rotations between consecutive tangents, then their prefix products per chain
    Q = np.zeros((n, 4))
    max_len = 0
    for c in range(n_chains):
        max_len = max(max_len, lens[c])
    for k in range(n):
        if pos_in[k] == 0:
            Q[k, 0] = 1.0
            continue
        ax, ay, az = T[k - 1, 0], T[k - 1, 1], T[k - 1, 2]
        bx, by, bz = T[k, 0], T[k, 1], T[k, 2]
        d = ax * bx + ay * by + az * bz
        w = 1.0 + d
        x, y, z = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
        if w < 1e-9:  # (anti)parallel reversal: 180 degrees about any perpendicular axis
            w = 0.0
            x, y, z = _perpendicular(ax, ay, az)
        qn = np.sqrt(w * w + x * x + y * y + z * z)
        Q[k, 0], Q[k, 1], Q[k, 2], Q[k, 3] = w / qn, x / qn, y / qn, z / qn
    prefix_rotations(Q, pos_in, max_len)
    U = np.empty((n, 3))
    V = np.empty((n, 3))
    for c in range(n_chains):
        s = start[c]
        u0x, u0y, u0z = _perpendicular(T[s, 0], T[s, 1], T[s, 2])
        for k in range(s, s + lens[c]):
            w, qx, qy, qz = Q[k, 0], Q[k, 1], Q[k, 2], Q[k, 3]
            tx = 2.0 * (qy * u0z - qz * u0y)
            ty = 2.0 * (qz * u0x - qx * u0z)
            tz = 2.0 * (qx * u0y - qy * u0x)
            ux = u0x + w * tx + (qy * tz - qz * ty)
            uy = u0y + w * ty + (qz * tx - qx * tz)
            uz = u0z + w * tz + (qx * ty - qy * tx)
            dt = ux * T[k, 0] + uy * T[k, 1] + uz * T[k, 2]
            ux, uy, uz = ux - dt * T[k, 0], uy - dt * T[k, 1], uz - dt * T[k, 2]
            un = np.sqrt(ux * ux + uy * uy + uz * uz)
            ux, uy, uz = ux / un, uy / un, uz / un
            U[k, 0], U[k, 1], U[k, 2] = ux, uy, uz
            V[k, 0] = T[k, 1] * uz - T[k, 2] * uy
            V[k, 1] = T[k, 2] * ux - T[k, 0] * uz
            V[k, 2] = T[k, 0] * uy - T[k, 1] * ux
    # taper slope dr/ds (for normals) and the v coordinate (arc length over circumference)
    slope_seg = np.zeros(n)
    seg_r_mean = np.zeros(n)
    for k in range(n - 1):
        seg_r_mean[k] = 0.5 * (r[k] + r[k + 1])
        slope_seg[k] = (r[k + 1] - r[k]) / max(seg_len[k], 1e-9)
    for k in range(n):
        slope_seg[k] = min(max(slope_seg[k], -1.0), 1.0) if valid[k] else 0.0
    slope = np.empty(n)
    dv = np.empty(n)
    two_pi = 2.0 * np.pi
    for k in range(n):
        if pos_in[k] == 0:
            slope[k] = slope_seg[k]
        elif last[k]:
            slope[k] = slope_seg[k - 1]
        else:
            slope[k] = 0.5 * (slope_seg[k] + slope_seg[k - 1])
        dv[k] = seg_len[k] / (two_pi * max(seg_r_mean[k], min_radius)) if not last[k] else 0.0
    cum = np.empty(n)
    cum[0] = 0.0
    for k in range(1, n):
        cum[k] = cum[k - 1] + dv[k - 1]
    vcoord = np.empty(n)
    for k in range(n):
        vcoord[k] = cum[k] - cum[start[chain_of[k]]]
    return T, U, V, slope, vcoord


@nb.njit(cache=True, nogil=True)
def tube_geometry(P, r, T, U, V, slope, vcoord, cs, sn, start, lens, capped):
    """Vertices and faces of :func:`treeform.geometry.tubes._tubes` from its ring frames
    (:func:`tube_frames`), laid out as it lays them out: every ring's ``S + 1`` vertices, one
    cone apex per chain, then a fan (ring copy + centre) per capped chain; faces ring by ring
    ([fan S]? then 2S sides, or the S cone triangles on a chain's last ring).

    ``cs``, ``sn``: the (S + 1) cosines and sines round a ring (the seam repeating the first).

    Returns
    -------
    positions, normals : (V, 3) float32; uvs : (V, 2) float32; faces : (F, 3) uint32
    """
    n = P.shape[0]
    n_chains = len(lens)
    segs = len(cs) - 1
    m = segs + 1
    n_caps = 0
    for c in range(n_chains):
        if capped[c]:
            n_caps += 1
    nv = n * m + n_chains + n_caps * (segs + 2)
    pos = np.empty((nv, 3), np.float32)  # each value rounded once, as NumPy's astype rounds it
    nrm = np.empty((nv, 3), np.float32)
    uv = np.empty((nv, 2), np.float32)
    for k in range(n):
        den = np.sqrt(1.0 + slope[k] * slope[k])
        for j in range(m):
            v = k * m + j
            for a in range(3):
                radial = cs[j] * U[k, a] + sn[j] * V[k, a]
                pos[v, a] = P[k, a] + r[k] * radial
                nrm[v, a] = (radial - slope[k] * T[k, a]) / den
            uv[v, 0] = j / segs
            uv[v, 1] = vcoord[k]
    apex_base = n * m
    two_pi = 2.0 * np.pi
    for c in range(n_chains):
        t = start[c] + lens[c] - 1
        h = 0.5 * r[t]
        v = apex_base + c
        for a in range(3):
            pos[v, a] = P[t, a] + h * T[t, a]
            nrm[v, a] = T[t, a]
        uv[v, 0] = 0.5
        uv[v, 1] = vcoord[t] + h / (two_pi * r[t])
    cap_base = apex_base + n_chains
    cap_of_ring = np.full(n, -1, np.int64)
    i = 0
    for c in range(n_chains):
        if not capped[c]:
            continue
        s = start[c]
        cap_of_ring[s] = i
        b = cap_base + i * (segs + 2)
        for j in range(segs + 2):
            for a in range(3):
                pos[b + j, a] = pos[s * m + j, a] if j < m else P[s, a]
                nrm[b + j, a] = -T[s, a]
            if j < m:
                uv[b + j, 0] = 0.5 + 0.5 * cs[j]
                uv[b + j, 1] = 0.5 + 0.5 * sn[j]
            else:
                uv[b + j, 0] = 0.5
                uv[b + j, 1] = 0.5
        i += 1
    n_faces = 0
    for c in range(n_chains):
        n_faces += 2 * segs * (lens[c] - 1) + segs + (segs if capped[c] else 0)
    faces = np.empty((n_faces, 3), np.uint32)
    f = 0
    for c in range(n_chains):
        for k in range(start[c], start[c] + lens[c]):
            if cap_of_ring[k] >= 0:
                b = cap_base + cap_of_ring[k] * (segs + 2)
                centre = b + segs + 1
                for j in range(segs):
                    faces[f, 0], faces[f, 1], faces[f, 2] = centre, b + j + 1, b + j
                    f += 1
            if k < start[c] + lens[c] - 1:
                for j in range(segs):
                    a0 = k * m + j
                    faces[f, 0], faces[f, 1], faces[f, 2] = a0, a0 + 1, a0 + m
                    faces[f + 1, 0], faces[f + 1, 1], faces[f + 1, 2] = a0 + 1, a0 + m + 1, a0 + m
                    f += 2
            else:
                for j in range(segs):
                    a0 = k * m + j
                    faces[f, 0], faces[f, 1], faces[f, 2] = a0, a0 + 1, apex_base + c
                    f += 1
    return pos, nrm, uv, faces


@nb.njit(cache=True, nogil=True)
def chain_max_radius(flat, lens, radius):
    """(C,) largest radius of each chain's own nodes (a side chain's first node is its parent's),
    -inf for a chain without one: :func:`treeform.geometry.tubes._chain_measure_flat`."""
    out = np.empty(len(lens))
    k = 0
    for c in range(len(lens)):
        m = -np.inf
        first = k + 1 if (c > 0 and lens[c] >= 2) else k
        for i in range(first, k + lens[c]):
            m = max(m, radius[flat[i]])
        out[c] = m
        k += lens[c]
    return out
