"""Tree-form metrics of seed 003 §6: branching angle, height, trunk diameter, LAI, biomass, MRT.

All functions take a :class:`~treeform.structures.skeleton.TreeSkeleton` (metres, Y up,
node 0 the trunk base, ``parent[i] < i``) and, for the leaf area index, a
:class:`~treeform.structures.foliage.Foliage` (square leaf cards) or leaf triangles.

The 10-D metric space of §6 (:func:`metric_vector`) stacks the five global metrics, in the
order the paper's text lists them when it builds the space ("branching angle, tree height,
trunk diameter, leaf area index, biomass"), and the maximum radial trunk distance of five
uniform vertical layers, bottom to top (see :data:`METRIC_NAMES`).
"""

from __future__ import annotations

import math

import numpy as np

from treeform._shared.errors import InputError
from treeform.structures.foliage import Foliage
from treeform.structures.skeleton import TreeSkeleton

__all__ = [
    "METRIC_NAMES",
    "average_branching_angle",
    "branching_angles",
    "biomass",
    "crown_extents",
    "leaf_area_index",
    "leaf_area_index_triangles",
    "max_radial_trunk_distance",
    "mesh_metrics",
    "metric_vector",
    "tree_height",
    "tree_metrics",
    "trunk_diameter",
]

METRIC_NAMES = (
    "branching_angle_deg",
    "tree_height_m",
    "trunk_diameter_m",
    "leaf_area_index",
    "biomass_m3",
    "mrt_1_m",
    "mrt_2_m",
    "mrt_3_m",
    "mrt_4_m",
    "mrt_5_m",
)
"""Names of the :func:`metric_vector` components, in order (seed 003 §6); MRT layers bottom to top."""

LAI_RESOLUTION = 512
"""Default ground-grid cells along the longer side of the crown's footprint for the LAI."""


# --------------------------------------------------------------------------- helpers
def _check_skeleton(skeleton) -> TreeSkeleton:
    if not isinstance(skeleton, TreeSkeleton):
        raise InputError(f"skeleton: expected a TreeSkeleton, got {type(skeleton).__name__}")
    return skeleton


def _main_child(s: TreeSkeleton) -> np.ndarray:
    """(N,) index of each node's continuation child (-1 for a tip).

    The same rule as :meth:`TreeSkeleton.chains` (and so the meshes): the child with the
    node's own order first, then the largest radius, then the smallest index.
    """
    n = s.n_nodes
    main = np.full(n, -1, np.int64)
    if n == 1:
        return main
    c = np.arange(1, n)
    p = s.parent[1:]
    same = (s.order[c] == s.order[p]).astype(np.int64)
    idx = np.lexsort((-c, s.radius[c], same, p))  # primary key p; the last of each group wins
    cs, ps = c[idx], p[idx]
    last = np.r_[ps[1:] != ps[:-1], True]
    main[ps[last]] = cs[last]
    return main


def _trunk(s: TreeSkeleton) -> np.ndarray:
    """Node indices of the trunk: from the root, following continuation children."""
    main = _main_child(s)
    out = [0]
    while main[out[-1]] >= 0:
        out.append(int(main[out[-1]]))
    return np.array(out, np.int64)


def _layers_arg(layers) -> int:
    if isinstance(layers, bool) or not isinstance(layers, (int, np.integer)) or layers < 1:
        raise InputError(f"layers: expected an integer >= 1, got {layers!r}")
    return int(layers)


# --------------------------------------------------------------------------- global metrics
def branching_angles(skeleton: TreeSkeleton) -> tuple[np.ndarray, np.ndarray]:
    """Angle of every lateral branch to its parent's direction, in degrees.

    A *branching point* is a node with two or more children; one child continues the parent
    branch (the same rule as :meth:`TreeSkeleton.chains`), the others are *laterals*. A
    lateral's initial direction is its first segment (branching node -> child); the parent's
    direction at the node is the segment arriving at it (for the root: the continuation
    child's segment). Laterals with a zero-length segment are skipped.

    Parameters
    ----------
    skeleton : TreeSkeleton

    Returns
    -------
    angles : ndarray, shape (L,), float64
        Degrees in [0, 180], one per lateral branch.
    node : ndarray, shape (L,), int64
        The branching node of each lateral.
    """
    s = _check_skeleton(skeleton)
    n = s.n_nodes
    if n < 3:
        return np.zeros(0), np.zeros(0, np.int64)
    main = _main_child(s)
    c = np.arange(1, n)
    b = s.parent[1:]
    lateral = (main[b] != c) & (s.child_counts()[b] >= 2)
    c, b = c[lateral], b[lateral]
    pos = s.positions
    child_dir = pos[c] - pos[b]
    pb = s.parent[b]
    parent_dir = np.where((b == 0)[:, None], pos[main[b]] - pos[b], pos[b] - pos[np.maximum(pb, 0)])
    nc = np.linalg.norm(child_dir, axis=1)
    npd = np.linalg.norm(parent_dir, axis=1)
    ok = (nc > 0) & (npd > 0)
    cos = np.einsum("ij,ij->i", child_dir[ok], parent_dir[ok]) / (nc[ok] * npd[ok])
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0))), b[ok]


