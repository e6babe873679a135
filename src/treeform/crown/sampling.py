"""Points inside the envelope, spread evenly over the photo's pixels (for foliage)."""

from __future__ import annotations

import numpy as np

from treeform._shared.checks import check_array, check_positive
from treeform._shared.errors import InputError
from treeform._shared.rng import as_rng


def sample_crown_columns(mask: np.ndarray, front_z: np.ndarray, n: int, *, shell_power: float = 2.0,
                         weight=None, candidates: int = 8, seed=None) -> np.ndarray:
    """Sample ``n`` points whose projections cover ``mask`` uniformly, inside the envelope.

    A leaf's contribution to the picture depends on the pixel it covers, not on the
    crown's thickness there, so points are spread evenly over the mask: pixels are
    ordered along a Morton (Z-order) curve and picked by stratified sampling along it
    (one pick per 1/n of the curve, so no region gets clumps or holes), with sub-pixel
    jitter; each takes a depth within the envelope column ``[-z_f, z_f]`` at
    its pixel, with density growing toward the front and back surfaces as
    ``|t|^shell_power`` (foliage concentrates on the lit outer shell).

    Parameters
    ----------
    mask : ndarray, shape (H, W), bool
        Pixels to cover (e.g. the foliage pixels of the tree).
    front_z : ndarray, shape (H, W)
        Height of the envelope's front half, in pixels (0 where there is no envelope).
    n : int
    shell_power : float
        0 = uniform in depth; larger values push the points toward the surfaces.
    weight : callable, optional
        ``weight(uvz (K, 3)) -> (K,)`` non-negative density over the crown (e.g. its foliage
        clumps, :func:`clump_density`): each point draws ``candidates`` depths as above and
        keeps one with probability proportional to its weight (sampling importance
        resampling), so the points gather where the weight is high along their column while
        every pixel keeps its share of them.
    candidates : int
        Depths drawn per point when ``weight`` is given.

    Returns
    -------
    ndarray, shape (n, 3)
        (column, row, z) in pixel units, z toward the viewer.

    Examples
    --------
    >>> m = np.ones((10, 10), bool)
    >>> p = sample_crown_columns(m, np.full((10, 10), 4.0), 100, seed=0)
    >>> p.shape, bool(np.abs(p[:, 2]).max() <= 4.0)
    ((100, 3), True)
    """
    mask = check_array(mask, "mask", ndim=2).astype(bool)
    front_z = check_array(front_z, "front_z", ndim=2)
    if front_z.shape != mask.shape:
        raise InputError(f"front_z: shape {front_z.shape} does not match mask {mask.shape}")
    rng = as_rng(seed)
    ys, xs = np.nonzero(mask)
    if n <= 0 or len(ys) == 0:
        return np.zeros((0, 3))
    order = np.argsort(_morton(ys, xs), kind="stable")
    pick = order[np.minimum(((np.arange(n) + rng.random(n)) * len(ys) / n).astype(np.int64), len(ys) - 1)]
    u = xs[pick] + rng.random(n)
    v = ys[pick] + rng.random(n)
    zf = front_z[ys[pick], xs[pick]]
    if weight is not None and int(candidates) < 1:
        raise InputError(f"candidates: expected a positive count, got {candidates}")
    if weight is None:
        t = rng.random(n) ** (1.0 / (1.0 + shell_power))
        sign = np.where(rng.random(n) < 0.5, -1.0, 1.0)
        return np.stack([u, v, sign * t * zf], axis=1)
    m = int(candidates)
    t = rng.random((n, m)) ** (1.0 / (1.0 + shell_power))
    z = np.where(rng.random((n, m)) < 0.5, -1.0, 1.0) * t * zf[:, None]
    cand = np.stack([np.repeat(u, m), np.repeat(v, m), z.ravel()], axis=1)
    w = np.maximum(np.asarray(weight(cand), np.float64).reshape(n, m), 0) + 1e-9
    c = np.cumsum(w, axis=1)
    k = np.minimum((c < rng.random(n)[:, None] * c[:, -1:]).sum(1), m - 1)
    return np.stack([u, v, z[np.arange(n), k]], axis=1)


