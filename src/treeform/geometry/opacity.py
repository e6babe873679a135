"""The opacity grid of a tree mesh: leaf and wood area per voxel as an extinction coefficient.

Beer-Lambert in a canopy (Ross 1981; the turbid-medium model of radiative transfer in
vegetation): a ray through a volume of randomly placed thin surfaces of one-sided area
density ``a`` (m^2 per m^3) is blocked with the coefficient ``sigma = G a``, where ``G`` is
the mean projected share of a surface element: 1/2 for thin cards of any orientation (the
mean of ``|cos|``), 1/pi for the closed surface of solid wood seen from its side (an upright
tube's width over its girth; a randomly turned convex body's would be 1/4, Cauchy). Each card's
area is counted where its texture is opaque (its alpha passes the material's cutoff), so a leaf
cluster's transparent margins block nothing.

The relief impostor (:mod:`treeform.render.impostor`) uses the grid to see through a porous
crown: the gaps between clusters that the radial distance map, the crown's outer surface,
fills.

Wood is one opaque body, not a cloud: a trunk narrower than a voxel blocks less than half of a
ray through that voxel and fades from the grid (in pieces, where it crosses from one voxel
column into the next). With the tree's skeleton, the trunk and the thickest limbs become
capsules beside the grid (:func:`wood_capsules`), hit exactly at any distance; their bark is
left out of ``sigma``.
"""

from __future__ import annotations

import numpy as np

from treeform._shared.checks import check_int
from treeform._shared.errors import InputError
from treeform.geometry.leaves import card_quads
from treeform.structures.mesh import Mesh
from treeform.structures.opacity import MAX_WOOD, OpacityGrid, trilinear_corners

__all__ = ["opacity_grid", "wood_capsules", "CARD_SHADOW", "SOLID_SHADOW"]

CARD_SHADOW = 0.5
"""Mean projected share of a thin two-sided card (leaves)."""
SOLID_SHADOW = 1.0 / np.pi
"""Projected share of a closed opaque surface, bark on a tube seen from its side (its width 2r over its
girth 2 pi r): trunks and limbs stand more upright than a random body (1/4, Cauchy)."""
WOOD_MIN_RADIUS = 0.1
"""Thinnest wood kept as a capsule, in voxels: a fifth of a voxel wide, under half a pixel while a voxel
spans two (a tree up to about 200 px tall, farther than the billboard clouds take over); thinner wood
stays in the grid, where a crown's twigs belong."""
_CARD_SAMPLES = 4
"""Samples per card edge: its area is split among 4 x 4 points, each weighted by its texel's alpha."""


def _card_samples(part, n: int):
    """Points (Q * n * n, 3) on each quad of an alpha-tested part and their opaque area (m^2), or None."""
    cards = card_quads(part)
    if cards is None:
        return None
    quads, uv = cards
    tex = part.material.texture
    s = (np.arange(n) + 0.5) / n
    su, sv = (a.ravel() for a in np.meshgrid(s, s))
    w = np.stack([(1 - su) * (1 - sv), su * (1 - sv), su * sv, (1 - su) * sv], 1)  # bilinear over corners 0..3
    pts = np.einsum("sk,qkd->qsd", w, quads)
    uvs = np.einsum("sk,qkd->qsd", w, uv)
    h, wd = tex.shape[:2]
    opaque = tex[..., 3] >= 255.0 * float(part.material.alpha_cutoff)
    col = np.clip(np.floor(uvs[..., 0] * wd).astype(np.int64), 0, wd - 1)
    row = np.clip(np.floor(uvs[..., 1] * h).astype(np.int64), 0, h - 1)
    a, b, c, d = (quads[:, k] for k in range(4))
    area = 0.5 * (np.linalg.norm(np.cross(b - a, c - a), axis=1) + np.linalg.norm(np.cross(c - a, d - a), axis=1))
    return pts.reshape(-1, 3), (opaque[row, col] * (area / (n * n))[:, None]).ravel()


