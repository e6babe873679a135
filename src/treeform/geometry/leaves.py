"""Leaves: procedural alpha-masked leaf textures and one textured quad (card) per leaf.

Conifer kinds (needle clusters, scale sprays) are drawn by :mod:`treeform.geometry.needles`.
"""

from __future__ import annotations

import functools

import numpy as np

from treeform._shared.checks import check_choice
from treeform._shared.errors import InputError
from treeform._shared.rng import as_rng
from treeform.geometry.textures import LEAF_TEXTURE_SIZE
from treeform.structures.foliage import Foliage
from treeform.structures.mesh import Material, MeshPart

__all__ = ["CLUSTER_COVERAGE", "TEXTURE_KINDS", "card_frames", "leaf_cards", "leaf_material", "leaf_texture",
           "card_quads", "opaque_cards", "texture_coverage"]

TEXTURE_KINDS = ("cluster", "leaf", "needles", "scales")
"""Kinds of :func:`leaf_texture`: a broadleaf cluster, one leaf, a needle cluster, a scale spray."""

CLUSTER_COVERAGE = 0.65
"""Target opaque fraction (alpha > 0.5) of a ``kind="cluster"`` texture."""

_BASE_RGB = np.array([0.90, 0.96, 0.86])  # light grey-green: the card colour tints it
_STEM_RGB = np.array([0.80, 0.82, 0.70])


def texture_coverage(texture: np.ndarray) -> float:
    """Fraction of texels with alpha > 0.5 in an (H, W, 4) uint8 texture."""
    texture = np.asarray(texture)
    if texture.ndim != 3 or texture.shape[2] != 4:
        raise InputError(f"texture: expected an (H, W, 4) array, got shape {texture.shape}")
    return float(np.mean(texture[..., 3] > 127))


def card_quads(part: MeshPart) -> tuple[np.ndarray, np.ndarray] | None:
    """An alpha-textured part's quads: ``(positions (Q, 4, 3), uvs (Q, 4, 2))`` float64, or None.

    The part must hold quads of 4 consecutive vertices drawn as triangles (0, 1, 2) and
    (0, 2, 3), UVs and an (H, W, 4) texture, as :func:`leaf_cards` and the photo-leaf atlas
    write them; None for anything else.
    """
    tex, uv = part.material.texture, part.uvs
    n_v = part.n_vertices
    if tex is None or np.ndim(tex) != 3 or np.shape(tex)[2] != 4 or uv is None or n_v == 0 or n_v % 4:
        return None
    n = n_v // 4
    idx = np.asarray(part.indices, np.int64).reshape(-1)
    if idx.size != 6 * n or not np.array_equal(idx.reshape(n, 6) - 4 * np.arange(n)[:, None],
                                               np.broadcast_to([0, 1, 2, 0, 2, 3], (n, 6))):
        return None
    return np.asarray(part.positions, np.float64).reshape(n, 4, 3), np.asarray(uv, np.float64).reshape(n, 4, 2)