def _morton(ys: np.ndarray, xs: np.ndarray) -> np.ndarray:
    """Z-order (Morton) code of pixel coordinates below 65536."""
    def spread(v):
        v = v.astype(np.uint64) & np.uint64(0xFFFF)
        v = (v | (v << np.uint64(8))) & np.uint64(0x00FF00FF)
        v = (v | (v << np.uint64(4))) & np.uint64(0x0F0F0F0F)
        v = (v | (v << np.uint64(2))) & np.uint64(0x33333333)
        return (v | (v << np.uint64(1))) & np.uint64(0x55555555)

    return spread(ys) << np.uint64(1) | spread(xs)


def ray_extents(contains, origins: np.ndarray, directions: np.ndarray, t_near: float, t_far: float, *,
                steps: int = 96) -> tuple[np.ndarray, np.ndarray]:
    """First and last parameter t at which each ray is inside a volume.

    Samples ``steps`` points on every ray ``o + t d`` for t in [t_near, t_far] and
    returns the smallest and largest t found inside (NaN for rays that miss).

    Parameters
    ----------
    contains : callable
        ``contains(points (N, 3)) -> (N,) bool``, e.g. ``RadialDistanceMap.contains``.
    origins, directions : ndarray, shape (N, 3)
    t_near, t_far : float

    Returns
    -------
    t_first, t_last : ndarray, shape (N,)

    Examples
    --------
    >>> ball = lambda p: np.linalg.norm(p, axis=1) < 1
    >>> a, b = ray_extents(ball, np.array([[0, 0, 5.0]]), np.array([[0, 0, -1.0]]), 0, 10, steps=201)
    >>> round(float(a[0]), 1), round(float(b[0]), 1)
    (4.0, 6.0)
    """
    o = np.asarray(origins, np.float64).reshape(-1, 3)
    d = np.asarray(directions, np.float64).reshape(-1, 3)
    ts = np.linspace(t_near, t_far, steps)
    first = np.full(len(o), np.nan)
    last = np.full(len(o), np.nan)
    for t in ts:
        inside = np.asarray(contains(o + t * d), bool)
        new = inside & np.isnan(first)
        first[new] = t
        last[inside] = t
    return first, last


