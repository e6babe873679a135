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

__all__ = ["interpret", "encode"]


def _norm(v):
    n = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    return (v[0] / n, v[1] / n, v[2] / n) if n > 1e-12 else v


def encode(modules):
    """A string of modules as the compiled turtle reads it: op codes (int8), first parameters,
    whether there is one, and the ``@T`` points in order (k, 3).

    Examples
    --------
    >>> ops, p0, has_p, pts = encode([("F", (2.0,)), ("+", ()), ("@T", (1, 2, 3)), ("X", (5.0,))])
    >>> ops.tolist(), p0.tolist(), has_p.tolist(), pts.tolist()
    ([1, 4, 2, 0], [2.0, 0.0, 1.0, 5.0], [True, False, True, True], [[1.0, 2.0, 3.0]])
    """
    from treeform.growth.lsystem._turtle_kernel import OPS

    get = OPS.get
    params = [m[1] for m in modules]
    ops = np.array([get(m[0], 0) for m in modules], np.int8)
    has_p = np.array([len(p) > 0 for p in params], bool)
    p0 = np.array([float(p[0]) if p else 0.0 for p in params], np.float64)
    at = np.flatnonzero(ops == 2)
    if any(len(params[i]) != 3 for i in at):
        raise InputError("@T: expected 3 parameters (x, y, z)")
    targets = np.array([params[i] for i in at], np.float64).reshape(-1, 3)
    return ops, p0, has_p, targets


def _announce_compile():
    import logging

    from treeform._shared.jit import announce_compile
    from treeform.growth.lsystem import _turtle_kernel

    announce_compile(logging.getLogger(__name__), "the L-system turtle", 3, _turtle_kernel.__file__,
                     names={"run_turtle"})


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
    from treeform.growth.lsystem._turtle_kernel import UNMATCHED, run_turtle

    tx, ty, tz, te = (float(v) for v in tropism)
    ops, p0, has_p, targets = encode(modules)
    _announce_compile()
    P, par, R, O, given, a, err = run_turtle(ops, p0, has_p, targets, float(step), float(width), float(width_ratio),
                                             np.array(_norm((tx, ty, tz)), np.float64), te,
                                             np.array([float(v) for v in origin], np.float64))
    if err == UNMATCHED:
        raise InputError("L-system string: ']' without a matching '['")
    skeleton = TreeSkeleton(P, par, radius=R, order=O)
    if not len(a):
        return (skeleton, Foliage.empty(), given) if return_given else (skeleton, Foliage.empty())
    col = np.tile(np.clip(np.asarray(leaf_color, np.float32), 0, 1), (len(a), 1))
    # orthonormalise (rounding drift over long strings)
    nrm = a[:, 3:6] / np.linalg.norm(a[:, 3:6], axis=1, keepdims=True)
    up = a[:, 6:9] - (a[:, 6:9] * nrm).sum(1, keepdims=True) * nrm
    up /= np.linalg.norm(up, axis=1, keepdims=True)
    foliage = Foliage(a[:, :3], nrm, up, a[:, 9], col, a[:, 10].astype(np.int64))
    return (skeleton, foliage, given) if return_given else (skeleton, foliage)
