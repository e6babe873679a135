"""Trees from the L-system: a whole tree from a preset's axiom, or a given skeleton dressed by it.

:func:`dress_skeleton` is the generative model of seed 004 §4 constrained by the image: the
main branches come from the photo's foliage skeleton (§3), written into the axiom as ``@T``
segments, and along them the preset's ``N(r, o)`` rules grow the twigs and leaves that fill the
foliage of radius ``r`` around each branch.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from treeform._shared.errors import InputError
from treeform.growth.lsystem.grammar import LSystem, load_preset
from treeform.growth.lsystem.turtle import interpret
from treeform.structures.foliage import Foliage
from treeform.structures.skeleton import TreeSkeleton

__all__ = ["LSystemTree", "lsystem_tree", "dress_skeleton"]


@dataclass
class LSystemTree:
    """A tree grown by an L-system: skeleton, leaf cards, the size of the derived string and
    which nodes were given (``@T`` points, e.g. a photo's main branches) rather than grown."""

    skeleton: TreeSkeleton
    foliage: Foliage
    modules: int
    preset: str
    given: np.ndarray


def _grammar(preset, defines) -> LSystem:
    if isinstance(preset, LSystem):
        return preset.with_defines(defines)
    return load_preset(preset, defines=defines)


def _leaf_color(ls: LSystem):
    from treeform.growth.species import SPECIES, load_species_appearance

    if ls.name in SPECIES:
        return tuple(load_species_appearance(ls.name).leaf_color)
    return (0.24, 0.40, 0.13)


def _finish(ls: LSystem, modules: list, *, seed, origin=(0.0, 0.0, 0.0), trunk_radius=None) -> LSystemTree:
    """Turtle, then pipe-model radii (``tip_radius``, ``pipe_exponent`` defines, if any); with
    ``trunk_radius`` the radii scale toward it by their share of the root's (``r·(1 + (k-1)·r/r0)``,
    ``k = trunk_radius / r0``): the trunk takes the measured radius, twigs keep theirs."""
    from treeform.growth.radii import pipe_model_radii

    skel, fol, given = interpret(modules, step=ls.defines.get("step", 1.0), tropism=ls.tropism,
                                 leaf_color=_leaf_color(ls), origin=origin, return_given=True)
    tip = ls.defines.get("tip_radius", 0.004)
    radius = pipe_model_radii(skel.parent, tip_radius=tip, exponent=ls.defines.get("pipe_exponent", 2.3))
    if trunk_radius is not None and radius[0] > 0:
        k = float(trunk_radius) / radius[0]
        radius = radius * (1.0 + (k - 1.0) * radius / radius[0])
    skel = TreeSkeleton(skel.positions, skel.parent, radius=radius, order=skel.order,
                        meta={"generator": "lsystem", "preset": ls.name, "modules": len(modules),
                              "seed": seed if isinstance(seed, (int, np.integer)) else None})
    return LSystemTree(skel, fol, len(modules), ls.name, given)


def lsystem_tree(preset="generic", *, seed=0, defines: dict | None = None, derivations: int | None = None) -> LSystemTree:
    """Grow a whole tree from a preset's own axiom (the generative model alone, seed 004 §4).

    Parameters
    ----------
    preset : str, path to a .lsys file, or LSystem
        A species (``oak``, ``pine``, ...), ``generic`` or a grammar of one's own.
    seed : int
    defines : dict, optional
        Overrides of the preset's ``define`` values (e.g. ``{"height": 14, "density": 1.5}``).
    derivations : int, optional
        Rewriting steps (default: the grammar's).

    Returns
    -------
    LSystemTree
        Radii by the pipe model from the tips (the grammar's ``!`` widths are not used).

    Examples
    --------
    >>> t = lsystem_tree("oak", seed=1)
    >>> t.skeleton.n_nodes > 100 and len(t.foliage) > 100
    True
    """
    ls = _grammar(preset, defines)
    return _finish(ls, ls.derive(steps=derivations, seed=seed), seed=seed)


def _check_polylines(polylines, foliage_radius):
    if not isinstance(polylines, (list, tuple)) or not polylines:
        raise InputError("polylines: expected a non-empty list of (K, 3) arrays")
    polys, radii = [], []
    if not isinstance(foliage_radius, (list, tuple)) or len(foliage_radius) != len(polylines):
        raise InputError("foliage_radius: expected one (K,) array per polyline")
    for i, (p, r) in enumerate(zip(polylines, foliage_radius)):
        p = np.asarray(p, np.float64)
        r = np.asarray(r, np.float64).reshape(-1)
        if p.ndim != 2 or p.shape[1] != 3 or len(p) < 2 or not np.all(np.isfinite(p)):
            raise InputError(f"polylines[{i}]: expected a finite (K>=2, 3) array, got shape {p.shape}")
        if len(r) != len(p) or not np.all(np.isfinite(r)) or np.any(r < 0):
            raise InputError(f"foliage_radius[{i}]: expected {len(p)} finite values >= 0")
        polys.append(p)
        radii.append(r)
    return polys, radii


def _attachments(polys, parent):
    """Parent branch and the parent's point index where each branch starts."""
    B = len(polys)
    if parent is None:
        parent = [-1] + [0] * (B - 1)
        for i in range(1, B):
            best = (np.inf, 0)
            for j in range(i):
                d = float(((polys[j] - polys[i][0]) ** 2).sum(1).min())
                best = min(best, (d, j))
            parent[i] = best[1]
    parent = np.asarray(parent, np.int64).reshape(-1)
    if len(parent) != B or parent[0] != -1 or np.any(parent[1:] < 0) or np.any(parent[1:] >= np.arange(1, B)):
        raise InputError("parent: expected -1 for the first polyline and an earlier polyline's index for each other")
    at = np.zeros(B, np.int64)
    for i in range(1, B):
        at[i] = int(np.argmin(((polys[parent[i]] - polys[i][0]) ** 2).sum(1)))
    return parent, at


def dress_skeleton(polylines, foliage_radius, *, parent=None, preset="generic", seed=0,
                   defines: dict | None = None, trunk_radius: float | None = None) -> LSystemTree:
    """Dress given main branches with the preset's twigs and leaves (seed 004 §4 on a §3 skeleton).

    Parameters
    ----------
    polylines : list of ndarray, each (K_i >= 2, 3)
        Main branches in metres (e.g. :func:`treeform.skeleton.lift_to_3d`); the first is the
        trunk and starts at the root.
    foliage_radius : list of ndarray, each (K_i,)
        Radius of the foliage around each branch point in metres (0: bare wood).
    parent : array-like (B,), optional
        Each branch's parent branch (-1 for the trunk); None: the earlier branch nearest to its start.
    preset : str, path or LSystem
        Must define ``leaf_size`` and ``density`` and rewrite ``N(r, o)``.
    seed : int
    defines : dict, optional
        Overrides, e.g. ``{"density": 1.6, "spread": 0.8, "leaf_size": 0.3}``.
    trunk_radius : float, optional
        Radius of the trunk at the root in metres (e.g. measured in a photo); the pipe-model
        radii are scaled toward it, the more the thicker they are.

    Returns
    -------
    LSystemTree
        The main branches (every polyline point a node, bracket depth = order) carrying the
        grown twigs; leaf cards as the rules put them.

    Notes
    -----
    The axiom is the skeleton written as turtle commands: each branch a bracketed run of
    ``@T(x, y, z)`` at its points, a child branch opened at its parent's nearest point, and a
    dressing module ``N(r, o)`` every ``leaf_size / density`` metres where the foliage radius
    ``r`` is positive. The preset's rules rewrite ``N`` for its ``derivations`` steps.

    Examples
    --------
    >>> trunk = np.array([[0, 0, 0], [0, 3, 0], [0, 6, 0.]])
    >>> t = dress_skeleton([trunk], [np.array([0, 1.5, 1.0])], seed=0)
    >>> d = np.linalg.norm(t.skeleton.positions[None] - trunk[:, None], axis=2).min(1)
    >>> bool(np.all(d < 1e-9)), len(t.foliage) > 10
    (True, True)
    """
    polys, radii = _check_polylines(polylines, foliage_radius)
    parent, at = _attachments(polys, parent)
    ls = _grammar(preset, defines)
    for need in ("leaf_size", "density"):
        if need not in ls.defines:
            raise InputError(f"L-system {ls.name}: a dressing preset must define {need!r}")
    if ("N", 2) not in ls.rules:
        raise InputError(f"L-system {ls.name}: a dressing preset must rewrite N(r, o)")
    spacing = ls.defines["leaf_size"] / max(ls.defines["density"], 1e-3)
    children: dict = {}
    for i in range(1, len(polys)):
        children.setdefault((int(parent[i]), int(at[i])), []).append(i)
    origin = polys[0][0]
    axiom: list = []

    def emit(b: int, depth: int):
        P, R = polys[b], radii[b]
        start = 0 if b == 0 else 1
        if b != 0 and np.linalg.norm(P[0] - polys[parent[b]][at[b]]) > 1e-6:
            axiom.append(("@T", tuple(P[0])))
        carry = 0.0  # arc length since the last dressing module
        for k in range(start, len(P)):
            if k > 0:
                seg = P[k] - P[k - 1]
                L = float(np.linalg.norm(seg))
                t = spacing - carry
                while t < L:  # dressing modules along the segment, every `spacing` metres
                    axiom.append(("@T", tuple(P[k - 1] + seg * (t / L))))
                    r = float(R[k - 1] + (R[k] - R[k - 1]) * (t / L))
                    if r > 0:
                        axiom.append(("N", (r, float(depth))))
                    t += spacing
                carry = L - (t - spacing)
                axiom.append(("@T", tuple(P[k])))
            for c in children.get((b, k), ()):
                axiom.append(("[", ()))
                emit(c, depth + 1)
                axiom.append(("]", ()))

    emit(0, 0)
    modules = ls.derive(axiom, seed=seed)
    if trunk_radius is not None and (not np.isfinite(trunk_radius) or trunk_radius <= 0):
        raise InputError(f"trunk_radius: expected a positive number of metres, got {trunk_radius!r}")
    return _finish(ls, modules, seed=seed, origin=tuple(origin), trunk_radius=trunk_radius)