def sample_rdm_shell(rdm, n: int, *, shell_power: float = 4.0, keep=None, seed=None, max_rounds: int = 20) -> np.ndarray:
    """Sample ``n`` points inside a radial distance map, denser toward its surface.

    Directions are uniform on the sphere; the radius is ``t·R(direction)`` with t drawn
    so the density grows as ``t^shell_power`` (on top of the volume element), which puts
    foliage in the crown's outer shell seen from every side.

    Parameters
    ----------
    rdm : RadialDistanceMap
    n : int
    shell_power : float
    keep : callable, optional
        ``keep(points) -> bool`` extra test (e.g. the photo's visual hull); rejected
        points are redrawn.

    Returns
    -------
    ndarray, shape (m, 3), m <= n (fewer only if ``keep`` rejects nearly everything)

    Examples
    --------
    >>> from treeform.structures import RadialDistanceMap
    >>> rdm = RadialDistanceMap(np.zeros(3), np.full((6, 4, 4), 2.0, np.float32))
    >>> p = sample_rdm_shell(rdm, 500, seed=0)
    >>> p.shape, bool(np.linalg.norm(p, axis=1).max() <= 2.0), bool(np.median(np.linalg.norm(p, axis=1)) > 1.6)
    ((500, 3), True, True)
    """
    rng = as_rng(seed)
    out = []
    have = 0
    for _ in range(max_rounds):
        if have >= n:
            break
        m = 2 * (n - have) + 16
        d = rng.normal(size=(m, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        t = rng.random(m) ** (1.0 / (3.0 + shell_power))
        p = rdm.center + d * (t * rdm.lookup(d))[:, None]
        if keep is not None:
            p = p[np.asarray(keep(p), bool)]
        out.append(p)
        have += len(p)
    pts = np.concatenate(out) if out else np.zeros((0, 3))
    return pts[:n]


def visual_hull_contains(camera, mask: np.ndarray, points: np.ndarray, offset: tuple = (0, 0)) -> np.ndarray:
    """Whether points project onto ``True`` pixels of ``mask`` seen by ``camera`` (its visual hull).

    Parameters
    ----------
    camera : Camera
    mask : ndarray, shape (H, W), bool
        The camera's image, or a larger canvas around it (see ``offset``).
    points : ndarray, shape (N, 3)
    offset : (int, int)
        ``(top, left)``: the camera's pixel (u, v) is ``mask[v + top, u + left]`` (a silhouette
        continued past the frame, :func:`treeform.crown.frame.beyond_frame`).

    Returns
    -------
    ndarray, shape (N,), bool

    Examples
    --------
    >>> from treeform.structures import Camera
    >>> cam = Camera(10, 10, 90.0, (0, 0, 5), (0, 0, 0))
    >>> m = np.zeros((10, 10), bool); m[:, 5:] = True
    >>> visual_hull_contains(cam, m, np.array([[1.0, 0, 0], [-1.0, 0, 0]])).tolist()
    [True, False]
    """
    uvz = camera.project(points)
    h, w = mask.shape
    u = np.floor(uvz[:, 0]).astype(np.int64) + int(offset[1])
    v = np.floor(uvz[:, 1]).astype(np.int64) + int(offset[0])
    ok = (u >= 0) & (u < w) & (v >= 0) & (v < h) & (uvz[:, 2] > 0)
    out = np.zeros(len(uvz), bool)
    out[ok] = mask[v[ok], u[ok]]
    return out


def rdm_front_height(rdm, camera, plane_distance: float, metres_per_pixel: float, shape: tuple,
                     *, step: int = 4, steps: int = 64) -> np.ndarray:
    """Height of a radial distance map's front surface above the plane z = 0, per image pixel.

    Rays through every ``step``-th pixel are marched through the RDM (``steps`` samples
    between depths ``plane_distance ± max radius``); the first inside sample gives the
    front surface, whose height toward the camera is returned in pixel units
    (``metres / metres_per_pixel``) and interpolated to every pixel. 0 where rays miss.

    Parameters
    ----------
    rdm : RadialDistanceMap
    camera : Camera
        Looking at the plane z = 0 from ``plane_distance``.
    plane_distance : float
    metres_per_pixel : float
        Scale on the plane z = 0.
    shape : tuple of int
        (H, W) of the output.

    Returns
    -------
    ndarray, shape (H, W)
    """
    import scipy.ndimage as ndi

    h, w = shape
    gy, gx = np.mgrid[step // 2:h:step, step // 2:w:step]
    reach = float(rdm.radii.max()) * 1.05 + 1e-6
    near = camera.unproject(gx.ravel() + 0.5, gy.ravel() + 0.5, np.full(gx.size, plane_distance - reach))
    far = camera.unproject(gx.ravel() + 0.5, gy.ravel() + 0.5, np.full(gx.size, plane_distance + reach))
    first, _ = ray_extents(rdm.contains, near, far - near, 0.0, 1.0, steps=steps)
    z = np.where(np.isnan(first), 0.0, reach * (1 - 2 * np.nan_to_num(first, nan=0.5)) / metres_per_pixel)
    z = np.maximum(z, 0).reshape(gx.shape)
    full = ndi.zoom(z, (h / z.shape[0], w / z.shape[1]), order=1)[:h, :w]
    return np.pad(full, ((0, h - full.shape[0]), (0, w - full.shape[1])), mode="edge")


def farthest_point_order(points: np.ndarray, n: int, *, first: int = 0) -> np.ndarray:
    """Indices of ``n`` points picked by farthest-point sampling: every prefix is well spread.

    Starts at ``first``; each next point is the one farthest from all picked so far (ties:
    the lowest index), so the first k of the order cover the set about evenly for every k.

    Examples
    --------
    >>> farthest_point_order(np.array([[0, 0, 0], [1, 0, 0], [10, 0, 0], [5, 0, 0.]]), 3).tolist()
    [0, 2, 3]
    """
    pts = check_array(points, "points", ndim=2, min_size=1).astype(np.float64)
    n = min(int(n), len(pts))
    order = np.empty(n, np.int64)
    dist = np.full(len(pts), np.inf)
    k = int(first)
    for i in range(n):
        order[i] = k
        dist = np.minimum(dist, np.einsum("ij,ij->i", pts - pts[k], pts - pts[k]))
        k = int(np.argmax(dist))
    return order


def billboard_centres(rdm, nodes=None, n: int = 144, *, inner: float = 0.35, box=None, seed=None) -> np.ndarray:
    """Centres of a crown's billboard cloud (seed 001 §4.2), ordered so every prefix is spread.

    The centres are points of the branching structure (``nodes``, e.g. the tree's skeleton)
    inside the crown (the RDM) and outside its core (beyond ``inner`` of the radius in their
    direction: billboards deep inside are hidden); where the skeleton offers too few, points
    of the RDM's shell (:func:`sample_rdm_shell`) fill up. The order is farthest-point, from
    the highest point down, so drawing the first k of them (fewer far away) still covers the
    crown.

    Parameters
    ----------
    rdm : RadialDistanceMap
    nodes : array_like, shape (N, 3), optional
    n : int
    inner : float
        Relative radius of the excluded core.
    box : (array_like (3,), array_like (3,)), optional
        Keep only points inside this box (e.g. the leaves' bounds: the RDM also holds the
        trunk, and billboards along it would hang below the crown).
    seed : int or Generator, optional
        For the subsample of a large skeleton and the shell points.

    Returns
    -------
    ndarray, shape (n, 3), float32
    """
    rng = as_rng(seed)
    n = int(n)
    if n < 1:
        raise InputError(f"n: expected a positive count, got {n}")
    cand = np.zeros((0, 3))
    if nodes is not None:
        p = check_array(nodes, "nodes", shape=(None, 3)).astype(np.float64)
        d = p - rdm.center
        r = np.linalg.norm(d, axis=1)
        big = rdm.lookup(d)
        ok = (r <= big) & (r >= inner * big)
        if box is not None:
            ok &= np.all((p >= np.asarray(box[0])) & (p <= np.asarray(box[1])), axis=1)
        cand = p[ok]
        if len(cand) > 20 * n:
            cand = cand[np.sort(rng.choice(len(cand), 20 * n, replace=False))]
    if len(cand) < 4 * n:  # too few branch points: the crown's shell fills in
        keep = None if box is None else (lambda q: np.all((q >= np.asarray(box[0])) & (q <= np.asarray(box[1])), axis=1))
        cand = np.concatenate([cand, sample_rdm_shell(rdm, 4 * n - len(cand), keep=keep, seed=rng)])
    order = farthest_point_order(cand, n, first=int(np.argmax(cand[:, 1])))
    return cand[order].astype(np.float32)


CARD_COVER = 0.85
"""Share of a leaf card's projected square that must lie on the photo's tree mask for the card to stay where
the photo decides (:func:`card_cover`): chosen on the 14 library cut-outs, whose alpha is exact (learned route,
median error 0.5: 13.7 %, 0.7: 11.7 %, 0.85: 10.8 %, 0.95: 10.7 % but a sparse birch loses cards it needs)."""


CARVE_BRIDGE = 0.05
"""Longest stretch of branch, as a share of the tree's height, that may run outside the photo's silhouette
between two stretches inside it and stay (:func:`carve_to_silhouette`): a limb crossing a gap of the mask. A
longer excursion is a wire looping round the crown's outline in the photo's view: it goes, and the branch past
it hangs from the node before it."""


OUTLINE_CLOSING = 0.04
"""Radius, as a share of the mask's height, of the closing that makes the tree's outline from its mask for
:func:`carve_to_silhouette`'s wires: the open lower crown, where the mask shows thin limbs only, lies within it."""


def carve_to_silhouette(skeleton, foliage, camera, mask: np.ndarray, *, margin: int = 1,
                        cover: float = CARD_COVER, offset: tuple = (0, 0), bridge: float = CARVE_BRIDGE):
    """The tree cut to the cone of its silhouette: branch ends and cards outside ``mask``'s outline go.

    A node stays while it or a node further on its branches projects inside ``mask`` closed and
    grown by ``margin`` pixels: a branch ends where it leaves the silhouette for good, and a limb
    across a hole of the crown is kept whole. A stretch of branch outside the outline (the holes
    filled) stays only when short (at most ``bridge`` times the tree's height along it) between
    two stretches inside: a limb crossing a narrow gap of the mask. A longer one is a wire looping
    round the crown in the photo's view: it goes, and the branch past it hangs, where it is, from
    the node before it, if the straight limb between them lies within the outline (else it goes
    too). The trunk (order 0) always stays, as a mask may miss part of it. A card stays when its node stays and at least ``cover`` of its
    square, drawn where it projects (its edge at its own depth), lies on the mask: a card whose
    centre alone is inside reaches half its edge past the outline, or over a gap between two
    whorls (on the 14 library cut-outs, whose alpha is exact, keeping cards by their centre on
    the outline grown by half a card made the learned route's front 17 % larger than the tree at
    the median, 40 % on a pine). Their ``node`` indices follow the pruned skeleton.

    Parameters
    ----------
    skeleton : TreeSkeleton
    foliage : Foliage
    camera : Camera
        The photo's camera; ``mask`` is its image.
    mask : ndarray, shape (H, W), bool
        The camera's image, or with ``offset`` a larger canvas around it.
    margin : int
        Pixels the branches' outline is closed and grown by.
    cover : float
        Share of a card's square that must lie on ``mask`` for the card to stay.
    offset : (int, int)
        ``(top, left)``: the camera's pixel (u, v) is ``mask[v + top, u + left]`` (a crown continued
        past the frame, :func:`treeform.crown.frame.beyond_frame`).
    bridge : float
        Longest outside stretch kept, as a share of the tree's height (0: none; a large number:
        every branch that comes back inside stays whole).

    Returns
    -------
    (TreeSkeleton, Foliage)

    Examples
    --------
    >>> from treeform.structures import Camera, Foliage, TreeSkeleton
    >>> cam = Camera(100, 100, 40.0, (0, 2, 10.0), (0, 2, 0), (0, 1, 0))
    >>> sk = TreeSkeleton(np.array([[0, 0, 0], [0, 2, 0], [3, 3, 0], [0.3, 3, 0.]]), np.array([-1, 0, 1, 1]),
    ...                   order=np.array([0, 0, 1, 1]))
    >>> f = Foliage([[3, 3, 0], [0.3, 3, 0]], [[0, 0, 1]] * 2, [[0, 1, 0]] * 2, [0.2] * 2, [[1, 1, 1]] * 2, [2, 3])
    >>> m = np.zeros((100, 100), bool); m[10:95, 40:60] = True  # a narrow tree: the limb at x = 3 m is outside
    >>> sk2, f2 = carve_to_silhouette(sk, f, cam, m)
    >>> sk2.n_nodes, f2.node.tolist()
    (3, [2])
    """
    from dataclasses import replace

    import scipy.ndimage as ndi

    margin = max(1, int(margin))
    mask = np.asarray(mask, bool)
    disk = np.hypot(*np.mgrid[-margin:margin + 1, -margin:margin + 1]) <= margin
    grown = ndi.binary_dilation(ndi.binary_closing(mask, disk, border_value=0), disk)
    inside = visual_hull_contains(camera, grown, skeleton.positions, offset=offset) | (skeleton.order == 0)
    par = skeleton.parent
    back = inside.copy()  # a node inside, or one further on its branches is
    for i in range(skeleton.n_nodes - 1, 0, -1):  # children come after their parents
        if back[i]:
            back[par[i]] = True
    # path length outside the outline (the mask closed over its gaps and holes: a limb through the open
    # lower crown, or across a hole, stays), from the last node inside above (up) and to the next one inside
    # further on (down)
    rows = np.flatnonzero(mask.any(axis=1))
    r = max(1, int(round(OUTLINE_CLOSING * (rows[-1] - rows[0] + 1)))) if len(rows) else 1
    ball = np.hypot(*np.mgrid[-r:r + 1, -r:r + 1]) <= r
    outline = ndi.binary_fill_holes(ndi.binary_closing(np.pad(grown, r + 1), ball)[r + 1:-(r + 1), r + 1:-(r + 1)])
    within = visual_hull_contains(camera, outline, skeleton.positions, offset=offset)
    step = np.zeros(skeleton.n_nodes)
    step[1:] = np.linalg.norm(skeleton.positions[1:] - skeleton.positions[par[1:]], axis=1)
    up = np.where(within, 0.0, np.inf)
    down = np.where(within, 0.0, np.inf)
    trunk = skeleton.order == 0
    for i in range(1, skeleton.n_nodes):  # parents come first
        if not within[i] and not trunk[i]:  # (the trunk outside the outline anchors nothing)
            up[i] = up[par[i]] + step[i]
    for i in range(skeleton.n_nodes - 1, 0, -1):
        if not within[par[i]]:
            down[par[i]] = min(down[par[i]], down[i] + step[i])
    height = float(np.ptp(skeleton.positions[:, 1])) if skeleton.n_nodes > 1 else 0.0
    # (a stretch with nothing within the outline above it but a trunk outside it -- the way up from a trunk the
    # mask missed, or from a base put in the wrong place -- is not a wire: it stays where it leads inside)
    wire = back & ~inside & np.isfinite(up) & (up + down > check_positive(bridge, "bridge", allow_zero=True) * height)
    # a wire's nodes go and the branch past it hangs, where it is, from the node before it -- where the
    # straight limb between them lies inside the silhouette (else it would only be a shorter wire: it goes)
    keep = back & ~wire
    rejoin = np.flatnonzero(keep & (par >= 0) & ~keep[np.maximum(par, 0)])
    if len(rejoin):
        anc = skeleton.nearest_kept(keep)[par[rejoin]]  # the node before the wire
        t = np.linspace(0.0, 1.0, 9)[1:-1, None, None]
        chord = (1 - t) * skeleton.positions[anc] + t * skeleton.positions[rejoin]
        on = visual_hull_contains(camera, outline, chord.reshape(-1, 3), offset=offset).reshape(len(t), -1).all(0)
        cut = np.zeros(skeleton.n_nodes, bool)
        cut[rejoin[~on]] = True
        for i in range(1, skeleton.n_nodes):  # what grows past a rejoin that goes, goes with it
            cut[i] |= cut[par[i]]
        keep &= ~cut
    skeleton, new = skeleton.splice(keep)
    if len(foliage):
        old = foliage.node
        node = np.where(old >= 0, new[np.maximum(old, 0)], -1)
        kept = ((old < 0) | (node >= 0)) & (card_cover(camera, mask, foliage, offset=offset) >= cover)
        foliage = replace(foliage.subset(kept), node=node[kept])
    return skeleton, foliage


def card_cover(camera, mask: np.ndarray, foliage, offset: tuple = (0, 0)) -> np.ndarray:
    """(M,) share of each card's square, drawn where the card projects, that lies on ``mask``.

    The square is centred on the card's projected centre, its edge the card's edge at the card's
    depth (at least a pixel); pixels outside ``mask`` count as off it; a card behind the
    camera covers nothing. Summed over an integral image: O(1) a card. ``mask`` is the camera's
    image, or with ``offset`` = ``(top, left)`` a larger canvas around it (the camera's pixel
    (u, v) is ``mask[v + top, u + left]``, as in :func:`visual_hull_contains`: a crown continued
    past the frame by :func:`treeform.crown.frame.beyond_frame` keeps its cards there).

    Examples
    --------
    >>> from treeform.structures import Camera, Foliage
    >>> cam = Camera(100, 100, 90.0, (0, 0, 10.0), (0, 0, 0), (0, 1, 0))   # 5 px per metre at the origin
    >>> f = Foliage([[0, 0, 0], [2, 0, 0]], [[0, 0, 1]] * 2, [[0, 1, 0]] * 2, [2.0] * 2, [[1, 1, 1]] * 2)
    >>> m = np.zeros((100, 100), bool); m[:, :60] = True                   # the mask ends at u = 60
    >>> card_cover(cam, m, f).round(2).tolist()                            # inside; half over the edge
    [1.0, 0.5]
    >>> wide = np.zeros((100, 120), bool); wide[:, :80] = True             # the same, 20 px more canvas left
    >>> card_cover(cam, wide, f, offset=(0, 20)).round(2).tolist()
    [1.0, 0.5]
    """
    import cv2

    mask = np.asarray(mask, bool)
    h, w = mask.shape
    n = len(foliage)
    if n == 0:
        return np.zeros(0)
    uvz = camera.project(foliage.positions)
    z = uvz[:, 2]
    front = z > 1e-9
    half = 0.5 * np.asarray(foliage.size, np.float64) * camera.focal / np.where(front, z, 1.0)
    half = np.maximum(half, 0.5)
    u = np.where(front, uvz[:, 0] + int(offset[1]), -1e9)
    v = np.where(front, uvz[:, 1] + int(offset[0]), -1e9)
    lo_u, hi_u = np.floor(u - half + 0.5), np.floor(u + half + 0.5)  # pixels [lo, hi) of the square
    lo_v, hi_v = np.floor(v - half + 0.5), np.floor(v + half + 0.5)
    area = np.maximum(hi_u - lo_u, 1.0) * np.maximum(hi_v - lo_v, 1.0)
    x0, x1 = (np.clip(a, 0, w).astype(np.int64) for a in (lo_u, hi_u))
    y0, y1 = (np.clip(a, 0, h).astype(np.int64) for a in (lo_v, hi_v))
    ii = cv2.integral(mask.astype(np.uint8))  # (h + 1, w + 1): sums of mask[:y, :x]
    on = ii[y1, x1] - ii[y0, x1] - ii[y1, x0] + ii[y0, x0]
    return np.where(front, on / area, 0.0)


def fill_silhouette(skeleton, foliage, camera, mask, rbv, *, mpp: float, depth_samples: int = 24, seed=0):
    """``foliage`` plus cards where ``mask`` shows the tree and no card projects.

    The grown crown fills its RBV, not the photo's outline: where the mask has pixels more
    than half a card from every card's centre, new cards are laid on a grid of a card's
    size, each at a random depth along its pixel's ray where the ray runs inside the RBV (where
    it misses it, within the mask's row revolved about the row's centre, as seed 004 §3.5
    revolves the crown), hung on the nearest twig
    (:func:`~treeform.growth.leaves.attach_leaves`).

    Parameters
    ----------
    skeleton : TreeSkeleton
    foliage : Foliage
        The cards so far (at least one: their median size is the new cards' size).
    camera : Camera
        The photo's camera; ``mask`` is its image.
    mask : ndarray, shape (H, W), bool
        Where the photo shows leaves.
    rbv : RadialBoundingVolume
        The crown's volume, in the camera's world.
    mpp : float
        Metres per pixel on the plane through the volume's axis.
    depth_samples : int
        Points tried along each ray.
    seed : int

    Returns
    -------
    Foliage
        ``foliage`` first, then the new cards (tinted with ``foliage``'s median colour).
    """
    import scipy.ndimage as ndi

    from treeform.crown.layout import row_extents
    from treeform.growth.leaves import attach_leaves
    from treeform.structures import Foliage

    rng = np.random.default_rng([int(seed), 7])
    size = float(np.median(foliage.size))
    r = max(1.0, 0.5 * size / mpp)  # a card's half edge in pixels
    h, w = mask.shape
    uv = camera.project(foliage.positions)[:, :2]
    centres = np.zeros(mask.shape, bool)
    ok = (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)
    centres[uv[ok, 1].astype(np.int64), uv[ok, 0].astype(np.int64)] = True
    holes = mask & (ndi.distance_transform_edt(~centres) > r)
    step = max(1, int(round(r)))
    grid = np.zeros_like(holes)
    oy, ox = rng.integers(0, step, 2)
    grid[oy::step, ox::step] = True
    vs, us = np.nonzero(holes & grid)
    if len(us) == 0:
        return foliage
    # depth: points along each pixel's ray between the RBV's front and back
    us, vs = us + rng.uniform(0, 1, len(us)), vs + rng.uniform(0, 1, len(vs))
    reach = float(rbv.physical_radii.max())
    cam_z = float(camera.position[2])
    depths = cam_z - np.linspace(reach, -reach, depth_samples)  # along the view axis (the camera looks down -Z)
    pts = camera.unproject(np.repeat(us, depth_samples), np.repeat(vs, depth_samples),
                           np.tile(depths, len(us))).reshape(len(us), depth_samples, 3)
    inside = rbv.contains(pts.reshape(-1, 3)).reshape(len(us), depth_samples)
    has = inside.any(1)
    score = np.where(inside, rng.uniform(0, 1, inside.shape), -1.0)
    chosen = pts[np.arange(len(us)), np.argmax(score, axis=1)]
    if not has.all():  # rays past the RBV: within the silhouette's row revolved about its centre
        miss = np.flatnonzero(~has)
        rows, left, right = row_extents(mask)
        row = np.clip(vs[miss].astype(np.int64), 0, h - 1)
        half = 0.5 * (right[row] - left[row] + 1) * mpp
        dx = (us[miss] - 0.5 * (left[row] + right[row] + 1)) * mpp
        zmax = np.sqrt(np.maximum(half ** 2 - dx ** 2, (0.1 * half) ** 2))
        z = rng.uniform(-1.0, 1.0, len(miss)) * zmax
        chosen[miss] = camera.unproject(us[miss], vs[miss], cam_z - z)
    new = attach_leaves(skeleton, chosen, size=size, center=rbv.origin + [0, 0.6 * rbv.physical_height, 0],
                        scatter=1.4, seed=rng)
    if len(new) == 0:
        return foliage
    color = np.tile(np.median(foliage.color, axis=0), (len(new), 1))
    return Foliage(np.concatenate([foliage.positions, new.positions]), np.concatenate([foliage.normals, new.normals]),
                   np.concatenate([foliage.up, new.up]), np.concatenate([foliage.size, new.size]),
                   np.concatenate([foliage.color, color]), np.concatenate([foliage.node, new.node]))


def foliage_clumps(contains, bounds, spacing: float, *, max_clumps: int = 2000, seed=None) -> np.ndarray:
    """Centres of a crown's foliage clumps: blue-noise points about ``spacing`` apart inside it.

    A real crown's leaves grow in clumps at the ends of its limbs, with air between them
    (from the side a crown shows lobes, gaps and the limbs inside). The clumps are spread
    evenly (:func:`treeform.growth.sampling.blue_noise_points`), one per ``spacing**3`` of
    the crown's volume (estimated from 4,000 uniform probes of ``bounds``).

    Parameters
    ----------
    contains : callable
        ``contains(points (N, 3)) -> (N,) bool``, the crown's volume.
    bounds : (array_like (3,), array_like (3,))
        A box around it.
    spacing : float
        Mean distance between neighbouring clumps, in the points' units.
    max_clumps : int
        At most this many (a volume far longer than wide, where ``spacing`` is set by its
        mean radius, then gets wider spacing instead of a million clumps).
    seed : int or Generator, optional

    Returns
    -------
    ndarray, shape (K, 3)
        4 to ``max_clumps`` centres (fewer only if the volume holds fewer).

    Examples
    --------
    >>> c = foliage_clumps(lambda p: np.linalg.norm(p, axis=1) < 1, ([-1] * 3, [1] * 3), 0.5, seed=0)
    >>> 25 <= len(c) <= 40, bool(np.linalg.norm(c, axis=1).max() < 1)
    (True, True)
    """
    from treeform.growth.sampling import blue_noise_points

    if not spacing > 0:
        raise InputError(f"spacing: expected a positive distance, got {spacing}")
    rng = as_rng(seed)
    lo, hi = (np.asarray(b, np.float64).reshape(3) for b in bounds)
    probe = rng.uniform(lo, hi, size=(4000, 3))
    volume = float(np.prod(np.maximum(hi - lo, 0.0))) * float(np.mean(contains(probe)))
    n = int(np.clip(round(volume / spacing ** 3), 4, max(4, int(max_clumps))))
    return blue_noise_points(contains, (lo, hi), n, seed=rng)


def clump_density(points: np.ndarray, centres: np.ndarray, sigma: float) -> np.ndarray:
    """Foliage density in (0, 1] at ``points``: ``exp(-d^2 / (2 sigma^2))``, d to the nearest clump centre.

    Examples
    --------
    >>> clump_density(np.array([[0, 0, 0], [1, 0, 0.]]), np.zeros((1, 3)), 1.0).round(3).tolist()
    [1.0, 0.607]
    """
    from scipy.spatial import cKDTree

    pts = check_array(points, "points", shape=(None, 3)).astype(np.float64)
    ctr = check_array(centres, "centres", shape=(None, 3), min_size=1).astype(np.float64)
    if not sigma > 0:
        raise InputError(f"sigma: expected a positive width, got {sigma}")
    d, _ = cKDTree(ctr).query(pts)
    return np.exp(-0.5 * (d / sigma) ** 2)


def thinned(contains, density, *, seed=None):
    """``contains`` that also keeps each point with probability ``density(point)`` (rejection).

    Turns a volume test into one that samplers (:func:`sample_rdm_shell`,
    :func:`treeform.growth.sampling.blue_noise_points`) use to draw points with that density
    inside the volume; same seed and calls, same answers.

    Examples
    --------
    >>> keep = thinned(lambda p: p[:, 0] > 0, lambda p: np.full(len(p), 0.5), seed=0)
    >>> ok = keep(np.ones((1000, 3)))
    >>> bool(400 < ok.sum() < 600), bool(keep(-np.ones((5, 3))).any())
    (True, False)
    """
    rng = as_rng(seed)

    def keep(points):
        ok = np.asarray(contains(points), bool).copy()
        if ok.any():
            ok[ok] = rng.random(int(ok.sum())) < density(points[ok])
        return ok
    return keep