def opaque_cards(part: MeshPart) -> np.ndarray | None:
    """An alpha-tested part's cards shrunk to the opaque box of their texture, as (V, 3) positions.

    A leaf card is a quad whose texture is transparent around the leaf or cluster it shows; what
    ignores alpha (a radial distance map rasterized from the triangles, a bounding volume) sees
    the whole quad and stands out by those margins. Each card's corners are moved, within its
    own plane, to the corners of the box holding the texels of its tile (its corners' UV
    rectangle: its own tile of an atlas, or the whole texture) whose alpha passes the
    material's cutoff; a card with no such texel shrinks to its centre.

    Parameters
    ----------
    part : MeshPart
        Quads of 4 consecutive vertices drawn as triangles (0, 1, 2) and (0, 2, 3), with UVs on
        the corners of an axis-aligned rectangle and an (H, W, 4) texture, as :func:`leaf_cards`
        and the photo-leaf atlas write them.

    Returns
    -------
    ndarray, shape (V, 3), float64, or None
        The moved positions (UVs, indices unchanged); None when ``part`` is not such a set of
        cards (no texture with alpha, no UVs, other triangles).

    Examples
    --------
    A card whose texture is opaque only in its left half keeps that half:

    >>> tex = np.zeros((8, 8, 4), np.uint8); tex[:, :4, 3] = 255
    >>> pos = np.array([[0, 0, 0], [2, 0, 0], [2, 2, 0], [0, 2, 0]], float)
    >>> uv = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)
    >>> part = MeshPart(pos, np.tile([0.0, 0.0, 1.0], (4, 1)), uv, np.ones((4, 4)), np.array([[0, 1, 2], [0, 2, 3]]),
    ...                 material=Material(texture=tex, alpha_mode="MASK"))
    >>> opaque_cards(part)[:, 0].tolist()
    [0.0, 1.0, 1.0, 0.0]
    """
    quads = card_quads(part)
    if quads is None:
        return None
    P, uv = quads
    tex = part.material.texture
    lo, hi = uv.min(1), uv.max(1)
    span = hi - lo
    if np.any(span <= 0):
        return None
    s = (uv - lo[:, None]) / span[:, None]  # each corner's place in its tile: 0 or 1 along u and v
    corner = np.rint(s).astype(np.int64)
    if np.abs(s - corner).max() > 1e-3 or np.any(np.sort(corner[..., 0] + 2 * corner[..., 1], axis=1) != [0, 1, 2, 3]):
        return None
    H, W = tex.shape[:2]
    cutoff = float(part.material.alpha_cutoff if part.material.alpha_cutoff is not None else 0.5)
    opaque = np.asarray(tex)[..., 3] >= cutoff * 255.0
    tiles, inverse = np.unique(np.round(np.c_[lo, hi] * 65536.0).astype(np.int64), axis=0, return_inverse=True)
    tile_box = np.full((len(tiles), 4), 0.5)  # (s0, s1, t0, t1): the opaque box in tile coordinates
    for k, key in enumerate(tiles):
        u0, v0, u1, v1 = key / 65536.0
        c0, r0 = max(0, int(np.floor(u0 * W))), max(0, int(np.floor(v0 * H)))
        a = opaque[r0:min(H, max(int(np.ceil(v1 * H)), r0 + 1)), c0:min(W, max(int(np.ceil(u1 * W)), c0 + 1))]
        rows, cols = np.flatnonzero(a.any(1)), np.flatnonzero(a.any(0))
        if rows.size:  # else the card shrinks to its centre
            uu = (c0 + np.array([cols[0], cols[-1] + 1])) / W
            vv = (r0 + np.array([rows[0], rows[-1] + 1])) / H
            tile_box[k] = np.clip(np.r_[(uu - u0) / (u1 - u0), (vv - v0) / (v1 - v0)], 0.0, 1.0)
    box = tile_box[inverse.reshape(-1)]
    # the card's corners by place: P[i, j] at s = i along u, t = j along v; positions bilinear in (s, t)
    order = np.argsort(corner[..., 0] + 2 * corner[..., 1], axis=1)
    Q = np.take_along_axis(P, order[..., None], axis=1)  # (n, 4, 3): (0, 0), (1, 0), (0, 1), (1, 1)
    ss = box[:, None, 0] + s[..., 0] * (box[:, None, 1] - box[:, None, 0])
    tt = box[:, None, 2] + s[..., 1] * (box[:, None, 3] - box[:, None, 2])
    out = ((1 - ss) * (1 - tt))[..., None] * Q[:, None, 0] + (ss * (1 - tt))[..., None] * Q[:, None, 1] \
        + ((1 - ss) * tt)[..., None] * Q[:, None, 2] + (ss * tt)[..., None] * Q[:, None, 3]
    return out.reshape(-1, 3)