def average_branching_angle(skeleton: TreeSkeleton) -> float:
    """Average branching angle in degrees (seed 003 §6).

    For every branching point, the mean angle between each lateral child's initial
    direction and the parent's direction at the node (see :func:`branching_angles`); then
    the mean over branching points (a whorl of several laterals counts once).

    Parameters
    ----------
    skeleton : TreeSkeleton

    Returns
    -------
    float
        Degrees in [0, 180]; NaN when the tree has no lateral branch.

    Examples
    --------
    >>> s = TreeSkeleton(np.array([[0, 0, 0], [0, 1, 0], [0, 2, 0], [1, 2, 0.]]),
    ...                  np.array([-1, 0, 1, 1]), order=np.array([0, 0, 0, 1]))
    >>> round(average_branching_angle(s), 6)
    45.0
    """
    angles, node = branching_angles(skeleton)
    if len(angles) == 0:
        return float("nan")
    uniq, inv = np.unique(node, return_inverse=True)
    per_point = np.bincount(inv, weights=angles) / np.bincount(inv)
    return float(per_point.mean())


def tree_height(skeleton: TreeSkeleton, *, foliage: Foliage | None = None) -> float:
    """Tree height in metres (seed 003 §6): highest point above the base node.

    ``max(y) - y_root`` over the skeleton nodes and, when ``foliage`` is given, the corners of
    its leaf cards.

    Parameters
    ----------
    skeleton : TreeSkeleton
    foliage : Foliage, keyword-only, optional

    Returns
    -------
    float
    """
    s = _check_skeleton(skeleton)
    top = s.positions[:, 1].max()
    if foliage is not None and len(_check_foliage(foliage)):
        top = max(top, _card_corners(foliage)[..., 1].max())
    return float(top - s.positions[0, 1])


def trunk_diameter(skeleton: TreeSkeleton, *, at: float = 0.0) -> float:
    """Trunk diameter in metres at ``at`` metres above the base (seed 003 §6: "at base").

    The trunk is the chain of continuation children from the root (as in
    :meth:`TreeSkeleton.chains`); the radius is interpolated linearly along the first trunk
    segment that spans the height ``y_root + at``; the diameter is twice that radius. With the
    default ``at=0`` it is ``2 * radius[0]``. (Forestry's DBH is ``at=1.3``.)

    Parameters
    ----------
    skeleton : TreeSkeleton
    at : float, keyword-only
        Height above the base, metres, >= 0.

    Returns
    -------
    float

    Raises
    ------
    InputError
        ``at`` negative or above the trunk's top.
    """
    s = _check_skeleton(skeleton)
    try:
        at = float(at)
    except (TypeError, ValueError):
        raise InputError(f"at: expected a number of metres, got {at!r}") from None
    if not math.isfinite(at) or at < 0:
        raise InputError(f"at: expected a height >= 0 m, got {at!r}")
    if at == 0:
        return float(2.0 * s.radius[0])
    trunk = _trunk(s)
    y = s.positions[trunk, 1] - s.positions[0, 1]
    r = s.radius[trunk]
    for k in range(len(trunk) - 1):
        y0, y1 = y[k], y[k + 1]
        if min(y0, y1) <= at <= max(y0, y1):
            f = 0.0 if y1 == y0 else (at - y0) / (y1 - y0)
            return float(2.0 * (r[k] + f * (r[k + 1] - r[k])))
    raise InputError(f"at: {at} m is above the trunk's top ({y.max():.3f} m above the base)")


def stems_at(skeleton: TreeSkeleton, *, fraction: float = 0.05) -> int:
    """Number of separate branches crossing the horizontal plane at ``fraction`` of the tree's height.

    A tree with one trunk has 1 (a rope of strands converging at the ground, or several
    stems, count more). Edges are the skeleton's parent links; the plane lies at
    ``y_root + fraction · tree_height``; an edge crosses it when its two ends lie on
    opposite sides (an end exactly on it counts as above).

    Parameters
    ----------
    skeleton : TreeSkeleton
    fraction : float in (0, 1)

    Returns
    -------
    int

    Examples
    --------
    >>> s = TreeSkeleton(np.array([[0, 0, 0], [0, 1, 0], [0, 2, 0], [1, 0.5, 0]]), np.array([-1, 0, 1, 2]))
    >>> stems_at(s, fraction=0.05), stems_at(s, fraction=0.5)
    (1, 2)
    """
    s = _check_skeleton(skeleton)
    fraction = float(fraction)
    if not 0.0 < fraction < 1.0:
        raise InputError(f"fraction: expected a number in (0, 1), got {fraction!r}")
    if s.n_nodes < 2:
        return 0
    plane = s.positions[0, 1] + fraction * tree_height(s)
    child = np.flatnonzero(s.parent >= 0)
    below_a = s.positions[s.parent[child], 1] < plane
    below_b = s.positions[child, 1] < plane
    return int(np.count_nonzero(below_a != below_b))


