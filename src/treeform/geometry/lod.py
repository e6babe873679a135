"""A whole tree mesh (bark + leaf cards) under a triangle budget: the level of detail."""

from __future__ import annotations

import numpy as np

from treeform._shared.errors import InputError
from treeform._shared.rng import as_rng
from treeform.geometry import leaves as _leaves
from treeform.geometry import tubes as _tubes
from treeform.structures.foliage import Foliage
from treeform.structures.mesh import Mesh
from treeform.structures.skeleton import TreeSkeleton

__all__ = ["LOD_PRESETS", "MIN_RADIAL_SEGMENTS", "foliage_budget", "plan_lod", "tree_mesh"]

LOD_PRESETS = {"low": 20_000, "medium": 60_000, "high": 200_000, "full": None}
"""Named ``max_triangles`` budgets for :func:`tree_mesh` (``None``: no limit)."""

MIN_RADIAL_SEGMENTS = 3

BRANCH_SHARE = 0.35
"""When leaves must be thinned too, branches keep at most this share of the budget
(or whatever the full foliage leaves over, if that is more)."""


def _chain_units(lens: np.ndarray, root_flags: np.ndarray) -> np.ndarray:
    """Triangles per radial segment of each chain (see :func:`tubes.tube_triangle_count`)."""
    return np.where(lens >= 2, 2 * (lens - 1) + 1 + root_flags.astype(np.int64), 0)


def plan_lod(chain_lengths, chain_radius, n_leaves: int, *, max_triangles=None, radial_segments: int = 8,
             seed=0) -> dict:
    """Decide how to fit a tree into ``max_triangles``.

    In order, only as far as needed: (1) lower the radial segments, down to 3; (2) drop the
    thinnest chains (by their largest own radius) until the branches fit their allowance,
    ``max(budget - 2·M, BRANCH_SHARE·budget)``; (3) keep a deterministic random subset of
    the leaves (enlarged by ``sqrt(M / M_kept)`` so the crown's coverage stays similar).

    Parameters
    ----------
    chain_lengths : array_like of int, shape (C,)
        Nodes per chain, in :meth:`TreeSkeleton.chains` order (chain 0 starts at the root).
    chain_radius : array_like of float, shape (C,)
        Thickness of each chain (the largest radius of its own nodes).
    n_leaves : int
        ``M``.
    max_triangles : int or None
    radial_segments : int
    seed : int or numpy.random.Generator
        Selects the leaf subset.

    Returns
    -------
    dict
        ``radial_segments`` (int), ``keep_chains`` (C,) bool, ``keep_leaves`` (M,) bool,
        ``leaf_scale`` (float), ``branch_triangles`` and ``leaf_triangles`` (int).
    """
    plan = _plan(chain_lengths, chain_radius, n_leaves, max_triangles, radial_segments)
    m_keep = plan.pop("m_keep")
    keep_leaves = np.ones(n_leaves, bool)
    if m_keep < n_leaves:  # (3) a deterministic random subset of the leaves, enlarged
        keep_leaves[:] = False
        if m_keep:
            keep_leaves[np.sort(as_rng(seed).permutation(n_leaves)[:m_keep])] = True
            plan["leaf_scale"] = float(np.sqrt(n_leaves / m_keep))
    plan["keep_leaves"] = keep_leaves
    return plan