# --------------------------------------------------------------------------- leaf layout
def _layout(rng: np.random.Generator, kind: str) -> dict:
    """Leaf blades in texture units (x right, y down, [0, 1]²): base, unit direction, length."""
    if kind == "leaf":
        base = np.array([[0.5, 0.90]])
        direc = np.array([[0.0, -1.0]])
        length = np.array([0.84])
        reach = length
        stems = np.array([[0.5, 0.995, 0.5, 0.90, 0.011]])
        width = np.array([0.40])
    else:
        n_out = int(rng.integers(9, 12))  # long blades reaching for the border (corners too)
        n_in = int(rng.integers(5, 8))  # shorter blades on top, filling the middle
        n = n_out + n_in
        centre = np.array([0.5, 0.5]) + rng.uniform(-0.03, 0.03, 2)
        ang = np.concatenate([
            np.linspace(0.0, 2.0 * np.pi, n_out, endpoint=False) + rng.uniform(0, 2 * np.pi)
            + rng.uniform(-0.3, 0.3, n_out) * (2 * np.pi / n_out),
            np.linspace(0.0, 2.0 * np.pi, n_in, endpoint=False) + rng.uniform(0, 2 * np.pi)
            + rng.uniform(-0.3, 0.3, n_in) * (2 * np.pi / n_in),
        ])
        direc = np.stack([np.cos(ang), np.sin(ang)], axis=1)
        # blade bases scattered around the centre (leaves on short shoots), outwards
        rad = np.sqrt(rng.uniform(0, 1, n)) * 0.08
        base = centre + rad[:, None] * direc + rng.uniform(-0.02, 0.02, (n, 2))
        # length: a fraction of the distance to the square's border along the blade, so the
        # cluster fills the square without being cut by its edge
        with np.errstate(divide="ignore", invalid="ignore"):
            tx = np.where(direc[:, 0] > 0, (0.985 - base[:, 0]) / direc[:, 0],
                          np.where(direc[:, 0] < 0, (0.015 - base[:, 0]) / direc[:, 0], np.inf))
            ty = np.where(direc[:, 1] > 0, (0.985 - base[:, 1]) / direc[:, 1],
                          np.where(direc[:, 1] < 0, (0.015 - base[:, 1]) / direc[:, 1], np.inf))
        frac = np.concatenate([rng.uniform(0.82, 0.98, n_out), rng.uniform(0.45, 0.65, n_in)])
        reach = np.minimum(tx, ty)
        length = reach * frac
        width = rng.uniform(0.26, 0.36, n)  # half-width/length; scaled; scaled to reach the coverage
        stems = [[centre[0], centre[1], 0.5 + rng.uniform(-0.05, 0.05), 0.995, 0.011]]
        stems += [[centre[0], centre[1], bx, by, 0.006] for bx, by in base]
        stems = np.array(stems)
    n = len(length)
    return {
        "base": base, "dir": direc, "length": length, "reach": reach, "width": width, "stems": stems,
        "shade": rng.uniform(0.84, 1.0, n),
        "hue": rng.uniform(-0.03, 0.03, (n, 3)),
        "fold": rng.uniform(-0.08, 0.08, n),
        "tip_p": rng.uniform(0.55, 0.75, n),
        "veins": rng.integers(6, 10, n),
    }


def _profile(x: np.ndarray, p: float) -> np.ndarray:
    """Leaf half-width profile along the blade, 0 at base and tip, max 1 (ovate, pointed tip)."""
    q = 1.0
    xm = p / (p + q)
    xc = np.clip(x, 0.0, 1.0)
    return xc**p * (1.0 - xc) ** q / (xm**p * (1.0 - xm) ** q)


def _bezier_profile(x: np.ndarray, ctrl) -> np.ndarray:
    """Leaf half-width along the blade from a cubic Bézier outline (seed 004 §4), max 1.

    The margin runs from the base ``(0, 0)`` over the control points ``(a1, b1)``, ``(a2, b2)``
    to the tip ``(1, 0)`` (``0 <= a1 <= a2 <= 1``, so the curve is a function of x); the other
    margin is its mirror image across the midrib.
    """
    a1, b1, a2, b2 = ctrl
    t = np.linspace(0.0, 1.0, 97)
    mt = 1.0 - t
    bx = 3 * mt * mt * t * a1 + 3 * mt * t * t * a2 + t**3
    by = 3 * mt * mt * t * b1 + 3 * mt * t * t * b2
    return np.interp(np.clip(x, 0.0, 1.0), bx, by / by.max())