def biomass(skeleton: TreeSkeleton) -> float:
    """Total branch volume in m³ (seed 003 §6: "the total volume of all branches").

    Every segment parent -> child is a truncated cone of length ``L`` with end radii
    ``r0`` and ``r1 = radius[child]``: ``V = π L (r0² + r0 r1 + r1²) / 3``. ``r0`` is the
    parent's radius when the child continues the parent's branch, and
    ``min(radius[parent], radius[child])`` for the first segment of a lateral (the same rule
    as the tube meshes, so a thin lateral does not inherit the trunk's thickness).

    Parameters
    ----------
    skeleton : TreeSkeleton

    Returns
    -------
    float

    Examples
    --------
    >>> s = TreeSkeleton(np.array([[0, 0, 0], [0, 2, 0.]]), np.array([-1, 0]), np.array([0.5, 0.5]))
    >>> bool(np.isclose(biomass(s), np.pi * 0.5 ** 2 * 2))
    True
    """
    s = _check_skeleton(skeleton)
    if s.n_nodes < 2:
        return 0.0
    main = _main_child(s)
    c = np.arange(1, s.n_nodes)
    p = s.parent[1:]
    r1 = s.radius[c]
    r0 = np.where(main[p] == c, s.radius[p], np.minimum(s.radius[p], r1))
    length = s.segment_lengths()[1:]
    return float(np.sum(np.pi * length * (r0 * r0 + r0 * r1 + r1 * r1) / 3.0))


def max_radial_trunk_distance(skeleton: TreeSkeleton, *, layers: int = 5) -> np.ndarray:
    """Maximum radial trunk distance (MRT) per vertical layer, metres (seed 003 §6).

    The tree's height above the base (``tree_height(skeleton)``) is split into ``layers``
    equal slabs, layer 0 at the base (layer ``i`` holds ``i h / L <= y < (i+1) h / L``, the
    top one also ``y == h``). In each, the MRT is the largest horizontal distance of a
    skeleton node from the trunk: the trunk chain (root, then continuation children, as
    the meshes draw it) read at the node's height, linearly between its nodes, its top
    node's position above it. A leaning trunk is measured from itself, not from the
    vertical through the base (a leaning oak's crown would otherwise read metres wide at
    every layer). A layer without nodes has MRT 0; nodes below the base are ignored.

    Parameters
    ----------
    skeleton : TreeSkeleton
    layers : int, keyword-only
        Number of layers, >= 1 (the metric space uses 5).

    Returns
    -------
    ndarray, shape (layers,), float64
        Bottom to top.
    """
    s = _check_skeleton(skeleton)
    n = _layers_arg(layers)
    local = s.positions - s.positions[0]
    y = local[:, 1]
    h = y.max()
    out = np.zeros(n)
    if h <= 0:
        return out
    trunk = local[_trunk(s)]
    # the trunk's (x, z) as a function of height: heights made non-decreasing along the chain
    ty = np.maximum.accumulate(trunk[:, 1])
    keep = y >= 0
    yk = y[keep]
    ax = np.interp(yk, ty, trunk[:, 0])
    az = np.interp(yk, ty, trunk[:, 2])
    idx = np.clip(np.floor(yk / h * n).astype(np.int64), 0, n - 1)
    np.maximum.at(out, idx, np.hypot(local[keep, 0] - ax, local[keep, 2] - az))
    return out


