"""The 3D turtle that turns an L-system string into a TreeSkeleton and leaf cards (ABOP ch. 1.5).

The turtle carries a position and an orthonormal frame: heading H, left L, up U (``H × L = U``),
starting at the origin with H = +Y (up), L = -X, U = +Z (toward the camera). Symbols (angles in
degrees, lengths in metres):

========== ==========================================================================
``F(l)``   draw a branch segment of length ``l`` (default ``step``): a new skeleton node
``f(l)``   move ``l`` without drawing (the next node still hangs on the current one)
``@T(x,y,z)`` draw a segment to the point (heading turned onto it by the smallest rotation)
``+(a)``   turn left by ``a`` (about U); ``-(a)`` turn right
``&(a)``   pitch down by ``a`` (about L); ``^(a)`` pitch up
``\\(a)``   roll left by ``a`` (about H); ``/(a)`` roll right
``|``      turn around (180° about U)
``$``      roll so that L is horizontal
``[`` ``]`` push / pop the state; a bracket opens a branch one order higher
``!(w)``   set the branch radius to ``w`` (``!`` alone: multiply it by ``width_ratio``)
``L(s)``   a leaf card of edge ``s`` on the current node, at the tip of the turtle's heading
``%``      cut: skip the rest of the current branch (up to its ``]``)
========== ==========================================================================

After every ``F``/``@T`` the heading bends toward the tropism vector T by ``e·|H × T|``
(gravity droops branches, a negative strength raises them). Other letters are ignored.
"""

from __future__ import annotations

import math

import numpy as np

from treeform._shared.errors import InputError
from treeform.structures.foliage import Foliage
from treeform.structures.skeleton import TreeSkeleton

__all__ = ["interpret"]


def _rot(v, k, c, s):
    """Rotate 3-tuple ``v`` about unit axis ``k`` by the angle with cosine ``c``, sine ``s`` (Rodrigues)."""
    vx, vy, vz = v
    kx, ky, kz = k
    d = (kx * vx + ky * vy + kz * vz) * (1.0 - c)
    return (vx * c + (ky * vz - kz * vy) * s + kx * d,
            vy * c + (kz * vx - kx * vz) * s + ky * d,
            vz * c + (kx * vy - ky * vx) * s + kz * d)


def _norm(v):
    n = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    return (v[0] / n, v[1] / n, v[2] / n) if n > 1e-12 else v


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _turn_onto(h, l, new_h):
    """Rotate the frame (h, l) so that h becomes ``new_h`` by the smallest rotation."""
    ax = _cross(h, new_h)
    s = math.sqrt(ax[0] ** 2 + ax[1] ** 2 + ax[2] ** 2)
    c = h[0] * new_h[0] + h[1] * new_h[1] + h[2] * new_h[2]
    if s < 1e-9:
        if c > 0:
            return new_h, l
        return new_h, (-l[0], -l[1], -l[2])  # reversal: a half turn about U keeps the frame right-handed
    ax = (ax[0] / s, ax[1] / s, ax[2] / s)
    return new_h, _norm(_rot(l, ax, c, s))