def _render(layout: dict, res: int, width_scale: float, *, shade: bool, texel: float = 0.0):
    """Rasterize the layout at ``res``²; returns (alpha (res, res) float, rgb (res, res, 3) or None).

    ``texel`` is the output texel size (texture units) that sets the vein and midrib widths.
    """
    alpha = np.zeros((res, res))
    rgb = np.empty((res, res, 3)) if shade else None
    if shade:
        rgb[:] = _BASE_RGB
    px = 1.0 / res
    # twig / petioles (under the blades)
    for x0, y0, x1, y1, hw in layout["stems"]:
        _stroke(alpha, rgb, (x0, y0), (x1, y1), hw, res)
    for i in range(len(layout["length"])):
        b, d, L = layout["base"][i], layout["dir"][i], layout["length"][i]
        w = min(0.45, layout["width"][i] * width_scale)  # max half-width / length
        nrm = np.array([-d[1], d[0]])
        tip = b + L * d
        pad = w * L + 2 * px
        lo = np.floor((np.minimum(b, tip) - pad) * res).astype(int).clip(0, res)
        hi = np.ceil((np.maximum(b, tip) + pad) * res).astype(int).clip(0, res)
        if hi[0] <= lo[0] or hi[1] <= lo[1]:
            continue
        xs = (np.arange(lo[0], hi[0]) + 0.5) * px
        ys = (np.arange(lo[1], hi[1]) + 0.5) * px
        gx, gy = np.meshgrid(xs - b[0], ys - b[1])
        u = (gx * d[0] + gy * d[1]) / L  # along the blade, 0 base .. 1 tip
        v = (gx * nrm[0] + gy * nrm[1]) / L  # across, in leaf lengths
        hw = w * (_bezier_profile(u, layout["bezier"][i]) if "bezier" in layout else _profile(u, layout["tip_p"][i]))
        inside = (u > 0) & (u < 1) & (np.abs(v) < hw)
        win = alpha[lo[1]:hi[1], lo[0]:hi[0]]
        if not shade:
            win[inside] = 1.0
            continue
        u, v, hw = u[inside], v[inside], hw[inside]
        rel = np.abs(v) / np.maximum(hw, 1e-9)  # 0 on the midrib, 1 on the margin
        tone = layout["shade"][i] * (1.0 - 0.10 * rel**2 + layout["fold"][i] * np.sign(v))
        # pinnate veins leave the midrib at an angle towards the tip
        nv = layout["veins"][i]
        phase = (u - 0.3 * np.abs(v) / max(w, 1e-6)) * nv
        dist = np.abs(phase - np.rint(phase)) / nv * L / texel  # in output texels, roughly
        vein = np.exp(-((dist / 0.35) ** 2)) * (rel < 0.92) * (u > 0.06) * (u < 0.93)
        midrib = np.exp(-((np.abs(v) * L / texel / 0.4) ** 2)) * (u < 0.97)
        tone = tone * (1.0 + 0.07 * vein) + 0.10 * midrib
        win_rgb = rgb[lo[1]:hi[1], lo[0]:hi[0]]
        win_rgb[inside] = (_BASE_RGB + layout["hue"][i])[None, :] * tone[:, None]
        win[inside] = 1.0
    return alpha, rgb