# --------------------------------------------------------------------------- crown extents
def crown_extents(points) -> dict:
    """The crown's horizontal extents and width, metres: the one definition treeform reports.

    The crown's *extents* are its spread along X and along Z, from the outermost point on
    one side to the outermost on the other (``max - min``, no trimming: the drip line). The
    *crown width* is their mean, the forestry convention of averaging two perpendicular
    crown diameters. The *maximum radial extent* is the largest horizontal distance of a
    point from the trunk axis: the vertical line through a skeleton's base node, or through
    the origin (treeform's tree base) for a point array.

    ``treeform grow``'s summary and metrics.json, the reconstructions' metrics.json and
    ``treeform metrics`` all report these numbers, measured on the branch skeleton's
    nodes (``skeleton.positions``), so every file of one tree gives the same figures; for a
    bare mesh (:func:`mesh_metrics`) they are measured on its vertices.

    Parameters
    ----------
    points : array_like, shape (N, 3), or TreeSkeleton
        Points in metres, Y up, tree base at the origin (a skeleton: its nodes).

    Returns
    -------
    dict
        ``crown_extent_x_m``, ``crown_extent_z_m``, ``crown_width_m``, ``max_radial_extent_m``
        (floats; all 0 for a single point).

    Raises
    ------
    InputError
        ``points`` is empty, not (N, 3), or holds NaN or infinite values.

    Examples
    --------
    >>> m = crown_extents(np.array([[0, 0, 0], [-1, 5, 0], [3, 6, 1], [0, 7, -3.]]))
    >>> m["crown_extent_x_m"], m["crown_extent_z_m"], m["crown_width_m"]
    (4.0, 4.0, 4.0)
    """
    p = points.positions if isinstance(points, TreeSkeleton) else np.asarray(points, np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or len(p) == 0:
        raise InputError(f"points: expected a non-empty (N, 3) array, got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise InputError("points: contains NaN or infinite values")
    ex, ez = float(np.ptp(p[:, 0])), float(np.ptp(p[:, 2]))
    axis = p[0] if isinstance(points, TreeSkeleton) else np.zeros(3)
    return {
        "crown_extent_x_m": ex,
        "crown_extent_z_m": ez,
        "crown_width_m": 0.5 * (ex + ez),
        "max_radial_extent_m": float(np.hypot(p[:, 0] - axis[0], p[:, 2] - axis[2]).max()),
    }


# --------------------------------------------------------------------------- leaf area index
def _check_foliage(foliage) -> Foliage:
    if not isinstance(foliage, Foliage):
        raise InputError(f"foliage: expected a Foliage, got {type(foliage).__name__}")
    return foliage


def _card_corners(foliage: Foliage) -> np.ndarray:
    """(M, 4, 3) corners of the leaf cards, in the order of ``geometry.leaves.leaf_cards``.

    ``up`` is orthogonalised against the normal, ``right = up x normal``; corners
    ``c - r + u, c + r + u, c + r - u, c - r - u`` with ``r, u`` half an edge long.
    """
    nrm = foliage.normals / np.maximum(np.linalg.norm(foliage.normals, axis=1, keepdims=True), 1e-300)
    up = foliage.up - np.einsum("ij,ij->i", foliage.up, nrm)[:, None] * nrm
    up /= np.maximum(np.linalg.norm(up, axis=1, keepdims=True), 1e-300)
    right = np.cross(up, nrm)
    h = 0.5 * foliage.size[:, None]
    u, r = up * h, right * h
    c = foliage.positions
    return np.stack([c - r + u, c + r + u, c + r - u, c - r - u], axis=1)


def _card_triangles(foliage: Foliage) -> np.ndarray:
    """(2M, 3, 3) the two triangles of every leaf card (sharing the 0-2 diagonal)."""
    q = _card_corners(foliage)
    return np.concatenate([q[:, [0, 1, 2]], q[:, [0, 2, 3]]], axis=0)


def _convex_hull(pts: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull (H, 2) of 2-D points (Andrew's monotone chain).

    Points strictly inside the polygon of the extreme points along x, z and both diagonals
    cannot be hull vertices and are dropped first (Akl-Toussaint), so the Python loop sees a
    few hundred points instead of every leaf corner.

    Examples
    --------
    >>> g = np.stack(np.meshgrid(np.arange(5.0), np.arange(4.0)), -1).reshape(-1, 2)
    >>> _convex_hull(g).tolist()
    [[0.0, 0.0], [4.0, 0.0], [4.0, 3.0], [0.0, 3.0]]
    """
    pts = np.asarray(pts, np.float64)
    if len(pts) > 64:
        keys = np.stack([pts[:, 0], pts[:, 0] + pts[:, 1], pts[:, 1], pts[:, 1] - pts[:, 0]], axis=1)
        ext = np.concatenate([keys.argmax(0), keys.argmin(0)])
        ang = np.arctan2(*(pts[ext] - pts[ext].mean(0)).T[::-1])
        poly = np.unique(pts[ext[np.argsort(ang)]], axis=0, return_index=True)[1]
        poly = pts[ext[np.argsort(ang)]][np.sort(poly)]  # counter-clockwise, duplicates dropped
        if len(poly) >= 3:
            inner = np.ones(len(pts), bool)
            for k in range(len(poly)):
                a, b = poly[k], poly[(k + 1) % len(poly)]
                inner &= (b[0] - a[0]) * (pts[:, 1] - a[1]) - (b[1] - a[1]) * (pts[:, 0] - a[0]) > 0
            pts = pts[~inner]
    pts = np.unique(pts, axis=0)
    if len(pts) < 3:
        return pts

    def half(points):
        out = []
        for p in points:
            while len(out) >= 2 and ((out[-1][0] - out[-2][0]) * (p[1] - out[-2][1])
                                     - (out[-1][1] - out[-2][1]) * (p[0] - out[-2][0])) <= 0:
                out.pop()
            out.append(p)
        return out

    lower = half(pts)
    upper = half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


def _raster_triangles(tri: np.ndarray, x0: float, z0: float, cell: float, nx: int, nz: int) -> np.ndarray:
    """(nz, nx) int64: how many of the 2-D triangles (T, 3, 2) cover each cell centre.

    Cell (j, i) has its centre at ``(x0 + (i + 0.5) cell, z0 + (j + 0.5) cell)``. A centre
    on an edge shared by two triangles is counted once (a tie rule on a canonically oriented
    edge function), so a card split into two triangles covers its diagonal once.
    """
    counts = np.zeros(nz * nx, np.int64)
    a, b, c = tri[:, 0], tri[:, 1], tri[:, 2]
    area2 = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    keep = area2 != 0
    tri = tri[keep]
    flip = area2[keep] < 0
    tri[flip] = tri[flip][:, [0, 2, 1]]  # counter-clockwise in (x, z)
    if len(tri) == 0:
        return counts.reshape(nz, nx)
    lo_xy = tri.min(axis=1)
    hi_xy = tri.max(axis=1)
    i0 = np.clip(np.ceil((lo_xy[:, 0] - x0) / cell - 0.5).astype(np.int64), 0, nx)
    i1 = np.clip(np.floor((hi_xy[:, 0] - x0) / cell - 0.5).astype(np.int64), -1, nx - 1)
    j0 = np.clip(np.ceil((lo_xy[:, 1] - z0) / cell - 0.5).astype(np.int64), 0, nz)
    j1 = np.clip(np.floor((hi_xy[:, 1] - z0) / cell - 0.5).astype(np.int64), -1, nz - 1)
    w = np.maximum(i1 - i0 + 1, 0)
    sizes = w * np.maximum(j1 - j0 + 1, 0)
    # canonical edges: (lo, hi) in lexicographic order, sign +1 when the triangle runs lo -> hi
    edges = []
    for k in range(3):
        p, q = tri[:, k], tri[:, (k + 1) % 3]
        fwd = (p[:, 0] < q[:, 0]) | ((p[:, 0] == q[:, 0]) & (p[:, 1] < q[:, 1]))
        lo = np.where(fwd[:, None], p, q)
        hi = np.where(fwd[:, None], q, p)
        edges.append((lo, hi - lo, fwd))
    budget = 1 << 22
    start = 0
    cum = np.cumsum(sizes)
    while start < len(tri):
        base = cum[start - 1] if start else 0
        stop = max(int(np.searchsorted(cum, base + budget, side="right")), start + 1)
        sel = np.arange(start, stop)
        sz = sizes[sel]
        total = int(sz.sum())
        start = stop
        if total == 0:
            continue
        t = np.repeat(sel, sz)
        off = np.arange(total) - np.repeat(np.cumsum(sz) - sz, sz)
        ii = i0[t] + off % w[t]
        jj = j0[t] + off // w[t]
        px = x0 + (ii + 0.5) * cell
        pz = z0 + (jj + 0.5) * cell
        inside = np.ones(total, bool)
        for lo, d, fwd in edges:
            e = d[t, 0] * (pz - lo[t, 1]) - d[t, 1] * (px - lo[t, 0])
            f = fwd[t]
            inside &= np.where(f, e > 0, e < 0) | ((e == 0) & f)
        counts += np.bincount(jj[inside] * nx + ii[inside], minlength=nz * nx)
    return counts.reshape(nz, nx)


def _inside_convex(poly: np.ndarray, px: np.ndarray, pz: np.ndarray) -> np.ndarray:
    """Boolean mask of points (inclusive) inside a counter-clockwise convex polygon (H, 2)."""
    inside = np.ones(np.broadcast_shapes(np.shape(px), np.shape(pz)), bool)
    for k in range(len(poly)):
        a, b = poly[k], poly[(k + 1) % len(poly)]
        inside &= (b[0] - a[0]) * (pz - a[1]) - (b[1] - a[1]) * (px - a[0]) >= 0
    return inside


def _lai(triangles: np.ndarray, extra_xz: np.ndarray | None, *, footprint: str, cell, coverage) -> dict:
    """LAI with its numerator and denominator, see :func:`leaf_area_index_triangles`."""
    if footprint not in ("hull", "union"):
        raise InputError(f"footprint: expected one of hull, union; got {footprint!r}")
    try:
        coverage = float(coverage)
    except (TypeError, ValueError):
        raise InputError(f"coverage: expected a number in (0, 1], got {coverage!r}") from None
    if not (0 < coverage <= 1):
        raise InputError(f"coverage: expected a number in (0, 1], got {coverage!r}")
    tri = np.asarray(triangles, np.float64)
    if tri.ndim != 3 or tri.shape[1:] != (3, 3):
        raise InputError(f"triangles: expected shape (T, 3, 3), got {tri.shape}")
    if not np.all(np.isfinite(tri)):
        raise InputError("triangles: contains NaN or infinite values")
    tri2 = tri[..., [0, 2]]
    pts = tri2.reshape(-1, 2)
    if footprint == "hull" and extra_xz is not None and len(extra_xz):
        pts = np.concatenate([pts, extra_xz])
    empty = {"leaf_area_index": 0.0, "projected_leaf_area_m2": 0.0, "crown_projection_area_m2": 0.0, "cell_m": 0.0}
    if len(tri2) == 0:
        return empty
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    extent = float((hi - lo).max())
    if extent <= 0:
        return empty
    if cell is None:
        cell = extent / LAI_RESOLUTION
    else:
        try:
            cell = float(cell)
        except (TypeError, ValueError):
            raise InputError(f"cell: expected a positive number of metres, got {cell!r}") from None
        if not (math.isfinite(cell) and cell > 0):
            raise InputError(f"cell: expected a positive number of metres, got {cell!r}")
    nx = int(math.ceil((hi[0] - lo[0]) / cell)) + 1
    nz = int(math.ceil((hi[1] - lo[1]) / cell)) + 1
    if nx * nz > 1 << 26:
        raise InputError(f"cell: {cell} m gives a {nx} x {nz} ground grid; choose a larger cell")
    counts = _raster_triangles(tri2, float(lo[0]), float(lo[1]), cell, nx, nz)
    covered = counts > 0
    if footprint == "hull":
        hull = _convex_hull(pts)
        if len(hull) >= 3:
            cx = lo[0] + (np.arange(nx) + 0.5) * cell
            cz = lo[1] + (np.arange(nz) + 0.5) * cell
            covered = covered | _inside_convex(hull, cx[None, :], cz[:, None])
    n_cov = int(covered.sum())
    area = cell * cell
    leaf = float(counts.sum()) * area * coverage
    crown = n_cov * area
    return {"leaf_area_index": leaf / crown if crown > 0 else 0.0, "projected_leaf_area_m2": leaf,
            "crown_projection_area_m2": crown, "cell_m": float(cell)}


def leaf_area_index_triangles(triangles, *, extra_points=None, footprint: str = "hull", cell=None,
                              coverage: float = 1.0) -> float:
    """Leaf area index of leaf triangles, e.g. a mesh's leaf primitive (seed 003 §6).

    The paper defines the LAI as "the projected tree geometry on the ground per unit area".
    Here, exactly:

    1. every leaf triangle is projected vertically onto the ground plane (x, z);
    2. the projections are rasterised on a square grid of ``cell`` metres: each cell counts
       how many triangles cover its centre (**overlapping leaves count once each**, so
       stacked leaves raise the index, as LAI's "layers of leaves" reading requires; a
       leaf seen edge-on projects to nothing);
    3. the *projected leaf area* is ``Σ counts · cell² · coverage``;
    4. the *crown projection area* is ``cell²`` times the number of cells in the crown's
       footprint: with ``footprint="hull"`` (default), the cells whose centres lie in the
       convex hull of the projected leaves and ``extra_points`` (the branches), plus any
       leaf-covered cell: the crown's drip-line area, gaps included; with
       ``footprint="union"``, only leaf-covered cells (then LAI >= 1 is the mean number of
       leaf layers above shaded ground);
    5. LAI = projected leaf area / crown projection area (0 when there is no leaf area).

    Parameters
    ----------
    triangles : array_like, shape (T, 3, 3)
        Leaf triangles in metres, Y up.
    extra_points : array_like, shape (P, 3), keyword-only, optional
        Further crown points (e.g. skeleton nodes) that widen the hull footprint.
    footprint : {"hull", "union"}, keyword-only
    cell : float, keyword-only, optional
        Ground cell size in metres; default the footprint's longer side / 512.
    coverage : float in (0, 1], keyword-only
        Opaque fraction of a leaf triangle (e.g. the alpha coverage of a leaf-cluster
        texture); 1 counts cards as solid.

    Returns
    -------
    float
    """
    extra = None
    if extra_points is not None:
        e = np.asarray(extra_points, np.float64)
        if e.ndim != 2 or e.shape[1] != 3:
            raise InputError(f"extra_points: expected shape (P, 3), got {e.shape}")
        extra = e[:, [0, 2]]
    return _lai(triangles, extra, footprint=footprint, cell=cell, coverage=coverage)["leaf_area_index"]


def leaf_area_index(foliage: Foliage, skeleton: TreeSkeleton | None = None, *, footprint: str = "hull",
                    cell=None, coverage: float = 1.0) -> float:
    """Leaf area index of square leaf cards (seed 003 §6).

    Each card of :class:`Foliage` (centre, normal, up, edge ``size``, the same square the
    leaf meshes draw) is split into two triangles and measured by
    :func:`leaf_area_index_triangles` (projected leaf area, overlaps counted, divided by the
    crown's ground-projection area); the skeleton's nodes, when given, widen the crown's hull
    footprint. A horizontal card of edge ``s`` contributes ``s²``; a vertical one nothing.

    Parameters
    ----------
    foliage : Foliage
        M leaf cards.
    skeleton : TreeSkeleton, optional
    footprint : {"hull", "union"}, keyword-only
    cell : float, keyword-only, optional
        Ground cell size in metres; default the footprint's longer side / 512.
    coverage : float in (0, 1], keyword-only

    Returns
    -------
    float
        0 for no leaves.

    Examples
    --------
    Two horizontal 1 m cards stacked on each other over a 1 m² crown:

    >>> n = np.array([[0, 1.0, 0]] * 2); u = np.array([[0, 0, 1.0]] * 2)
    >>> f = Foliage(np.array([[0, 3, 0], [0, 4, 0.]]), n, u, np.ones(2), np.full((2, 3), 0.5))
    >>> round(leaf_area_index(f), 6)
    2.0
    """
    return _lai_of(foliage, skeleton, footprint=footprint, cell=cell, coverage=coverage)["leaf_area_index"]


def _lai_of(foliage, skeleton, **kw) -> dict:
    f = _check_foliage(foliage)
    extra = None
    if skeleton is not None:
        extra = _check_skeleton(skeleton).positions[:, [0, 2]]
    return _lai(_card_triangles(f) if len(f) else np.zeros((0, 3, 3)), extra, **kw)


# --------------------------------------------------------------------------- summaries
def _recorded_leaves(s: TreeSkeleton):
    """The leaf count a pipeline recorded in ``skeleton.meta["n_leaves"]`` (None if absent)."""
    n = s.meta.get("n_leaves") if isinstance(s.meta, dict) else None
    return int(n) if isinstance(n, (int, np.integer)) and not isinstance(n, bool) and n >= 0 else None


def tree_metrics(skeleton: TreeSkeleton, foliage: Foliage | None = None, *, leaf_triangles=None,
                 layers: int = 5, lai_cell=None) -> dict:
    """Every tree-form metric of seed 003 §6 (and a few extents), JSON-ready.

    Parameters
    ----------
    skeleton : TreeSkeleton
    foliage : Foliage, optional
        Leaf cards for the LAI.
    leaf_triangles : array_like, shape (T, 3, 3), keyword-only, optional
        Leaf triangles (e.g. from a GLB's leaf primitive), used for the LAI when ``foliage``
        is None.
    layers : int, keyword-only
        MRT layers (5 in the paper's metric space).
    lai_cell : float, keyword-only, optional
        Ground cell of the LAI raster (metres).

    Returns
    -------
    dict
        ``branching_angle_deg``, ``tree_height_m``, ``trunk_diameter_m``, ``leaf_area_index``
        (NaN without leaves given), ``biomass_m3``, ``mrt_m`` (list of ``layers`` floats,
        bottom to top), ``projected_leaf_area_m2``, ``crown_projection_area_m2``,
        ``crown_extent_x_m``, ``crown_extent_z_m``, ``crown_width_m``, ``max_radial_extent_m``
        (:func:`crown_extents` of the skeleton's nodes), ``n_nodes``, ``n_branching_points``,
        ``n_leaves`` (the foliage's count; without foliage the count the pipeline that made
        the skeleton recorded in ``skeleton.meta["n_leaves"]``; None when neither exists).
    """
    s = _check_skeleton(skeleton)
    angles, nodes = branching_angles(s)
    if foliage is not None:
        lai = _lai_of(foliage, s, footprint="hull", cell=lai_cell, coverage=1.0)
        n_leaves = len(foliage)
    elif leaf_triangles is not None:
        lai = _lai(leaf_triangles, s.positions[:, [0, 2]], footprint="hull", cell=lai_cell, coverage=1.0)
        n_leaves = _recorded_leaves(s)
    else:
        lai = {"leaf_area_index": float("nan"), "projected_leaf_area_m2": float("nan"),
               "crown_projection_area_m2": float("nan")}
        n_leaves = _recorded_leaves(s)
    return {
        "branching_angle_deg": average_branching_angle(s),
        "tree_height_m": tree_height(s, foliage=foliage),
        "trunk_diameter_m": trunk_diameter(s),
        "leaf_area_index": lai["leaf_area_index"],
        "biomass_m3": biomass(s),
        "mrt_m": max_radial_trunk_distance(s, layers=layers).tolist(),
        "projected_leaf_area_m2": lai["projected_leaf_area_m2"],
        "crown_projection_area_m2": lai["crown_projection_area_m2"],
        **crown_extents(s),
        "n_nodes": int(s.n_nodes),
        "n_branching_points": int(len(np.unique(nodes))),
        "n_leaves": n_leaves,
    }


def metric_vector(skeleton: TreeSkeleton, foliage: Foliage | None = None) -> np.ndarray:
    """The 10-D tree-form metric vector of seed 003 §6 (Fig. 19).

    Components, in the order of §6's text ("the global metrics (branching angle, tree height,
    trunk diameter, leaf area index, biomass) together with 5 vertical layers of MRT"):

    0. average branching angle, degrees (:func:`average_branching_angle`)
    1. tree height, m (:func:`tree_height`, leaves included when given)
    2. trunk diameter at the base, m (:func:`trunk_diameter`)
    3. leaf area index (:func:`leaf_area_index`, hull footprint); NaN without ``foliage``
    4. biomass, m³ (:func:`biomass`)
    5-9. MRT of five uniform vertical layers, bottom to top, m
       (:func:`max_radial_trunk_distance` with ``layers=5``)

    (Fig. 19's caption lists the same five in another order, "LAI, tree height, biomass,
    trunk diameter, branch angle"; the paper gives no index order, so the text's is used and
    :data:`METRIC_NAMES` pins it.) Components are raw (not normalised); the paper compares "normalized metric space
    distances", so scale each axis (e.g. by its dataset standard deviation) before
    measuring distances.

    Parameters
    ----------
    skeleton : TreeSkeleton
    foliage : Foliage, optional

    Returns
    -------
    ndarray, shape (10,), float64
        Named by :data:`METRIC_NAMES`. Component 0 is NaN for a tree without laterals.
    """
    s = _check_skeleton(skeleton)
    lai = float("nan") if foliage is None else leaf_area_index(foliage, s)
    return np.array([
        average_branching_angle(s),
        tree_height(s, foliage=foliage),
        trunk_diameter(s),
        lai,
        biomass(s),
        *max_radial_trunk_distance(s, layers=5),
    ], dtype=np.float64)


def mesh_metrics(positions, *, leaf_triangles=None) -> dict:
    """What a bare mesh gives without its skeleton: height, extents, and LAI from leaves.

    Uses treeform's convention that the tree base sits on the vertical axis through the
    origin.

    Parameters
    ----------
    positions : array_like, shape (V, 3)
        All mesh vertices, metres, Y up.
    leaf_triangles : array_like, shape (T, 3, 3), keyword-only, optional
        The leaf primitive's triangles; the LAI is then computed with a hull footprint over
        all vertices.

    Returns
    -------
    dict
        ``tree_height_m`` (max y - min y), ``crown_extent_x_m``, ``crown_extent_y_m``,
        ``crown_extent_z_m`` (bounding box sides), ``crown_width_m`` (mean of the X and Z
        extents, :func:`crown_extents`), ``max_radial_extent_m`` (largest distance
        from the Y axis), ``leaf_area_index``, ``projected_leaf_area_m2``,
        ``crown_projection_area_m2`` (NaN without leaf triangles), ``n_vertices``.
    """
    p = np.asarray(positions, np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or len(p) == 0:
        raise InputError(f"positions: expected a non-empty (V, 3) array, got shape {p.shape}")
    if not np.all(np.isfinite(p)):
        raise InputError("positions: contains NaN or infinite values")
    ext = np.ptp(p, axis=0)
    crown = crown_extents(p)
    nan = float("nan")
    lai = {"leaf_area_index": nan, "projected_leaf_area_m2": nan, "crown_projection_area_m2": nan}
    if leaf_triangles is not None:
        lai = _lai(leaf_triangles, p[:, [0, 2]], footprint="hull", cell=None, coverage=1.0)
    return {
        "tree_height_m": float(ext[1]),
        "crown_extent_x_m": crown["crown_extent_x_m"],
        "crown_extent_y_m": float(ext[1]),
        "crown_extent_z_m": crown["crown_extent_z_m"],
        "crown_width_m": crown["crown_width_m"],
        "max_radial_extent_m": crown["max_radial_extent_m"],
        "leaf_area_index": lai["leaf_area_index"],
        "projected_leaf_area_m2": lai["projected_leaf_area_m2"],
        "crown_projection_area_m2": lai["crown_projection_area_m2"],
        "n_vertices": int(len(p)),
    }