def _triangle_samples(part, voxel: float):
    """Points on every triangle of a part and the area each stands for: a triangle larger than a
    quarter voxel's face is split into m^2 equal parts (m up to 16), each counted at its centroid."""
    v = np.asarray(part.positions, np.float64)[np.asarray(part.indices).reshape(-1, 3)]
    area = 0.5 * np.linalg.norm(np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0]), axis=1)
    m = np.clip(np.ceil(np.sqrt(area / (0.25 * voxel * voxel))), 1, 16).astype(np.int64)
    pts, wts = [], []
    for k in np.unique(m):
        sel = m == k
        # centroids of the k^2 sub-triangles of a triangle split k times along each edge
        bary = []
        for i in range(k):
            for j in range(k - i):
                bary.append(((i + 1 / 3) / k, (j + 1 / 3) / k))
                if i + j < k - 1:
                    bary.append(((i + 2 / 3) / k, (j + 2 / 3) / k))
        bary = np.array(bary)
        wgt = np.c_[1 - bary.sum(1), bary]  # (k^2, 3)
        tri = v[sel]
        pts.append(np.einsum("sk,tkd->tsd", wgt, tri).reshape(-1, 3))
        wts.append(np.repeat(area[sel] / (k * k), len(bary)))
    return np.concatenate(pts), np.concatenate(wts)


def wood_capsules(skeleton, voxel: float, *, max_capsules: int = MAX_WOOD,
                  min_radius: float = WOOD_MIN_RADIUS) -> np.ndarray:
    """The trunk and thickest limbs of a skeleton as at most ``max_capsules`` capsules.

    Chains (:meth:`~treeform.structures.TreeSkeleton.chains`) are taken thickest first, each up to
    where its radius falls under ``min_radius`` voxels; each is cut into straight pieces that stay
    within half a voxel of its nodes, and within their radius (so each node's axis point lies inside
    its capsule), and whose radius changes by less than a third; each piece is a capsule of its
    nodes' mean radius.

    Parameters
    ----------
    skeleton : TreeSkeleton
        In the mesh's frame (metres).
    voxel : float
        The opacity grid's voxel edge, metres: the scale of "thin".
    max_capsules : int
    min_radius : float
        In voxels.

    Returns
    -------
    ndarray, shape (K, 7), float32
        ``(ax, ay, az, bx, by, bz, r)`` rows, thickest chains first.

    Examples
    --------
    A straight trunk of 11 nodes tapering from 20 to 10 cm: a new piece wherever the radius has
    changed by a third of the piece's mean:

    >>> from treeform.structures import TreeSkeleton
    >>> y = np.linspace(0.0, 5.0, 11)
    >>> sk = TreeSkeleton(np.c_[0 * y, y, 0 * y], np.arange(-1, 10), np.linspace(0.2, 0.1, 11), np.zeros(11, np.int32))
    >>> c = wood_capsules(sk, 0.1)
    >>> len(c), float(c[0, 1]), round(float(c[-1, 4]), 6)
    (3, 0.0, 5.0)
    """
    from treeform.structures import TreeSkeleton

    if not isinstance(skeleton, TreeSkeleton):
        raise InputError(f"skeleton: expected a TreeSkeleton, got {type(skeleton).__name__}")
    voxel = float(voxel)
    if not (np.isfinite(voxel) and voxel > 0):
        raise InputError(f"voxel: expected a length > 0, got {voxel}")
    max_capsules = check_int(max_capsules, "max_capsules", 0, MAX_WOOD)
    pos, rad = np.asarray(skeleton.positions, np.float64), np.asarray(skeleton.radius, np.float64)
    rmin = float(min_radius) * voxel
    chains = sorted(skeleton.chains(), key=lambda c: -float(rad[c].max()))
    out = []
    for chain in chains:
        if len(out) >= max_capsules or rad[chain].max() < rmin:
            break
        thin = np.flatnonzero(rad[chain[1:]] < rmin)  # (the first node of a side chain is its parent's)
        chain = chain[:thin[0] + 1] if len(thin) else chain
        s = 0
        while s < len(chain) - 1 and len(out) < max_capsules:
            e = s + 1
            while e + 1 < len(chain) and _fits(pos[chain[s:e + 2]], rad[chain[s:e + 2]], 0.5 * voxel):
                e += 1
            piece = chain[s:e + 1]
            if np.linalg.norm(pos[piece[-1]] - pos[piece[0]]) > 0:
                out.append([*pos[piece[0]], *pos[piece[-1]], float(rad[piece].mean())])
            s = e
    return np.array(out, np.float32).reshape(-1, 7)