def _stroke(alpha, rgb, p0, p1, half_width, res):
    """Draw a straight, slightly tapering stem (half-width in texture units) into alpha/rgb."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    lo = np.floor((np.minimum(p0, p1) - half_width) * res - 1).astype(int).clip(0, res)
    hi = np.ceil((np.maximum(p0, p1) + half_width) * res + 1).astype(int).clip(0, res)
    ys, xs = (np.mgrid[lo[1]:hi[1], lo[0]:hi[0]] + 0.5) / res
    d = p1 - p0
    t = np.clip(((xs - p0[0]) * d[0] + (ys - p0[1]) * d[1]) / max(d @ d, 1e-12), 0, 1)
    dist = np.hypot(xs - p0[0] - t * d[0], ys - p0[1] - t * d[1])
    m = dist < half_width * (1.0 - 0.4 * t)
    alpha[lo[1]:hi[1], lo[0]:hi[0]][m] = 1.0
    if rgb is not None:
        rgb[lo[1]:hi[1], lo[0]:hi[0]][m] = _STEM_RGB


OUTLINES = ("profile", "bezier")
"""Blade outlines of :func:`leaf_texture`: a power-law profile, or cubic Bézier margins (seed 004 §4)."""


def leaf_texture(size: int = LEAF_TEXTURE_SIZE, *, seed=0, kind: str = "cluster", outline: str = "profile") -> np.ndarray:
    """A procedural leaf texture with an alpha mask, for alpha-tested leaf cards.

    ``kind="cluster"``: 14-18 ovate, pointed leaf blades on short petioles radiating from a
    twig at the centre (long ones reaching for the border, shorter ones on top), filling the
    square: the blade width is bisected so the opaque fraction is ``CLUSTER_COVERAGE`` ≈ 0.65
    (0.65 ± 0.005 over 100 seeds at 128²). ``kind="leaf"``: one blade on a petiole, base at the bottom edge, tip
    at the top. Blades have a lighter midrib and pinnate veins and a little per-blade
    shading; colours are light grey-green (luminance ≈ 0.9) so the card's vertex colour
    tints them. ``kind="needles"``: pine-like shoots fanning from a twig, bottle-brushes of
    thin pointed needles (about 0.3 opaque); ``kind="scales"``: a flat, thuja-like spray of
    overlapping scale leaves (about 0.3 opaque) -- see :mod:`treeform.geometry.needles`.
    Edges are antialiased by supersampling (4×4 up to 128², fewer above); transparent texels
    carry the mean leaf colour so filtering leaves no dark fringe.

    Parameters
    ----------
    size : int
        Edge length in texels (>= 8); default 256
        (:data:`~treeform.geometry.textures.LEAF_TEXTURE_SIZE`).
    seed : int or numpy.random.Generator
        Randomness; same seed -> identical texture.
    kind : {"cluster", "leaf", "needles", "scales"}
    outline : {"profile", "bezier"}
        Broadleaf blade margins: an ovate power-law profile, or two mirrored cubic Bézier
        curves from base to tip with random control points per blade (ovate, elliptic,
        obovate and lanceolate blades; seed 004 §4's Bézier leaves).

    Returns
    -------
    ndarray, shape (size, size, 4), uint8
        sRGB colour and alpha (0 outside the leaves, 255 inside).

    Examples
    --------
    >>> t = leaf_texture(64, seed=1)
    >>> 0.55 <= texture_coverage(t) <= 0.75
    True
    """
    if isinstance(size, bool) or not isinstance(size, (int, np.integer)) or size < 8:
        raise InputError(f"size: expected an integer >= 8, got {size!r}")
    check_choice(kind, "kind", TEXTURE_KINDS)
    check_choice(outline, "outline", OUTLINES)
    size = int(size)
    if kind in ("needles", "scales"):
        from treeform.geometry.needles import conifer_texture

        return conifer_texture(size, seed=seed, kind=kind)
    rng = as_rng(seed)
    layout = _layout(rng, kind)
    if outline == "bezier":  # drawn after the layout: the profile textures stay as they were
        n = len(layout["length"])
        layout["bezier"] = np.column_stack([rng.uniform(0.0, 0.35, n), rng.uniform(0.45, 1.0, n),
                                            rng.uniform(0.45, 0.85, n), rng.uniform(0.35, 0.9, n)])
    scale = 1.0
    if kind == "cluster":  # bisect the blade width for the target coverage (a cheap 1x mask)
        res = 96
        for _ in range(4):  # widest blades too sparse: lengthen the short ones and retry
            if _render(layout, res, 10.0, shade=False)[0].mean() >= CLUSTER_COVERAGE:
                break
            layout["length"] = np.minimum(layout["length"] * 1.15, layout["reach"])
        lo, hi = 0.3, 1.7
        for _ in range(12):
            mid = 0.5 * (lo + hi)
            cov = _render(layout, res, mid, shade=False)[0].mean()
            lo, hi = (mid, hi) if cov < CLUSTER_COVERAGE else (lo, mid)
        scale = 0.5 * (lo + hi)
    ss = _supersampling(size)
    alpha, rgb = _render(layout, size * ss, scale, shade=True, texel=1.0 / size)
    return _downsample(alpha, rgb, size, ss)


def _supersampling(size: int) -> int:
    """Sub-samples per texel edge used to antialias a ``size``² texture (4 up to 128², fewer above)."""
    return 4 if size <= 128 else 3 if size <= 256 else 2


def _downsample(alpha: np.ndarray, rgb: np.ndarray, size: int, ss: int) -> np.ndarray:
    """Box-filter a (size·ss)² alpha and RGB raster to a (size, size, 4) uint8 texture.

    Colour is averaged over the covered sub-samples only; transparent texels carry the mean
    colour of the covered ones, so filtering leaves no dark fringe.
    """
    a = alpha.reshape(size, ss, size, ss).mean(axis=(1, 3))
    pre = (rgb * alpha[..., None]).reshape(size, ss, size, ss, 3).sum(axis=(1, 3))
    cnt = alpha.reshape(size, ss, size, ss).sum(axis=(1, 3))
    mean_rgb = (rgb * alpha[..., None]).reshape(-1, 3).sum(0) / max(alpha.sum(), 1.0)
    col = np.where(cnt[..., None] > 0, pre / np.maximum(cnt, 1e-9)[..., None], mean_rgb)
    out = np.empty((size, size, 4), np.uint8)
    out[..., :3] = np.clip(np.rint(col * 255.0), 0, 255).astype(np.uint8)
    out[..., 3] = np.clip(np.rint(a * 255.0), 0, 255).astype(np.uint8)
    return out


@functools.lru_cache(maxsize=8)
def _default_leaf(size: int, seed: int, kind: str) -> np.ndarray:
    t = leaf_texture(size, seed=seed, kind=kind)
    t.flags.writeable = False
    return t


def leaf_material(texture=None, *, seed=0) -> Material:
    """The ``"leaves"`` material: alpha MASK at 0.5, double-sided, the given (or default) texture."""
    if texture is None:
        seed = 0 if isinstance(seed, np.random.Generator) or seed is None else int(seed)
        texture = _default_leaf(LEAF_TEXTURE_SIZE, seed, "cluster").copy()
    else:
        texture = np.asarray(texture)
        if texture.ndim != 3 or texture.shape[2] != 4 or texture.dtype != np.uint8:
            raise InputError(f"texture: expected an (H, W, 4) uint8 array, got {texture.shape} {texture.dtype}")
    return Material(name="leaves", base_color=(1.0, 1.0, 1.0, 1.0), texture=texture, alpha_mode="MASK",
                    alpha_cutoff=0.5, double_sided=True, roughness=0.8, metallic=0.0)


# --------------------------------------------------------------------------- cards
def card_frames(foliage: Foliage) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each card's unit normal, in-plane up and right (``up × normal``) vectors, as :func:`leaf_cards` builds them.

    ``up`` is the foliage's up vector orthogonalised against the normal (any in-plane
    direction where the two are parallel).

    Returns
    -------
    normal, up, right : ndarray, shape (M, 3)

    Examples
    --------
    >>> f = Foliage([[0, 1, 0]], [[0, 0, 2]], [[0, 1, 1]], [0.2], [[0.2, 0.5, 0.1]])
    >>> [a.round(3).tolist() for a in card_frames(f)]
    [[[0.0, 0.0, 1.0]], [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]]]
    """
    m = len(foliage)
    n = foliage.normals.astype(np.float64)
    nl = np.linalg.norm(n, axis=1, keepdims=True)
    if m and np.any(nl < 1e-12):
        raise InputError("foliage.normals: contains a zero-length normal")
    n = n / np.where(nl > 0, nl, 1.0)
    up = foliage.up - np.sum(foliage.up * n, axis=1, keepdims=True) * n
    ul = np.linalg.norm(up, axis=1, keepdims=True)
    bad = ul[:, 0] < 1e-9
    if np.any(bad):  # up parallel to the normal: any in-plane direction will do
        ref = np.where(np.abs(n[bad, 1:2]) < 0.9, [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]])
        up[bad] = ref - np.sum(ref * n[bad], axis=1, keepdims=True) * n[bad]
        ul[bad] = np.linalg.norm(up[bad], axis=1, keepdims=True)
    up = up / ul
    return n, up, np.cross(up, n)