def interpret(modules, *, step: float = 1.0, width: float = 0.05, width_ratio: float = 0.7,
              tropism=(0.0, -1.0, 0.0, 0.0), leaf_color=(0.24, 0.40, 0.13), origin=(0.0, 0.0, 0.0),
              return_given: bool = False):
    """Run the turtle over an L-system string.

    Parameters
    ----------
    modules : list of (name, tuple of float)
        A derived string (:meth:`LSystem.derive`).
    step : float
        Length of a bare ``F``.
    width : float
        Initial branch radius in metres.
    width_ratio : float
        Factor of a bare ``!``.
    tropism : (x, y, z, e)
        Tropism direction and strength.
    leaf_color : (3,) float in [0, 1]
        Tint of every leaf card.
    origin : (3,) float
        Start position (the skeleton's root).
    return_given : bool
        Also return which nodes were given as points (``@T``, and the root) rather than grown (``F``).

    Returns
    -------
    skeleton : TreeSkeleton
        Node 0 at ``origin``; radii from the ``!`` widths; ``order`` = bracket depth.
    foliage : Foliage
        One card per ``L``: centre half a card ahead of its node along the heading, normal U, up H.
    given : ndarray (N,) bool
        Only with ``return_given``.

    Examples
    --------
    >>> sk, fol = interpret([("F", (1.0,)), ("[", ()), ("+", (90.0,)), ("F", (1.0,)), ("L", (0.2,)),
    ...                      ("]", ()), ("F", (1.0,))])
    >>> sk.positions.round(3).tolist(), sk.parent.tolist(), sk.order.tolist(), len(fol)
    ([[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-1.0, 1.0, 0.0], [0.0, 2.0, 0.0]], [-1, 0, 1, 1], [0, 0, 1, 0], 1)
    """
    tx, ty, tz, te = (float(v) for v in tropism)
    tvec = _norm((tx, ty, tz))
    pos = tuple(float(v) for v in origin)
    h, l, u = (0.0, 1.0, 0.0), (-1.0, 0.0, 0.0), (0.0, 0.0, 1.0)
    w, node, depth = float(width), 0, 0
    P, par, R, O, GV = [pos], [-1], [w], [0], [True]
    leaves: list = []
    stack: list = []
    rad = math.pi / 180.0
    i, n = 0, len(modules)
    while i < n:
        name, p = modules[i]
        i += 1
        if name == "F" or name == "@T":
            if name == "F":
                d = float(p[0]) if p else step
                if d <= 0:
                    continue
                pos = (pos[0] + h[0] * d, pos[1] + h[1] * d, pos[2] + h[2] * d)
            else:
                if len(p) != 3:
                    raise InputError("@T: expected 3 parameters (x, y, z)")
                tgt = (float(p[0]), float(p[1]), float(p[2]))
                dv = (tgt[0] - pos[0], tgt[1] - pos[1], tgt[2] - pos[2])
                if dv[0] ** 2 + dv[1] ** 2 + dv[2] ** 2 < 1e-18:
                    continue
                h, l = _turn_onto(h, l, _norm(dv))
                u = _cross(h, l)
                pos = tgt
            P.append(pos)
            par.append(node)
            R.append(w)
            O.append(depth)
            GV.append(name == "@T")
            node = len(P) - 1
            if te != 0.0 and name == "F":
                ax = _cross(h, tvec)
                s = math.sqrt(ax[0] ** 2 + ax[1] ** 2 + ax[2] ** 2)
                if s > 1e-9:
                    ang = te * s
                    ax = (ax[0] / s, ax[1] / s, ax[2] / s)
                    c, sn = math.cos(ang), math.sin(ang)
                    h = _norm(_rot(h, ax, c, sn))
                    l = _norm(_rot(l, ax, c, sn))
                    u = _cross(h, l)
        elif name == "f":
            d = float(p[0]) if p else step
            pos = (pos[0] + h[0] * d, pos[1] + h[1] * d, pos[2] + h[2] * d)
        elif name in "+-&^/\\" and len(name) == 1:
            a = (float(p[0]) if p else 0.0) * rad
            if name in "-^/":
                a = -a
            c, sn = math.cos(a), math.sin(a)
            if name in "+-":  # about U: H toward L
                h, l = _rot(h, u, c, sn), _rot(l, u, c, sn)
            elif name in "&^":  # about L: H toward -U (down)
                h, u = _rot(h, l, c, sn), _rot(u, l, c, sn)
            else:  # about H
                l, u = _rot(l, h, c, sn), _rot(u, h, c, sn)
        elif name == "|":
            h, l = (-h[0], -h[1], -h[2]), (-l[0], -l[1], -l[2])
        elif name == "$":
            nl = _cross((0.0, 1.0, 0.0), h)
            if nl[0] ** 2 + nl[1] ** 2 + nl[2] ** 2 > 1e-12:
                l = _norm(nl)
                u = _cross(h, l)
        elif name == "[":
            stack.append((pos, h, l, u, w, node, depth))
            depth += 1
        elif name == "]":
            if not stack:
                raise InputError("L-system string: ']' without a matching '['")
            pos, h, l, u, w, node, depth = stack.pop()
        elif name == "!":
            w = float(p[0]) if p else w * width_ratio
            if w < 0:
                w = 0.0
        elif name == "L":
            s = float(p[0]) if p else step
            if s > 0:
                leaves.append((pos[0] + h[0] * s * 0.5, pos[1] + h[1] * s * 0.5, pos[2] + h[2] * s * 0.5,
                               u[0], u[1], u[2], h[0], h[1], h[2], s, node))
        elif name == "%":
            lvl = 0
            while i < n:
                nm = modules[i][0]
                if nm == "[":
                    lvl += 1
                elif nm == "]":
                    if lvl == 0:
                        break
                    lvl -= 1
                i += 1
    skeleton = TreeSkeleton(np.array(P), np.array(par, np.int64), radius=np.array(R), order=np.array(O, np.int32))
    given = np.array(GV, bool)
    if not leaves:
        return (skeleton, Foliage.empty(), given) if return_given else (skeleton, Foliage.empty())
    a = np.array(leaves, np.float64)
    col = np.tile(np.clip(np.asarray(leaf_color, np.float32), 0, 1), (len(a), 1))
    # orthonormalise (rounding drift over long strings)
    nrm = a[:, 3:6] / np.linalg.norm(a[:, 3:6], axis=1, keepdims=True)
    up = a[:, 6:9] - (a[:, 6:9] * nrm).sum(1, keepdims=True) * nrm
    up /= np.linalg.norm(up, axis=1, keepdims=True)
    foliage = Foliage(a[:, :3], nrm, up, a[:, 9], col, a[:, 10].astype(np.int64))
    return (skeleton, foliage, given) if return_given else (skeleton, foliage)