def _fits(p: np.ndarray, r: np.ndarray, tol: float) -> bool:
    """Whether the nodes ``p`` (n, 3) lie within ``tol`` and within their mean radius of the segment between
    the first and last, with radii ``r`` within a third of their mean."""
    if np.array_equal(p[0], p[-1]):
        return False
    dist = _segment_distance(p, p[0], p[-1])
    return bool(dist.max() <= min(tol, r.mean()) and r.max() - r.min() <= r.mean() / 3)


def _segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N,) distance of each point (N, 3) to the segment ``a``-``b``."""
    ab = b - a
    t = np.clip((points - a) @ ab / max(float(ab @ ab), 1e-300), 0.0, 1.0)
    return np.linalg.norm(points - (a + t[:, None] * ab), axis=1)


def _in_capsules(points: np.ndarray, capsules: np.ndarray, margin: float) -> np.ndarray:
    """(N,) bool: points within their radius + ``margin`` of any capsule's axis."""
    inside = np.zeros(len(points), bool)
    for c in capsules.astype(np.float64):
        inside |= _segment_distance(points, c[:3], c[3:6]) <= c[6] + margin
    return inside


def _bark_albedo(parts) -> np.ndarray | None:
    """Mean albedo (3,) in [0, 1] of the opaque parts (texture x base colour x vertex colours), or None."""
    cols, wts = [], []
    for p in parts:
        m = p.material
        c = np.asarray(m.base_color, np.float64)[:3].copy()
        if m.texture is not None:
            c *= np.asarray(m.texture, np.float64)[..., :3].reshape(-1, 3).mean(0) / 255.0
        if p.colors is not None and len(p.colors):
            c *= np.asarray(p.colors, np.float64)[:, :3].mean(0)
        cols.append(c)
        wts.append(float(p.n_triangles))
    if not cols or sum(wts) <= 0:
        return None
    return np.clip(np.average(np.array(cols), axis=0, weights=wts), 0.0, 1.0)