def leaf_cards(foliage: Foliage, *, texture=None, size_scale: float = 1.0) -> MeshPart:
    """One textured square quad per leaf.

    Card ``i`` is centred at ``foliage.positions[i]``, spanned by its ``up`` vector
    (orthogonalized against the normal) and ``right = up × normal`` (the span of
    ``normal × up``, oriented so the texture reads unmirrored from the front), with edge length
    ``foliage.size[i] * size_scale``. Triangles wind counter-clockwise seen from the normal
    side. UV (0, 0) is the top-left of the texture (glTF), at ``-right + up``; with
    ``foliage.uv`` each card spans its own rectangle of the texture (an atlas) instead.

    Parameters
    ----------
    foliage : Foliage
        M leaves.
    texture : ndarray, shape (H, W, 4), uint8, optional
        Leaf texture; default ``leaf_texture(256, seed=0, kind="cluster")``.
    size_scale : float or ndarray of shape (M,)
        Multiplier of the card sizes (the LOD uses it to enlarge subsampled leaves).

    Returns
    -------
    MeshPart
        Named ``"leaves"``: 4·M vertices, 2·M triangles; normals = card normal, colours =
        (leaf colour, 1); material ``"leaves"`` (MASK, cutoff 0.5, double-sided).

    Examples
    --------
    >>> f = Foliage([[0, 1, 0]], [[0, 0, 1]], [[0, 1, 0]], [0.2], [[0.2, 0.5, 0.1]])
    >>> p = leaf_cards(f)
    >>> p.n_vertices, p.n_triangles
    (4, 2)
    """
    if not isinstance(foliage, Foliage):
        raise InputError(f"foliage: expected a Foliage, got {type(foliage).__name__}")
    material = leaf_material(texture)
    m = len(foliage)
    scale = np.asarray(size_scale, np.float64)
    if scale.ndim not in (0, 1) or (scale.ndim == 1 and len(scale) != m) or not np.all(np.isfinite(scale)) \
            or np.any(scale <= 0):
        raise InputError(f"size_scale: expected a positive number or an array of {m} positive numbers")
    from treeform.geometry._kernels import card_corners

    half = np.ascontiguousarray(np.broadcast_to(0.5 * foliage.size * scale, (m,)), np.float64)
    # the frames of card_frames and the corners (0 bottom-left, 1 bottom-right, 2 top-right,
    # 3 top-left: c -+ half·right -+ half·up), compiled
    pos, nrm, ok = card_corners(foliage.positions, foliage.normals, foliage.up, half)
    if not ok:
        raise InputError("foliage.normals: contains a zero-length normal")
    if foliage.uv is None:
        uv = np.tile(np.array([[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]], np.float32), (m, 1))
    else:  # each card its own rectangle (u0, v0, u1, v1) of an atlas
        r = foliage.uv
        uv = np.stack([r[:, [0, 3]], r[:, [2, 3]], r[:, [2, 1]], r[:, [0, 1]]], axis=1).reshape(-1, 2)
    col = np.empty((m, 4, 4), np.float32)
    col[..., :3] = foliage.color[:, None, :]
    col[..., 3] = 1.0
    faces = (4 * np.arange(m, dtype=np.uint32))[:, None] + np.array([0, 1, 2, 0, 2, 3], np.uint32)
    return MeshPart(pos, nrm, uv, col.reshape(-1, 4), faces.reshape(-1, 3), material, "leaves")
