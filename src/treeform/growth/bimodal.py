"""Bi-modal growth: self-organizing scaffold, then phenomenological crown (seed 003 §4.3–4.4).

With a branch mask, markers are placed on a vertical plane, one per branch pixel
(§4.4, Fig. 8a–b); a planar branching structure grows toward them by space colonization
from the bottom-most marker (Fig. 8c); every branch is then turned about the vertical
axis toward the geometric centre of the left or right half of the sectors of its
RBV layer (Fig. 8d–f). The paper places markers "along the main branching structure and
in the 3D space of the radial bounding volume" (§1): the self-organizing growth then goes on
from the turned scaffold toward markers spread through the RBV, so that limbs the photo
hides fill the sectors the mask's plane does not reach; finally the crown grows with the
phenomenological model inside the RBV (§4.4.1). Without a mask, the markers fill the RBV's
volume alone.

Beyond the paper, a mask's scaffold has one tube per branch: a marker is removed once a
node passes within the local half-width of its branch (:func:`local_thickness`), not a
fixed pixel and a half, which on a trunk several pixels wide grew parallel strands (a rope
of thin strands: 5–45 % of the trunk's radius in ``benchmarks/bench_bimodal.py --own``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from treeform._shared.checks import check_array, check_positive, check_range
from treeform._shared.errors import InputError
from treeform._shared.rng import as_rng
from treeform._shared.timing import ProgressCallback, StageTimer
from treeform.structures.rbv import RadialBoundingVolume
from treeform.structures.skeleton import TreeSkeleton, subtree_sizes


@dataclass
class MaskFrame:
    """How a branch mask's pixels map onto the vertical plane z = 0 (metres, Y up).

    ``x = (column + 0.5 - base[0]) * scale``, ``y = (base[1] - row - 0.5) * scale``: an
    orthographic view from +Z. Depth offsets added later (branch orientation) keep a node
    on its pixel only in such a view; with a close perspective camera they shift by the
    magnification change ``z / distance``.
    """

    base: tuple
    scale: float
    shape: tuple

    def to_world(self, cols, rows) -> np.ndarray:
        cols, rows = np.asarray(cols, np.float64), np.asarray(rows, np.float64)
        x = (cols + 0.5 - self.base[0]) * self.scale
        y = (self.base[1] - rows - 0.5) * self.scale
        return np.stack([x, y, np.zeros_like(x)], axis=-1)

    def to_pixels(self, points: np.ndarray) -> np.ndarray:
        p = np.asarray(points, np.float64).reshape(-1, 3)
        return np.stack([p[:, 0] / self.scale + self.base[0] - 0.5, self.base[1] - p[:, 1] / self.scale - 0.5], 1)


def mask_markers(mask: np.ndarray, *, height: float | None = None, scale: float | None = None,
                 base=None) -> tuple[np.ndarray, MaskFrame]:
    """One marker per branch pixel on the plane z = 0 (seed 003 §4.4, Fig. 8b).

    The bottom-most branch pixels become the origin (the tree's base) and the mask's
    vertical extent maps to ``height`` metres.

    Parameters
    ----------
    mask : ndarray, shape (H, W), bool
        Branch pixels.
    height : float, optional
        Height in metres of the branch mask's vertical extent (used when ``scale`` is None).
    scale : float, optional
        Metres per pixel, when known (e.g. from the whole tree's height in the photo).
    base : (column, row), optional
        Pixel position of the tree's base (default: centre of the lowest branch pixels).

    Returns
    -------
    markers : ndarray, shape (M, 3)
    frame : MaskFrame

    Examples
    --------
    >>> m = np.zeros((10, 5), bool); m[2:10, 2] = True
    >>> pts, fr = mask_markers(m, height=4.0)
    >>> pts.shape, float(pts[:, 1].min()), float(pts[:, 1].max())
    ((8, 3), 0.0, 4.0)
    """
    mask = check_array(mask, "mask", ndim=2).astype(bool)
    rows, cols = np.nonzero(mask)
    if len(rows) < 2:
        raise InputError("mask: needs at least two branch pixels")
    bottom = rows.max()
    if scale is None:
        if height is None:
            raise InputError("mask_markers: give height or scale")
        scale = check_positive(height, "height") / max(bottom - rows.min(), 1)
    scale = check_positive(scale, "scale")
    if base is None:
        base = (float(cols[rows == bottom].mean()) + 0.5, bottom + 0.5)
    frame = MaskFrame((float(base[0]), float(base[1])), scale, mask.shape)
    return frame.to_world(cols, rows), frame


def local_thickness(mask: np.ndarray) -> np.ndarray:
    """Half-width in pixels of the branch each mask pixel belongs to.

    The distance transform read at the nearest pixel of the mask's medial axis (its
    thinning): on a tube of radius ``r`` pixels every pixel gets about ``r + 0.5``, at its
    edge as on its axis. Zero outside the mask.

    Examples
    --------
    >>> m = np.zeros((9, 12), bool); m[2:7, 1:11] = True   # a bar 5 pixels thick
    >>> t = local_thickness(m)
    >>> float(t[2, 5]), float(t[4, 5]), float(t[0, 0])
    (3.0, 3.0, 0.0)
    """
    import scipy.ndimage as ndi
    from skimage.morphology import skeletonize

    m = check_array(mask, "mask", ndim=2).astype(bool)
    if not m.any():
        return np.zeros(m.shape)
    edt = ndi.distance_transform_edt(m)
    axis = skeletonize(m)
    _, (ir, ic) = ndi.distance_transform_edt(~axis, return_indices=True)
    return np.where(m, edt[ir, ic], 0.0)


def _preorder(parent: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """DFS entry index and subtree size of every node (subtree of c = tin in [tin[c], tin[c] + size[c]))."""
    n = len(parent)
    children: list[list[int]] = [[] for _ in range(n)]
    for i in range(1, n):
        children[parent[i]].append(i)
    tin = np.zeros(n, np.int64)
    order = []
    stack = [0]
    while stack:
        v = stack.pop()
        tin[v] = len(order)
        order.append(v)
        stack.extend(reversed(children[v]))
    return tin, subtree_sizes(parent)


def half_centroid(rbv: RadialBoundingVolume, layer: int, side: int) -> np.ndarray:
    """Area centroid (x, z) of the left (side -1, x < 0) or right (side +1) half of an RBV layer's sectors.

    Each sector is a circular wedge of its stored radius; its centroid lies at
    ``(2 r / 3) sin(Δ/2) / (Δ/2)`` along the wedge's bisector, weighted by its area ``r² Δ / 2``.
    """
    radii = rbv.physical_radii[layer]
    n = len(radii)
    width = 2 * np.pi / n
    theta = (np.arange(n) + 0.5) * width
    x = np.cos(theta)
    pick = (x < 0) if side < 0 else (x >= 0)
    r = radii[pick]
    if not pick.any() or r.sum() <= 0:
        return np.array([side * 1.0, 0.0])
    area = r * r * width / 2
    dist = (2 * r / 3) * np.sin(width / 2) / (width / 2)
    c = np.stack([dist * np.cos(theta[pick]), dist * np.sin(theta[pick])], 1)
    return (area[:, None] * c).sum(0) / area.sum()


def orient_scaffold(skeleton: TreeSkeleton, rbv: RadialBoundingVolume, *, max_angle: float = 85.0) -> TreeSkeleton:
    """Turn a planar scaffold's branches into 3D toward the RBV's sectors (seed 003 §4.4, Fig. 8d–f).

    For each branching point b (a node with several children, in root-to-tip order), every
    lateral child's subtree is *rotated* about the vertical axis through b so that its mean
    horizontal direction points from b toward the geometric centre g of the left or right
    half of the sectors of b's RBV layer (the half on the branch's own side of the plane):
    toward where that layer's crown extends farthest. The rotation angle is limited to
    ``max_angle``; the main child (largest subtree) is not turned. Sub-branches are turned
    again about their own branching points, so each branch ends up aimed at its own layer.

    Returns
    -------
    TreeSkeleton
        Same topology, radii and order; new positions (heights unchanged).
    """
    parent = skeleton.parent
    n = skeleton.n_nodes
    pos = skeleton.positions.copy()
    tin, size = _preorder(parent)
    order = np.argsort(tin)
    kids: list[list[int]] = [[] for _ in range(n)]
    for i in range(1, n):
        kids[parent[i]].append(i)
    layers = rbv.radii.shape[0]
    top = rbv.physical_height
    limit = np.radians(max_angle)
    for b in order:  # root to tips: a branch is placed before its sub-branches are aimed
        if len(kids[b]) < 2:
            continue
        main = max(kids[b], key=lambda k: (size[k], -k))
        layer = int(np.clip(pos[b, 1] / max(top, 1e-9) * layers, 0, layers - 1))
        for c in kids[b]:
            if c == main:
                continue
            sub = order[tin[c]: tin[c] + size[c]]
            off = pos[sub][:, [0, 2]] - pos[b, [0, 2]]
            v = off.mean(0)
            if np.hypot(*v) < 1e-9:
                continue
            side = -1 if v[0] < 0 else 1
            g = half_centroid(rbv, layer, side) + rbv.origin[[0, 2]] - pos[b, [0, 2]]
            if np.hypot(*g) < 1e-9:
                continue
            ang = np.arctan2(g[1], g[0]) - np.arctan2(v[1], v[0])
            ang = float(np.clip((ang + np.pi) % (2 * np.pi) - np.pi, -limit, limit))
            c_, s_ = np.cos(ang), np.sin(ang)
            # rotation in the (x, z) plane by ang (x toward z)
            pos[sub, 0] = pos[b, 0] + c_ * off[:, 0] - s_ * off[:, 1]
            pos[sub, 2] = pos[b, 2] + s_ * off[:, 0] + c_ * off[:, 1]
    return TreeSkeleton(pos, parent, skeleton.radius, skeleton.order, skeleton.age, dict(skeleton.meta))


def resample_scaffold(skeleton: TreeSkeleton, spacing: float) -> tuple[TreeSkeleton, np.ndarray]:
    """Keep a subset of a dense scaffold's nodes about ``spacing`` apart along its branches.

    The root, every branching point and every tip are kept; along a branch a node is kept
    once the arc length from the last kept node reaches ``spacing``. A mask-traced scaffold
    has a node per pixel; growth models count light and shadow per node, so the scaffold
    must have the crown's internode spacing for its light to mean the same.

    Returns
    -------
    skeleton : TreeSkeleton
        The kept nodes, each attached to its nearest kept ancestor.
    kept : ndarray of int
        Indices of the kept nodes in the input.
    """
    parent = skeleton.parent
    n = skeleton.n_nodes
    nkids = np.bincount(parent[1:], minlength=n)
    pos = skeleton.positions
    keep = np.zeros(n, bool)
    keep[0] = True
    keep[nkids != 1] = True  # branching points and tips
    acc = np.zeros(n)
    for i in range(1, n):  # parents come first
        pa = parent[i]
        a = (0.0 if keep[pa] else acc[pa]) + float(np.linalg.norm(pos[i] - pos[pa]))
        if a >= spacing:
            keep[i] = True
            a = 0.0
        acc[i] = a
    kept = np.flatnonzero(keep)
    new_index = -np.ones(n, np.int64)
    new_index[kept] = np.arange(len(kept))
    anc = np.arange(n)  # nearest kept ancestor-or-self
    for i in range(1, n):
        anc[i] = i if keep[i] else anc[parent[i]]
    new_parent = np.array([-1] + [new_index[anc[parent[i]]] for i in kept[1:]], np.int64)
    sk = TreeSkeleton(pos[kept], new_parent, skeleton.radius[kept], skeleton.order[kept], skeleton.age[kept],
                      dict(skeleton.meta))
    return sk, kept


def clamp_into(rbv: RadialBoundingVolume, points: np.ndarray, *, margin: float = 0.98) -> np.ndarray:
    """Pull points that lie outside an RBV toward its axis until they are inside (heights clipped to it).

    A point in a sector of radius r that stands farther than ``margin · r`` from the axis is
    moved radially to ``margin · r``. Returns a new (N, 3) array.
    """
    p = np.array(points, np.float64, copy=True)
    o = rbv.origin
    h = rbv.physical_height
    p[:, 1] = np.clip(p[:, 1], o[1], o[1] + h)
    local = p - o
    n_l, n_s = rbv.radii.shape
    layer = np.clip((local[:, 1] / max(h, 1e-12) * n_l).astype(np.int64), 0, n_l - 1)
    ang = np.mod(np.arctan2(local[:, 2], local[:, 0]), 2 * np.pi)
    sector = np.clip((ang / (2 * np.pi) * n_s).astype(np.int64), 0, n_s - 1)
    r = np.hypot(local[:, 0], local[:, 2])
    lim = margin * rbv.physical_radii[layer, sector]
    out = r > lim
    f = np.where(out, lim / np.maximum(r, 1e-12), 1.0)
    p[:, 0] = o[0] + local[:, 0] * f
    p[:, 2] = o[2] + local[:, 2] * f
    return p


class _AboveGround:
    """The half-space y >= 0 (nothing grows into the ground)."""

    def contains(self, points):
        return np.asarray(points)[:, 1] >= 0.0


class _AboveBole:
    """An envelope cut below the height ``floor`` above its origin, but for the stem: within
    ``tolerance`` of the ``stem`` points (the scaffold's nodes below it). No branch grows, or
    bends, down below the bole."""

    def __init__(self, env, floor: float, stem: np.ndarray, tolerance: float):
        from scipy.spatial import cKDTree

        self.env, self.floor, self.tol = env, float(floor), float(tolerance)
        self.y0 = float(np.asarray(env.origin, np.float64)[1])
        self.stem = cKDTree(np.asarray(stem, np.float64).reshape(-1, 3))

    def contains(self, points):
        p = np.asarray(points, np.float64)
        ok = np.asarray(self.env.contains(p), bool)
        low = ok & (p[:, 1] - self.y0 < self.floor)
        if low.any():
            d, _ = self.stem.query(p[low], distance_upper_bound=self.tol)
            ok[np.flatnonzero(low)[~np.isfinite(d)]] = False
        return ok


class _Shifted:
    """An envelope seen from coordinates shifted by ``-offset``, plus a thin column around the axis.

    The column (radius ``axis_tolerance``) lets the scaffold's first steps leave the base,
    where the RBV is only as wide as the trunk, without stalling.
    """

    def __init__(self, env, offset, axis_tolerance: float = 0.0):
        self.env, self.offset = env, np.asarray(offset, np.float64)
        self.tol = float(axis_tolerance)

    def contains(self, points):
        p = np.asarray(points, np.float64)
        ok = self.env.contains(p + self.offset)
        if self.tol > 0:
            ok |= (np.hypot(p[:, 0], p[:, 2]) <= self.tol) & (p[:, 1] >= 0) & (p[:, 1] <= self.env.physical_height)
        return ok


def planar_scaffold(markers: np.ndarray, *, segment_length: float, kill_distance=None,
                    influence_radius: float | None = None, perception_angle: float = 90.0,
                    envelope=None, root=None, trunk_height: float = 0.0, trunk=None,
                    sprout_above: float | None = None) -> TreeSkeleton:
    """Self-organizing growth toward markers from ``root``, growing up first (§4.4, Fig. 8c).

    Reuses :func:`treeform.growth.space_colonization` with a perception cone. ``root``
    defaults to the bottom-most marker, dropped to y = 0; the result is expressed with
    the root at the origin (``envelope`` is given in the markers' coordinates). With
    ``trunk_height`` > 0 a vertical trunk of that height is laid first and only its top
    sprouts (a bole through the RBV's narrow lowest layers); ``trunk`` (K, 3), a polyline
    from ``root`` in the markers' coordinates, is laid instead (it may lean and bend), and
    with ``sprout_above`` its nodes at least that high sprout too, not its top alone.
    ``kill_distance`` may be one distance per marker.
    """
    from treeform.growth.radii import branch_orders, pipe_model_radii
    from treeform.growth.space_colonization import space_colonization

    markers = check_array(markers, "markers", ndim=2).reshape(-1, 3)
    seg = check_positive(segment_length, "segment_length")
    if root is None:
        root = markers[np.argmin(markers[:, 1])].copy()
        root[1] = 0.0
    root = np.asarray(root, np.float64).reshape(3)
    if trunk is None:
        k = max(1, int(trunk_height / seg) + 1)
        start = root + np.outer(np.linspace(0, trunk_height, k), [0.0, 1.0, 0.0])
    else:
        start = _along(np.asarray(trunk, np.float64).reshape(-1, 3), seg)
        k = len(start)
    growable = np.zeros(k, bool) if sprout_above is None else start[:, 1] >= sprout_above
    growable[-1] = True
    res = space_colonization(markers, start, influence_radius=influence_radius or 40 * seg,
                             kill_distance=2.0 * seg if kill_distance is None else kill_distance, segment_length=seg,
                             perception_angle=perception_angle, envelope=envelope, growable=growable)
    pos = res.positions - np.array([root[0], 0.0, root[2]])
    radius = pipe_model_radii(res.parent, tip_radius=0.01)
    return TreeSkeleton(pos, res.parent, radius, branch_orders(res.parent, radius), res.iteration.astype(float))


MAX_VOLUME_MARKERS = 20_000
"""At most this many markers fill an RBV beside a mask's scaffold (a huge volume stays fast)."""


def _grow_into_volume(scaffold: TreeSkeleton, rbv: RadialBoundingVolume, n_markers: int, angle: float,
                      rng: np.random.Generator, floor: float = 0.0) -> TreeSkeleton:
    """Go on growing a (turned) scaffold by space colonization toward markers spread through the RBV.

    Blue-noise markers fill the volume; those near the scaffold are removed at once; every
    scaffold node at or above the height ``floor`` (metres) may sprout, toward the markers
    above it, within a perception cone of half-angle ``angle``; the internode is 1/60 of the
    RBV's height, as the volume scaffold without a mask. New nodes follow the scaffold's (its order is kept) with
    pipe-model radii left to the crown.
    """
    from treeform.growth.space_colonization import space_colonization
    from treeform.growth.sampling import blue_noise_points

    height = rbv.physical_height
    seg = height / 60
    r = float(rbv.physical_radii.max())
    lo = np.asarray(rbv.origin) + [-r, 0.0, -r]
    hi = np.asarray(rbv.origin) + [r, height, r]
    markers = blue_noise_points(rbv.contains, (lo, hi), int(n_markers), seed=rng)
    markers = markers[markers[:, 1] - rbv.origin[1] >= floor]  # no limb grows down below the bole
    if len(markers) == 0:
        return scaffold
    res = space_colonization(markers, scaffold.positions, scaffold.parent, influence_radius=40 * seg,
                             kill_distance=2 * seg, segment_length=seg, perception_angle=float(angle),
                             envelope=_Shifted(rbv, np.zeros(3), axis_tolerance=2 * seg),
                             growable=scaffold.positions[:, 1] >= floor)
    m = len(res.positions) - scaffold.n_nodes
    return TreeSkeleton(res.positions, res.parent, np.concatenate([scaffold.radius, np.full(m, scaffold.radius.min())]),
                        np.concatenate([scaffold.order, np.full(m, scaffold.order.max() + 1)]),
                        np.concatenate([scaffold.age, np.zeros(m)]))


def _along(polyline: np.ndarray, step: float) -> np.ndarray:
    """Nodes at most ``step`` apart along a (K, 3) polyline, ends included."""
    from treeform.contour.resample import resample_polyline

    length = float(np.linalg.norm(np.diff(polyline, axis=0), axis=1).sum())
    return resample_polyline(polyline, max(2, int(np.ceil(length / step)) + 1), endpoint=True)


def _stem(frame: MaskFrame, path, height: float) -> np.ndarray:
    """The one stem a mask's scaffold starts from, (K, 3) from the base at the origin: along the
    photo's traced trunk ``path`` ((column, row) pixels, base first; None: not traced), then
    straight up, hidden, to ``height`` where the traced trunk ends lower."""
    pts = np.zeros((1, 3)) if path is None else frame.to_world(path[:, 0] - 0.5, path[:, 1] - 0.5)
    pts[0] = 0.0
    if pts[-1, 1] < height:
        pts = np.vstack([pts, [pts[-1, 0], height, 0.0]])
    return pts


def bimodal_grow(params, rbv: RadialBoundingVolume, *, mask: np.ndarray | None = None, mask_scale: float | None = None,
                 mask_base=None, seed=0,
                 markers: int = 4000, segment_length: float | None = None, max_markers: int = 40_000,
                 crown_years: int | None = None, spacing: float | None = None, orient: bool = True, clamp: bool = True,
                 marker_density: float = 0.5, perception_angle: float = 50.0, bole: float = 0.0,
                 trunk_path=None, progress: ProgressCallback | None = None) -> TreeSkeleton:
    """Grow a tree by the bi-modal model of seed 003 §4.3–4.4 inside a radial bounding volume.

    Parameters
    ----------
    params : GrowthParameters
        Species parameters for the phenomenological crown.
    rbv : RadialBoundingVolume
        The target volume (physical units: metres, base at its origin).
    mask : ndarray, shape (H, W), bool, optional
        Branch pixels of the tree seen from the front (+Z). Markers go on the plane z = 0;
        without a mask, ``markers`` blue-noise markers fill the RBV's volume.
    mask_scale : float, optional
        Metres per mask pixel (default: the mask's vertical extent spans the RBV's height).
    mask_base : (column, row), optional
        The tree base's pixel (default: centre of the lowest branch pixels).
    seed : int
    segment_length : float, optional
        Scaffold internode in metres (default: one mask pixel with a mask, so the scaffold
        traces every branch; 1/60 of the RBV height without).
    max_markers : int
        At most this many branch pixels become markers (a deterministic subset).
    crown_years : int, optional
        Growth cycles of the phenomenological crown on the scaffold (default: the species'
        age, so the crown grows as far as the species does, inside the RBV).
    spacing : float, optional
        Node spacing of the scaffold handed to the crown growth (default: half the species'
        base internode length): the traced scaffold is resampled so that light and shadow,
        counted per node, mean what they mean in the crown.
    orient : bool
        Rotate the mask's planar scaffold toward the RBV's sectors (§4.4, Fig. 8d–f); off,
        the scaffold stays on the mask's plane (its front view is the mask).
    marker_density : float
        With a mask: markers per m³ of the RBV spread through it, toward which the turned
        scaffold goes on growing (§1: markers "in the 3D space of the radial bounding
        volume"), so hidden limbs fill the sectors off the mask's plane (at most
        :data:`MAX_VOLUME_MARKERS`); 0 keeps the mask's scaffold alone. How densely a crown
        is branched is a species trait (:func:`treeform.growth.species.load_marker_density`).
    perception_angle : float
        Half-angle (degrees) of the perception cone of that volume growth (Palubicki et al.
        2009): it bounds the angle at which new limbs leave the scaffold, so it is a species
        trait (:func:`treeform.growth.species.load_perception_angle`).
    bole : float in [0, 0.5]
        Share of the RBV's height below which no branch leaves the stem: a tree stands on
        one stem even where its crown hangs down to the ground or hides the trunk (0: as the
        mask and the volume have it). With a mask, its scaffold starts from one stem (see
        ``trunk_path``) that reaches at least that high, straight up where low foliage hides
        the trunk; the volume scaffold's bole reaches at least that high; and no growth after
        that sprouts, or bends, below it.
    trunk_path : ndarray, shape (K, 2), optional
        With a mask: the photo's trunk, a (column, row) pixel polyline from ``mask_base`` up to
        where the trunk enters the crown (:attr:`treeform.crown.layout.TreeLayout.trunk_path`).
        The scaffold starts from one stem laid along it (and on up to ``bole``), whose nodes
        above the bole sprout; the wood it covers draws no limbs, so a wide trunk becomes one
        tube instead of a strand per run of wood pixels.
    progress : callable, optional

    Returns
    -------
    TreeSkeleton
        Scaffold nodes first (never shed), then the crown; ``meta["n_scaffold"]`` counts them,
        ``meta["n_traced"]`` the first of them, traced from the mask (0 without one).
        With a mask, scaffold radii follow the mask's branch widths (half the local width).
    """

    from treeform.growth.phenomenological import grow
    from treeform.growth.radii import branch_orders
    from treeform.growth.sampling import blue_noise_points

    if not isinstance(rbv, RadialBoundingVolume):
        raise InputError(f"rbv: expected a RadialBoundingVolume, got {type(rbv).__name__}")
    rng = as_rng(seed)
    timer = StageTimer(progress)
    height = rbv.physical_height
    seg = segment_length or height / 60
    bole_h = check_range(bole, "bole", 0.0, 0.5) * height
    mask_note = None

    def volume_scaffold():
        r = float(rbv.physical_radii.max())
        lo = np.asarray(rbv.origin) + [-r, 0.0, -r]
        hi = np.asarray(rbv.origin) + [r, height, r]
        pts = blue_noise_points(rbv.contains, (lo, hi), markers, seed=rng) - [rbv.origin[0], 0, rbv.origin[2]]
        pts = pts[pts[:, 1] - rbv.origin[1] >= bole_h]  # no limb grows down below the bole
        local = _Shifted(rbv, rbv.origin * [1, 0, 1], axis_tolerance=2 * seg)
        # a bole up to the first layer wide enough to branch in
        radii = rbv.physical_radii.max(axis=1)
        wide = np.flatnonzero(radii > min(4 * seg, 0.5 * radii.max()))
        first = max((wide[0] / len(radii)) * height, bole_h)
        return pts, planar_scaffold(pts, segment_length=seg, perception_angle=120.0, envelope=local,
                                    root=np.zeros(3), trunk_height=first)

    with timer.stage("markers"):
        if mask is not None:
            pts, frame = mask_markers(mask, height=height, scale=mask_scale, base=mask_base)
            seg = segment_length or frame.scale
            thick = local_thickness(mask)[np.asarray(mask, bool)]  # the markers' order (row-major)
            if len(pts) > max_markers:
                pick = np.sort(rng.choice(len(pts), max_markers, replace=False))
                pts, thick = pts[pick], thick[pick]
    with timer.stage("scaffold"):
        if mask is not None:
            # a marker goes once a node passes within its branch's half-width (one tube per branch)
            kill = np.maximum(1.5 * seg, (thick + 0.5) * frame.scale)
            stem, up, laid, stem_r = None, np.ones(len(pts), bool), 1, 0.0
            if bole_h > 0 or trunk_path is not None:
                from scipy.spatial import cKDTree

                # the stem stands for the wood it covers and for all below the bole: the rest draws limbs
                path = None if trunk_path is None else check_array(trunk_path, "trunk_path", ndim=2).reshape(-1, 2)
                stem = _stem(frame, path, bole_h)
                nodes = _along(stem, seg)
                d, _ = cKDTree(nodes[:, :2]).query(pts[:, :2])
                on = d <= 2 * seg
                stem_r = (np.median(thick[on]) - 0.5) * frame.scale if on.any() else 0.0  # the trunk's half-width
                up = (pts[:, 1] >= bole_h) & ~((d <= max(1.5 * stem_r, 2 * seg)) & (pts[:, 1] <= stem[-1, 1] + stem_r))
                laid = len(nodes)
            scaffold = planar_scaffold(pts[up], segment_length=seg, kill_distance=kill[up], perception_angle=90.0,
                                       root=np.zeros(3), envelope=_AboveGround(), trunk=stem, sprout_above=bole_h)
            if stem is None and scaffold.n_nodes - laid < 2:
                # the branches the mask shows are out of the root's reach (e.g. the trunk is
                # hidden or cut off by the frame): grow from the volume alone, as without a mask
                mask_note = f"branch mask ignored: its scaffold reached {scaffold.n_nodes} node(s) from the base"
                mask, seg = None, segment_length or height / 60
        if mask is None:
            pts, scaffold = volume_scaffold()
        if mask is not None:
            # branch widths from the mask, read while the scaffold still lies on the plane
            import scipy.ndimage as ndi
            from scipy.spatial import cKDTree

            # one Lloyd step: each node moves to the centroid of the branch pixels nearest to it,
            # which centres the tubes on the branches (space colonization's averaged steps wander
            # up to a pixel off a thin branch's ridge)
            _, owner = cKDTree(scaffold.positions[:, :2]).query(pts[:, :2])
            cnt = np.bincount(owner, minlength=scaffold.n_nodes)
            cen = np.stack([np.bincount(owner, pts[:, c], scaffold.n_nodes) for c in (0, 1)], 1)
            moved = scaffold.positions.copy()
            has = cnt > 0
            has[:laid] = False  # the stem stays on the photo's trunk line
            moved[has, :2] = cen[has] / cnt[has, None]
            scaffold = TreeSkeleton(moved, scaffold.parent, scaffold.radius, scaffold.order, scaffold.age)
            # every branch pixel belongs to its nearest scaffold node, whose tube must reach it,
            # but no wider than the branch's local half-width (5x5 maximum of the distance
            # transform less a quarter pixel)
            half = ndi.maximum_filter(np.maximum(ndi.distance_transform_edt(np.asarray(mask, bool)) - 0.25, 0.0), 5)
            px = frame.to_pixels(scaffold.positions)
            cap = half[np.clip(px[:, 1].astype(int), 0, frame.shape[0] - 1),
                       np.clip(px[:, 0].astype(int), 0, frame.shape[1] - 1)]
            d, owner = cKDTree(scaffold.positions[:, :2]).query(pts[:, :2])
            reach = np.zeros(scaffold.n_nodes)
            np.maximum.at(reach, owner, d / frame.scale)
            r_mask = np.minimum(reach + 0.5, cap) * frame.scale
            if stem is not None and stem_r > 0:  # one tube, the photo's trunk width, tapering a fifth to its top
                y = scaffold.positions[:laid, 1]
                r_mask[:laid] = stem_r * (1.0 - 0.2 * y / max(float(y.max()), 1e-9))
        step = spacing or 0.5 * params.internode_length_base
        scaffold, kept = resample_scaffold(scaffold, step)
        if mask is not None:
            r_mask = r_mask[kept]
            if orient:
                scaffold = orient_scaffold(scaffold, rbv)
        pos = scaffold.positions + [rbv.origin[0], 0, rbv.origin[2]]
        if clamp:
            pos[1:] = clamp_into(rbv, pos[1:])  # the scaffold stays inside the volume
        scaffold = TreeSkeleton(pos, scaffold.parent, scaffold.radius, scaffold.order, scaffold.age)
        scaffold.positions[0] = 0.0
        n_traced = scaffold.n_nodes if mask is not None else 0
        n_volume = int(min(round(check_positive(marker_density, "marker_density", allow_zero=True) * rbv.volume()),
                           MAX_VOLUME_MARKERS))
        if mask is not None and n_volume > 0:
            n0 = scaffold.n_nodes
            scaffold = _grow_into_volume(scaffold, rbv, n_volume, perception_angle, rng, floor=bole_h)
            r_mask = np.concatenate([r_mask, np.zeros(scaffold.n_nodes - n0)])
    with timer.stage("crown"):
        from dataclasses import replace

        years = params.age if crown_years is None else max(1, int(crown_years))
        low = scaffold.positions[:, 1] - rbv.origin[1] < bole_h
        env = rbv if bole_h <= 0 or not low.any() else _AboveBole(rbv, bole_h, scaffold.positions[low], 2 * seg)
        sk = grow(replace(params, age=years), seed=rng, envelope=env, initial=scaffold)
    radius = sk.radius.copy()
    k = scaffold.n_nodes
    if mask is not None:
        # where the mask shows a branch, the scaffold takes its width from the mask
        on = r_mask > 0
        radius[:k][on] = r_mask[on]
    meta = dict(sk.meta)
    meta.update({"method": "bimodal", "n_scaffold": int(k), "n_traced": int(n_traced)})
    if mask_note is not None:
        meta["mask_note"] = mask_note
    return TreeSkeleton(sk.positions, sk.parent, radius, branch_orders(sk.parent, radius), sk.age, meta)