def opacity_grid(mesh: Mesh, *, resolution: int = 64, pad: float = 0.02, skeleton=None) -> OpacityGrid:
    """The extinction coefficient of a tree mesh on a cube of ``resolution^3`` voxels.

    Parameters
    ----------
    mesh : Mesh
        The tree (``tree.glb``): alpha-tested quads (leaf cards) count their opaque texels'
        area with :data:`CARD_SHADOW`; other double-sided parts are cards without holes;
        single-sided parts are closed surfaces (:data:`SOLID_SHADOW`).
    resolution : int
        Voxels along the cube's edge (the cube holds the mesh's box with ``pad`` of its largest
        edge to spare on each side).
    pad : float
    skeleton : TreeSkeleton, optional
        The tree's skeleton (``skeleton.json``) in the mesh's frame: its trunk and thickest limbs
        become the grid's capsules (:func:`wood_capsules`, coloured with the mesh's mean bark) and
        the bark around them leaves the grid.

    Returns
    -------
    OpacityGrid
        Each sample's area is spread over the 8 voxels around it (trilinear weights), so a
        linearly filtered read of the grid integrates to the area it holds (for solid parts, a
        voxel's share ``f`` of shadow becomes the optical depth ``-ln(1 - f)`` of one opaque
        element, kept in its own voxel). A solid is counted by its surface: a trunk many voxels
        wide is two walls to a ray through it, and one much thinner than a voxel fades (a 20-m
        oak's 10-cm trunk at 96 voxels shows in pieces).

    Examples
    --------
    A 1 m x 1 m opaque card holds half its area as shadow, wherever it stands:

    >>> from treeform.structures import Material, MeshPart
    >>> pos = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    >>> part = MeshPart(pos, np.tile([0.0, 0.0, 1.0], (4, 1)), np.zeros((4, 2)), np.ones((4, 4)),
    ...                 np.array([[0, 1, 2], [0, 2, 3]]), Material("leaf", double_sided=True))
    >>> g = opacity_grid(Mesh([part]), resolution=8)
    >>> round(float(g.sigma.sum()) * g.voxel ** 3, 3)
    0.5
    """
    if not isinstance(mesh, Mesh):
        raise InputError(f"mesh: expected a treeform Mesh, got {type(mesh).__name__}")
    resolution = check_int(resolution, "resolution", 2, 512)
    parts = [p for p in mesh.parts if p.n_vertices and len(p.indices)]
    if not parts:
        raise InputError("mesh: no triangles to make an opacity grid of")
    pts = np.concatenate([np.asarray(p.positions, np.float64) for p in parts])
    lo, hi = pts.min(0), pts.max(0)
    ext = float(np.max(hi - lo))
    ext = max(ext, 1e-6) * (1.0 + 2.0 * float(pad))
    voxel = ext / resolution
    origin = 0.5 * (lo + hi) - 0.5 * ext
    capsules = None if skeleton is None else wood_capsules(skeleton, voxel)
    thin, solid = [], []  # (points, shadow area): thin cards, closed opaque surfaces
    for p in parts:
        cards = _card_samples(p, _CARD_SAMPLES) if p.material.alpha_mode != "OPAQUE" else None
        if cards is not None:
            thin.append((cards[0], CARD_SHADOW * cards[1]))
            continue
        q, a = _triangle_samples(p, voxel)
        if capsules is not None and len(capsules) and not p.material.double_sided:
            keep = ~_in_capsules(q, capsules, 0.5 * voxel)  # the capsules stand for this bark
            q, a = q[keep], a[keep]
        (thin if p.material.double_sided else solid).append(
            (q, (CARD_SHADOW if p.material.double_sided else SOLID_SHADOW) * a))
    sigma = _splat(thin, origin, voxel, resolution)
    if solid:
        # a solid body is one opaque element, not a cloud of small independent ones: a voxel whose
        # shadow share f it fills (f = sigma * voxel, the mean over directions) lets 1 - f of the light
        # through, optical depth -ln(1 - f) across it, not f (a limb thinner than a voxel stays seen)
        f = np.clip(_splat(solid, origin, voxel, resolution, nearest=True) * voxel, 0.0, 0.95)
        sigma += -np.log1p(-f) / voxel
    bark = _bark_albedo([p for p in parts if p.material.alpha_mode == "OPAQUE" and not p.material.double_sided])
    return OpacityGrid(sigma.astype(np.float32), origin, voxel, capsules, bark)


def _splat(samples, origin, voxel: float, resolution: int, *, nearest: bool = False) -> np.ndarray:
    """Shadow area per volume (N, N, N) of ``(points, area)`` pairs, each sample spread over its 8 voxels
    (or, ``nearest``, kept in its own)."""
    if not samples:
        return np.zeros((resolution,) * 3)
    P = np.concatenate([q for q, _ in samples])
    W = np.concatenate([a for _, a in samples])
    if nearest:
        idx = np.clip(np.floor((P - origin) / voxel).astype(np.int64), 0, resolution - 1)
        flat = np.bincount((idx[:, 2] * resolution + idx[:, 1]) * resolution + idx[:, 0], weights=W,
                           minlength=resolution ** 3)
        return (flat / voxel ** 3).reshape(resolution, resolution, resolution)
    cells, weights = trilinear_corners((P - origin) / voxel, resolution)
    flat = np.bincount(cells.ravel(), weights=(weights * W).ravel(), minlength=resolution ** 3)
    return (flat / voxel ** 3).reshape(resolution, resolution, resolution)