def _plan(chain_lengths, chain_radius, n_leaves: int, max_triangles, radial_segments: int) -> dict:
    """:func:`plan_lod` up to the choice of the kept leaves: their number is ``m_keep``; no ``keep_leaves``."""
    lens = np.asarray(chain_lengths, np.int64).reshape(-1)
    rad = np.asarray(chain_radius, np.float64).reshape(-1)
    n_chains = len(lens)
    root = np.arange(n_chains) == 0
    units = _chain_units(lens, root)
    segs = int(radial_segments)
    keep_chains = np.ones(n_chains, bool)
    plan = {"radial_segments": segs, "keep_chains": keep_chains, "leaf_scale": 1.0, "m_keep": int(n_leaves)}
    total_units = int(units.sum())
    leaf_tris = 2 * n_leaves
    if max_triangles is None or segs * total_units + leaf_tris <= max_triangles:
        plan.update(branch_triangles=segs * total_units, leaf_triangles=leaf_tris)
        return plan
    budget = int(max_triangles)
    # (1) fewer sides per ring
    if total_units:
        fit = (budget - leaf_tris) // total_units
        segs = int(np.clip(fit, MIN_RADIAL_SEGMENTS, segs))
    plan["radial_segments"] = segs
    if segs * total_units + leaf_tris <= budget:
        plan.update(branch_triangles=segs * total_units, leaf_triangles=leaf_tris)
        return plan
    # (2) drop the thinnest chains until the branches fit their allowance
    allowance = max(budget - leaf_tris, int(BRANCH_SHARE * budget))
    order = np.lexsort((-np.arange(n_chains), rad))  # thinnest first; later chains first on ties
    order = order[~root[order]]  # the trunk goes last
    order = np.concatenate([order, np.flatnonzero(root)])
    dropped = np.cumsum(units[order])  # units removed after dropping order[:k+1]
    need = segs * total_units - allowance
    if need > 0:
        k = int(np.searchsorted(segs * dropped, need)) + 1  # smallest k with segs*dropped[k-1] >= need
        keep_chains[order[:k]] = False
    branch_tris = segs * int(units[keep_chains].sum())
    # (3) the leaves that fit into what is left
    m_keep = int(min(n_leaves, max(budget - branch_tris, 0) // 2))
    plan.update(branch_triangles=branch_tris, leaf_triangles=2 * m_keep, m_keep=m_keep)
    return plan


def foliage_budget(skeleton: TreeSkeleton, n_leaves: int, *, max_triangles, radial_segments: int = 8) -> tuple[int, float]:
    """How many leaf clusters a triangle budget keeps, and how much to enlarge them: don't build what the LOD drops.

    :func:`tree_mesh` with ``max_triangles`` keeps ``M_kept`` of ``M`` leaves (:func:`plan_lod`)
    and enlarges them by ``sqrt(M / M_kept)``. Generating only ``M_kept`` clusters of that
    size in the first place gives the same crown coverage for a fraction of the work, and
    :func:`tree_mesh` with the same budget then keeps every one of them (``M_kept`` is
    lowered until it does).

    Parameters
    ----------
    skeleton : TreeSkeleton
    n_leaves : int
        ``M``, the leaf clusters of the full-detail tree.
    max_triangles : int or None
        The budget :func:`tree_mesh` will get (None: no limit).
    radial_segments : int
        As for :func:`tree_mesh`.

    Returns
    -------
    n_kept : int
        ``M_kept`` (``M`` when everything fits, 0 when no leaf does).
    size_factor : float
        ``sqrt(M / M_kept)``; 1.0 when nothing is dropped or nothing kept.

    Examples
    --------
    >>> s = TreeSkeleton(np.array([[0, 0, 0], [0, 1, 0.]]), np.array([-1, 0]), np.array([0.1, 0.05]))
    >>> n, factor = foliage_budget(s, 100, max_triangles=100)
    >>> n, round(factor, 4), foliage_budget(s, 100, max_triangles=None)
    (44, 1.5076, (100, 1.0))
    """
    if not isinstance(skeleton, TreeSkeleton):
        raise InputError(f"skeleton: expected a TreeSkeleton, got {type(skeleton).__name__}")
    if isinstance(n_leaves, bool) or not isinstance(n_leaves, (int, np.integer)) or n_leaves < 0:
        raise InputError(f"n_leaves: expected a non-negative integer, got {n_leaves!r}")
    _check_budget(max_triangles)
    segs = _tubes._check_segments(radial_segments)
    n = int(n_leaves)
    if max_triangles is None or n == 0:
        return n, 1.0
    nodes, lens = _tubes._chain_arrays(skeleton)
    rad = _tubes._chain_measure_flat(skeleton, nodes, lens)
    m = _plan(lens, rad, n, max_triangles, segs)["m_keep"]
    while 0 < m < n:  # fewer leaves can leave the branches more room; take as many as then fit
        fit = _plan(lens, rad, m, max_triangles, segs)["m_keep"]
        if fit == m:
            break
        m = fit
    return m, (float(np.sqrt(n / m)) if 0 < m < n else 1.0)


def _check_budget(max_triangles) -> None:
    if max_triangles is not None:
        if isinstance(max_triangles, bool) or not isinstance(max_triangles, (int, np.integer)) or max_triangles < 0:
            raise InputError(f"max_triangles: expected a non-negative integer or None, got {max_triangles!r}")


def tree_mesh(skeleton: TreeSkeleton, foliage: Foliage | None, *, max_triangles=None, radial_segments: int = 8,
              leaf_texture=None, bark_texture=None, bark_normal=None, seed=0) -> Mesh:
    """The tree as a :class:`Mesh`: a ``"bark"`` part (tubes) and a ``"leaves"`` part (cards).

    With ``max_triangles`` the total triangle count is guaranteed not to exceed it; when the
    full tree is over budget, :func:`plan_lod` first lowers the radial segments (down to 3),
    then drops the thinnest branch chains, then keeps a deterministic subset of the leaves,
    enlarging the kept cards by ``sqrt(M / M_kept)`` so the crown looks about as dense.
    Named budgets: :data:`LOD_PRESETS`. Parts with no triangles are left out.

    Parameters
    ----------
    skeleton : TreeSkeleton
        N nodes.
    foliage : Foliage or None
        M leaves (None: none).
    max_triangles : int or None
        Triangle budget (>= 0); None: no limit.
    radial_segments : int
        Sides per branch ring at full detail (>= 3).
    leaf_texture : ndarray, shape (H, W, 4), uint8, optional
        Default ``leaf_texture(256, seed=seed, kind="cluster")``.
    bark_texture : ndarray, shape (H, W, 4), uint8, optional
        Default ``bark_texture(512, seed=0)``; :func:`~treeform.geometry.tree_textures` sizes
        both textures for a tree.
    bark_normal : ndarray, shape (H, W, 4), uint8, optional
        Normal map of ``bark_texture`` (:func:`~treeform.geometry.textures.bark_normals`); the
        default texture brings its own.
    seed : int or numpy.random.Generator
        Selects the kept leaves and the default leaf texture; same seed -> identical mesh.

    Returns
    -------
    Mesh
        With ``n_triangles <= max_triangles``.

    Examples
    --------
    >>> s = TreeSkeleton(np.array([[0, 0, 0], [0, 1, 0.]]), np.array([-1, 0]), np.array([0.1, 0.05]))
    >>> f = Foliage([[0, 1, 0]] * 10, [[0, 0, 1]] * 10, [[0, 1, 0]] * 10, [0.2] * 10, [[0.2, 0.5, 0.1]] * 10)
    >>> tree_mesh(s, f).n_triangles, tree_mesh(s, f, max_triangles=20).n_triangles
    (52, 20)
    """
    if not isinstance(skeleton, TreeSkeleton):
        raise InputError(f"skeleton: expected a TreeSkeleton, got {type(skeleton).__name__}")
    if foliage is None:
        foliage = Foliage.empty()
    if not isinstance(foliage, Foliage):
        raise InputError(f"foliage: expected a Foliage or None, got {type(foliage).__name__}")
    _check_budget(max_triangles)
    segs = _tubes._check_segments(radial_segments)
    rng = as_rng(seed)
    tex_seed = int(rng.integers(2**31)) if isinstance(seed, np.random.Generator) else int(seed or 0)

    nodes, lens = _tubes._chain_arrays(skeleton)
    plan = plan_lod(lens, _tubes._chain_measure_flat(skeleton, nodes, lens), len(foliage),
                    max_triangles=max_triangles, radial_segments=segs, seed=rng)
    keep = plan["keep_chains"]
    root_flags = np.arange(len(lens)) == 0
    bark = _tubes._tubes(skeleton, nodes[np.repeat(keep, lens)], lens[keep], root_flags[keep],
                         plan["radial_segments"], cap_starts=False, material=_tubes.bark_material(bark_texture, bark_normal))
    parts = [bark] if bark.n_triangles else []
    kept = plan["keep_leaves"]
    if kept.any():
        sub = foliage if kept.all() else foliage.subset(np.flatnonzero(kept))  # indices: faster than a mask
        tex = leaf_texture if leaf_texture is not None else \
            _leaves._default_leaf(_leaves.LEAF_TEXTURE_SIZE, tex_seed, "cluster").copy()
        parts.append(_leaves.leaf_cards(sub, texture=tex, size_scale=plan["leaf_scale"]))
    mesh = Mesh(parts)
    if max_triangles is not None and mesh.n_triangles > max_triangles:  # pragma: no cover - plan guarantees it
        raise AssertionError(f"LOD produced {mesh.n_triangles} > {max_triangles} triangles")
    return mesh
