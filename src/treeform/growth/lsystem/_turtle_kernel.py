"""The 3D turtle compiled (numba): :func:`treeform.growth.lsystem.turtle.interpret` on an
encoded string (one op code and first parameter per module, the ``@T`` points apart).

The same arithmetic in the same order as the module-by-module Python loop it replaced (positions
agree with it to an ulp or two, where the compiled sine and cosine round differently); what goes
is the per-module interpreter overhead: a dressed candidate of seed 004's search is 100-200
thousand modules, 3-4x faster to interpret with the encoding.
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

# op codes of encode(); 0 = a letter the turtle ignores
OPS = {"F": 1, "@T": 2, "f": 3, "+": 4, "-": 5, "&": 6, "^": 7, "/": 8, "\\": 9, "|": 10, "$": 11,
       "[": 12, "]": 13, "!": 14, "L": 15, "%": 16}

UNMATCHED = 1
"""Error code: a ``]`` without its ``[``."""


@nb.njit(cache=True, nogil=True)
def _rot(v0, v1, v2, k0, k1, k2, c, s):
    d = (k0 * v0 + k1 * v1 + k2 * v2) * (1.0 - c)
    return (v0 * c + (k1 * v2 - k2 * v1) * s + k0 * d,
            v1 * c + (k2 * v0 - k0 * v2) * s + k1 * d,
            v2 * c + (k0 * v1 - k1 * v0) * s + k2 * d)


@nb.njit(cache=True, nogil=True)
def _norm(v0, v1, v2):
    n = math.sqrt(v0 * v0 + v1 * v1 + v2 * v2)
    if n > 1e-12:
        return v0 / n, v1 / n, v2 / n
    return v0, v1, v2


@nb.njit(cache=True, nogil=True)
def _cross(a0, a1, a2, b0, b1, b2):
    return a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0


@nb.njit(cache=True, nogil=True)
def run_turtle(ops, p0, has_p, targets, step, width, width_ratio, tvec, te, origin):
    """Interpret an encoded string.

    Returns ``(P (m, 3), parent (m,), radius (m,), order (m,), given (m,), leaves (k, 11), error)``;
    a leaf row is centre (3), normal U (3), up H (3), size, node; ``error`` 0 or :data:`UNMATCHED`.
    """
    n = len(ops)
    n_nodes, n_leaves, n_push = 1, 0, 0
    for i in range(n):
        o = ops[i]
        if o == 1 or o == 2:
            n_nodes += 1
        elif o == 15:
            n_leaves += 1
        elif o == 12:
            n_push += 1
    P = np.empty((n_nodes, 3))
    par = np.empty(n_nodes, np.int64)
    R = np.empty(n_nodes)
    O = np.empty(n_nodes, np.int32)
    GV = np.empty(n_nodes, np.bool_)
    leaves = np.empty((n_leaves, 11))
    sf = np.empty((n_push, 13))  # the stack: pos, h, l, u, w
    si = np.empty((n_push, 2), np.int64)  # node, depth
    t0, t1, t2 = tvec[0], tvec[1], tvec[2]
    x, y, z = origin[0], origin[1], origin[2]
    h0, h1, h2 = 0.0, 1.0, 0.0
    l0, l1, l2 = -1.0, 0.0, 0.0
    u0, u1, u2 = 0.0, 0.0, 1.0
    w = width
    node, depth, m, k, sp, nt = 0, 0, 1, 0, 0, 0
    P[0, 0], P[0, 1], P[0, 2] = x, y, z
    par[0], R[0], O[0], GV[0] = -1, w, 0, True
    rad = math.pi / 180.0
    i = 0
    while i < n:
        o = ops[i]
        p = p0[i]
        hp = has_p[i]
        i += 1
        if o == 1 or o == 2:
            if o == 1:
                d = p if hp else step
                if d <= 0:
                    continue
                x, y, z = x + h0 * d, y + h1 * d, z + h2 * d
            else:
                g0, g1, g2 = targets[nt, 0], targets[nt, 1], targets[nt, 2]
                nt += 1
                d0, d1, d2 = g0 - x, g1 - y, g2 - z
                if d0 ** 2 + d1 ** 2 + d2 ** 2 < 1e-18:
                    continue
                e0, e1, e2 = _norm(d0, d1, d2)
                # the frame turned so that H becomes e by the smallest rotation
                a0, a1, a2 = _cross(h0, h1, h2, e0, e1, e2)
                s = math.sqrt(a0 ** 2 + a1 ** 2 + a2 ** 2)
                c = h0 * e0 + h1 * e1 + h2 * e2
                if s < 1e-9:
                    if not c > 0:
                        l0, l1, l2 = -l0, -l1, -l2
                else:
                    a0, a1, a2 = a0 / s, a1 / s, a2 / s
                    r0, r1, r2 = _rot(l0, l1, l2, a0, a1, a2, c, s)
                    l0, l1, l2 = _norm(r0, r1, r2)
                h0, h1, h2 = e0, e1, e2
                u0, u1, u2 = _cross(h0, h1, h2, l0, l1, l2)
                x, y, z = g0, g1, g2
            P[m, 0], P[m, 1], P[m, 2] = x, y, z
            par[m], R[m], O[m], GV[m] = node, w, depth, o == 2
            node = m
            m += 1
            if te != 0.0 and o == 1:
                a0, a1, a2 = _cross(h0, h1, h2, t0, t1, t2)
                s = math.sqrt(a0 ** 2 + a1 ** 2 + a2 ** 2)
                if s > 1e-9:
                    ang = te * s
                    a0, a1, a2 = a0 / s, a1 / s, a2 / s
                    c, sn = math.cos(ang), math.sin(ang)
                    r0, r1, r2 = _rot(h0, h1, h2, a0, a1, a2, c, sn)
                    q0, q1, q2 = _rot(l0, l1, l2, a0, a1, a2, c, sn)
                    h0, h1, h2 = _norm(r0, r1, r2)
                    l0, l1, l2 = _norm(q0, q1, q2)
                    u0, u1, u2 = _cross(h0, h1, h2, l0, l1, l2)
        elif o == 3:
            d = p if hp else step
            x, y, z = x + h0 * d, y + h1 * d, z + h2 * d
        elif 4 <= o <= 9:
            a = (p if hp else 0.0) * rad
            if o == 5 or o == 7 or o == 8:
                a = -a
            c, sn = math.cos(a), math.sin(a)
            if o <= 5:  # about U: H toward L
                r0, r1, r2 = _rot(h0, h1, h2, u0, u1, u2, c, sn)
                l0, l1, l2 = _rot(l0, l1, l2, u0, u1, u2, c, sn)
                h0, h1, h2 = r0, r1, r2
            elif o <= 7:  # about L: H toward -U (down)
                r0, r1, r2 = _rot(h0, h1, h2, l0, l1, l2, c, sn)
                u0, u1, u2 = _rot(u0, u1, u2, l0, l1, l2, c, sn)
                h0, h1, h2 = r0, r1, r2
            else:  # about H
                r0, r1, r2 = _rot(l0, l1, l2, h0, h1, h2, c, sn)
                u0, u1, u2 = _rot(u0, u1, u2, h0, h1, h2, c, sn)
                l0, l1, l2 = r0, r1, r2
        elif o == 10:
            h0, h1, h2 = -h0, -h1, -h2
            l0, l1, l2 = -l0, -l1, -l2
        elif o == 11:
            n0, n1, n2 = _cross(0.0, 1.0, 0.0, h0, h1, h2)
            if n0 ** 2 + n1 ** 2 + n2 ** 2 > 1e-12:
                l0, l1, l2 = _norm(n0, n1, n2)
                u0, u1, u2 = _cross(h0, h1, h2, l0, l1, l2)
        elif o == 12:
            sf[sp, 0], sf[sp, 1], sf[sp, 2] = x, y, z
            sf[sp, 3], sf[sp, 4], sf[sp, 5] = h0, h1, h2
            sf[sp, 6], sf[sp, 7], sf[sp, 8] = l0, l1, l2
            sf[sp, 9], sf[sp, 10], sf[sp, 11] = u0, u1, u2
            sf[sp, 12] = w
            si[sp, 0], si[sp, 1] = node, depth
            sp += 1
            depth += 1
        elif o == 13:
            if sp == 0:
                return P[:m], par[:m], R[:m], O[:m], GV[:m], leaves[:k], UNMATCHED
            sp -= 1
            x, y, z = sf[sp, 0], sf[sp, 1], sf[sp, 2]
            h0, h1, h2 = sf[sp, 3], sf[sp, 4], sf[sp, 5]
            l0, l1, l2 = sf[sp, 6], sf[sp, 7], sf[sp, 8]
            u0, u1, u2 = sf[sp, 9], sf[sp, 10], sf[sp, 11]
            w = sf[sp, 12]
            node, depth = si[sp, 0], si[sp, 1]
        elif o == 14:
            w = p if hp else w * width_ratio
            if w < 0:
                w = 0.0
        elif o == 15:
            s = p if hp else step
            if s > 0:
                leaves[k, 0] = x + h0 * s * 0.5
                leaves[k, 1] = y + h1 * s * 0.5
                leaves[k, 2] = z + h2 * s * 0.5
                leaves[k, 3], leaves[k, 4], leaves[k, 5] = u0, u1, u2
                leaves[k, 6], leaves[k, 7], leaves[k, 8] = h0, h1, h2
                leaves[k, 9], leaves[k, 10] = s, node
                k += 1
        elif o == 16:
            lvl = 0
            while i < n:
                if ops[i] == 12:
                    lvl += 1
                elif ops[i] == 13:
                    if lvl == 0:
                        break
                    lvl -= 1
                elif ops[i] == 2:  # a skipped @T's point is not used
                    nt += 1
                i += 1
    return P[:m], par[:m], R[:m], O[:m], GV[:m], leaves[:k], 0
