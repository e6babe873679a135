"""Space colonization (Runions, Lane & Prusinkiewicz 2007) — treeform's one implementation.

Used by the single-photo envelope method (seed 001 §3.6), leaflet billboards and the
planar part of bi-modal growth (seed 003 §4.4).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from treeform._shared.checks import check_array, check_positive
from treeform._shared.errors import InputError


@dataclass
class SpaceColonizationResult:
    """Grown nodes; the first ``n_initial`` are the given start nodes.

    Attributes
    ----------
    positions : ndarray, shape (N, 3)
    parent : ndarray, shape (N,), int64
        ``parent[i] < i`` for every grown node.
    iteration : ndarray, shape (N,), int64
        Growth step that created each node (0 for start nodes).
    attractors_left : int
        Attractors neither reached nor killed when growth stopped.
    iterations : int
    """

    positions: np.ndarray
    parent: np.ndarray
    iteration: np.ndarray
    attractors_left: int
    iterations: int


def space_colonization(attractors: np.ndarray, start_positions: np.ndarray, start_parent: np.ndarray | None = None,
                       *, influence_radius: float, kill_distance: float, segment_length: float,
                       max_iterations: int = 1000, growable: np.ndarray | None = None,
                       perception_angle: float | None = None, initial_direction=(0.0, 1.0, 0.0),
                       candidates: int = 8, envelope=None, direction_weight: float = 0.0,
                       start_direction_weight: float | None = None) -> SpaceColonizationResult:
    """Grow a branching structure toward attraction points.

    Each step, every attractor is associated with its closest tree node within
    ``influence_radius``; each node with associated attractors grows one new node a
    distance ``segment_length`` along the normalised sum of the unit vectors toward its
    attractors; attractors closer than ``kill_distance`` to a node are removed. Growth
    stops when no attractor is associated with a node, when every proposed node already
    exists (attractors that a node can only approach by repeating itself are left), or
    after ``max_iterations``.

    Nearest-node queries are incremental: only the distances to the nodes created in
    the last step are computed, so a step costs O(A log n_new) instead of a full rebuild.

    Parameters
    ----------
    attractors : ndarray, shape (A, 3)
    start_positions : ndarray, shape (K, 3)
        Initial nodes (e.g. a trunk); at least one.
    start_parent : ndarray, shape (K,), int64, optional
        Parents of the initial nodes (default: a chain 0 <- 1 <- 2 ...).
    influence_radius, kill_distance, segment_length : float
        Runions's d_i, d_k and D (kill distance should exceed the segment length).
        ``kill_distance`` may also be an array of shape (A,): one per attractor.
    max_iterations : int
    growable : ndarray, shape (K,), bool, optional
        Which initial nodes may sprout (default: all).
    perception_angle : float, optional
        Half-angle in degrees of the perception cone around each node's growth
        direction (Palubicki et al. 2009, used by seed 003 §4.3's self-organizing mode):
        a node only perceives attractors inside its cone. ``None`` (default) is Runions's
        isotropic sphere. With a cone, each attractor takes the nearest of its
        ``candidates`` nearest nodes whose cone holds it.
    initial_direction : sequence of 3 floats
        Growth direction of the root (others grow along parent -> node).
    envelope : object, optional
        Anything with ``contains(points) -> bool`` (e.g. a RadialBoundingVolume): proposed
        nodes outside it are not created (seed 003 §4.4: growth stays inside the RBV).
    direction_weight : float
        Weight of the node's own direction (parent -> node; the root's: ``initial_direction``)
        added to the unit mean direction toward its attractors (Palubicki et al. 2009's default
        direction, weight xi against the optimal direction's eta = 1). 0 (default) is Runions's
        rule, where a lateral leaves along its attractors' direction (about 90 degrees off its
        parent inside a crown); at 1 a lateral whose attractors lie square to its parent leaves
        at 45 degrees and turns toward them over the next internodes; at w, at about atan(1 / w).
    start_direction_weight : float, optional
        The weight where a start node grows: a lateral leaving the given trunk or leader (a
        conifer's laterals leave its leader at 70-90 degrees, their own side shoots at less).
        ``None``: as ``direction_weight``.

    Returns
    -------
    SpaceColonizationResult

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> att = rng.uniform(-1, 1, (300, 3)) + [0, 3, 0]
    >>> res = space_colonization(att, np.zeros((1, 3)), influence_radius=5, kill_distance=0.2,
    ...                          segment_length=0.1)
    >>> res.attractors_left < 10, bool(np.all(res.parent[1:] < np.arange(1, len(res.parent))))
    (True, True)
    """
    att = check_array(attractors, "attractors", ndim=2).astype(np.float64).reshape(-1, 3)
    start = check_array(start_positions, "start_positions", ndim=2, min_size=3).astype(np.float64).reshape(-1, 3)
    di = check_positive(influence_radius, "influence_radius")
    if np.ndim(kill_distance) == 0:
        dk = check_positive(kill_distance, "kill_distance")
    else:
        dk = np.asarray(kill_distance, np.float64).reshape(-1)
        if dk.shape != (len(att),) or not np.all(dk > 0):
            raise InputError(f"kill_distance: expected a positive number or {len(att)} positive numbers "
                             f"(one per attractor)")
    seg = check_positive(segment_length, "segment_length")
    xi = check_positive(direction_weight, "direction_weight", allow_zero=True)
    xi0 = xi if start_direction_weight is None else check_positive(start_direction_weight, "start_direction_weight",
                                                                   allow_zero=True)
    k0 = len(start)
    if start_parent is None:
        start_parent = np.arange(-1, k0 - 1)
    start_parent = np.asarray(start_parent, np.int64)
    if len(start_parent) != k0:
        raise InputError(f"start_parent: length {len(start_parent)} != {k0} start positions")

    cap = max(1024, 4 * k0 + 4 * len(att))
    pos = np.empty((cap, 3))
    par = np.empty(cap, np.int64)
    it_of = np.zeros(cap, np.int64)
    pos[:k0], par[:k0] = start, start_parent
    n = k0
    can_grow = np.ones(cap, bool)
    if growable is not None:
        can_grow[:k0] = np.asarray(growable, bool)

    best_d = np.full(len(att), np.inf)
    best_n = np.full(len(att), -1, np.int64)
    alive = np.ones(len(att), bool)
    seen: set = set()
    q = 0.1 * seg

    cos_cone = None if perception_angle is None else float(np.cos(np.radians(perception_angle)))
    root_dir = np.asarray(initial_direction, np.float64)
    root_dir = root_dir / max(np.linalg.norm(root_dir), 1e-12)

    def directions(nodes):
        d = np.tile(root_dir, (len(nodes), 1))
        has = par[nodes] >= 0
        v = pos[nodes[has]] - pos[par[nodes[has]]]
        d[has] = v / np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-12)
        return d

    from treeform.growth._point_kernels import nearest_new_node

    def update(new_lo, new_hi):
        idx = np.flatnonzero(alive)
        if len(idx) == 0:
            return
        cand = np.arange(new_lo, new_hi)
        cand = cand[can_grow[cand]]
        if len(cand) == 0:
            return
        if cos_cone is None:  # the nearest new node within d_i: a compiled grid search
            nearest_new_node(att, idx, pos, cand, di, best_d, best_n)
            return
        # the perception cone: each attractor takes the nearest of its k nearest new nodes that sees it
        tree = cKDTree(pos[cand])
        k = min(candidates, len(cand))
        d, j = tree.query(att[idx], k=k, distance_upper_bound=di)
        d, j = d.reshape(len(idx), k), j.reshape(len(idx), k)
        ok = np.isfinite(d)
        jj = np.where(ok, j, 0)
        nodes = cand[jj]
        dirs = directions(nodes.ravel()).reshape(len(idx), k, 3)
        vec = att[idx][:, None, :] - pos[nodes]
        cosang = np.einsum("akc,akc->ak", vec, dirs) / np.maximum(np.linalg.norm(vec, axis=2), 1e-12)
        d = np.where(ok & (cosang >= cos_cone), d, np.inf)
        first = np.argmin(d, axis=1)
        d = d[np.arange(len(idx)), first]
        j = jj[np.arange(len(idx)), first]
        better = d < best_d[idx]
        best_d[idx[better]] = d[better]
        best_n[idx[better]] = cand[j[better]]

    update(0, n)
    alive &= ~(best_d < dk)
    it = 0
    for it in range(1, max_iterations + 1):
        sel = np.flatnonzero(alive & (best_n >= 0))
        if len(sel) == 0:
            it -= 1
            break
        nodes = best_n[sel]
        vec = att[sel] - pos[nodes]
        vec /= np.maximum(np.linalg.norm(vec, axis=1, keepdims=True), 1e-12)
        growing, inv = np.unique(nodes, return_inverse=True)
        acc = np.stack([np.bincount(inv, vec[:, c], len(growing)) for c in range(3)], 1)
        norm = np.linalg.norm(acc, axis=1)
        ok = norm > 1e-6
        growing, acc, norm = growing[ok], acc[ok], norm[ok]
        step = acc / norm[:, None]
        if xi > 0.0 or xi0 > 0.0:  # the node's own direction too; where the two cancel, the attractors' alone
            w = np.where(growing < k0, xi0, xi)[:, None]
            blend = step + w * directions(growing)
            bn = np.linalg.norm(blend, axis=1)
            step = np.where((bn > 1e-6)[:, None], blend / np.where(bn > 1e-6, bn, 1.0)[:, None], step)
        new = pos[growing] + seg * step
        if envelope is not None:
            ok = np.asarray(envelope.contains(new), bool)
            growing, new = growing[ok], new[ok]
        # a node that keeps the same attractors proposes the same node again: drop repeats
        keys = np.round(new / q).astype(np.int64)
        keep = np.ones(len(new), bool)
        for i, key in enumerate(map(tuple, keys)):
            if key in seen:
                keep[i] = False
            else:
                seen.add(key)
        growing, new = growing[keep], new[keep]
        if len(new) == 0:
            break
        if n + len(new) > cap:
            cap = 2 * (n + len(new))
            pos = np.resize(pos, (cap, 3))
            par = np.resize(par, cap)
            it_of = np.resize(it_of, cap)
            can_grow = np.resize(can_grow, cap)
        pos[n:n + len(new)], par[n:n + len(new)], it_of[n:n + len(new)] = new, growing, it
        can_grow[n:n + len(new)] = True
        update(n, n + len(new))
        n += len(new)
        alive &= ~(best_d < dk)
        if not alive.any():
            break
    return SpaceColonizationResult(pos[:n].copy(), par[:n].copy(), it_of[:n].copy(), int(alive.sum()), it)
