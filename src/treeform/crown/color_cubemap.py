"""The crown's colour cubemap by patch-based texture synthesis from one view (seed 001 §3.3).

A photo shows less than half of a crown; the hidden parts are assumed to look like the
visible ones. The tree's picture, scaled to a square, is placed on a cross-shaped canvas of
the six cube faces so that it covers the front face (+Z, toward the camera) and about a third
of each neighbouring face; the rest of the cross is synthesized from the picture's own crown
patches (:func:`synthesize`, Efros & Freeman's patch selection with cross-faded overlaps); the
faces are cut out of the cross (OpenGL order, the orientation of
:func:`treeform.structures.rdm.texel_directions`), and a band along each of the seven cube
edges the cross does not join is synthesized again across the edge, so the texture runs on
without a seam over every edge of the cube.

Layout of the cross (columns, rows of face cells): ``-X +Z +X -Z`` in the middle row, ``+Y``
above and ``-Y`` below ``+Z``; image right is world +X, image down is world -Y.
"""

from __future__ import annotations

import numpy as np

from treeform._shared.checks import check_int
from treeform._shared.errors import InputError
from treeform.structures.rdm import direction_to_texel

__all__ = ["color_cubemap", "synthesize", "cross_layout", "faces_from_cross", "cross_from_faces", "cube_edges",
           "edge_strip"]

_AXES = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], np.float64)
_CROSS_CELLS = {4: (1, 1), 0: (1, 2), 5: (1, 3), 1: (1, 0), 2: (0, 1), 3: (2, 1)}  # face -> (row, col)
_JOINED = {frozenset(p) for p in ((4, 0), (4, 1), (4, 2), (4, 3), (0, 5))}  # edges the cross already joins


def cross_layout(face: int) -> np.ndarray:
    """(3F, 4F) int8: the cube face (OpenGL index) each canvas pixel of the cross belongs to, -1 outside."""
    out = np.full((3 * face, 4 * face), -1, np.int8)
    for f, (r, c) in _CROSS_CELLS.items():
        out[r * face:(r + 1) * face, c * face:(c + 1) * face] = f
    return out


def _cross_pixel(d: np.ndarray, face: int) -> tuple[np.ndarray, np.ndarray]:
    """Row and column of the cross canvas pixel each direction (N, 3) falls on."""
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    ax = np.argmax(np.abs(d), axis=1)
    neg = d[np.arange(len(d)), ax] < 0
    f = 2 * ax + neg  # OpenGL face index
    s = np.empty(len(d))
    t = np.empty(len(d))
    with np.errstate(divide="ignore", invalid="ignore"):
        for k, (ss, tt) in {4: (x / z, -y / z), 0: (-z / x, -y / x), 5: (x / z, y / z), 1: (-z / x, y / x),
                            2: (x / y, z / y), 3: (-x / y, z / y)}.items():
            m = f == k
            s[m], t[m] = ss[m], tt[m]
    rc = np.array([_CROSS_CELLS[k] for k in range(6)])
    col = rc[f, 1] * face + np.clip(np.floor((s + 1) / 2 * face), 0, face - 1).astype(np.int64)
    row = rc[f, 0] * face + np.clip(np.floor((t + 1) / 2 * face), 0, face - 1).astype(np.int64)
    return row, col


def faces_from_cross(canvas: np.ndarray) -> np.ndarray:
    """The six (F, F, C) faces of a (3F, 4F, C) cross canvas, in OpenGL order and orientation."""
    from treeform.structures.rdm import texel_directions

    face = canvas.shape[0] // 3
    d = texel_directions(face).reshape(-1, 3)
    row, col = _cross_pixel(d, face)
    return canvas[row, col].reshape(6, face, face, *canvas.shape[2:])


def cross_from_faces(faces: np.ndarray, fill=255) -> np.ndarray:
    """The (3F, 4F, C) cross of six (F, F, C) faces, ``fill`` outside it: :func:`faces_from_cross` undone."""
    from treeform.structures.rdm import texel_directions

    faces = np.asarray(faces)
    face = faces.shape[1]
    out = np.full((3 * face, 4 * face, *faces.shape[3:]), fill, faces.dtype)
    row, col = _cross_pixel(texel_directions(face).reshape(-1, 3), face)
    out[row, col] = faces.reshape(-1, *faces.shape[3:])
    return out


def cube_edges():
    """The 12 edges of the cube as pairs of OpenGL face indices ``(a, b)``, and whether the cross joins them."""
    out = []
    for a in range(6):
        for b in range(a + 1, 6):
            if a // 2 != b // 2:
                out.append((a, b, frozenset((a, b)) in _JOINED))
    return out


def edge_strip(a: int, b: int, face: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """Texels of a strip across the edge of faces ``a`` and ``b``: ``(texels, u)``.

    The strip is ``face`` rows along the edge by ``2 width`` columns across it, face ``a`` on
    the left and ``b`` on the right, unfolded flat, so a texture synthesized in it runs over the
    edge. ``texels`` (F, 2W, 3) holds each pixel's (face, row, col); ``u`` (2W,) the signed
    distance of each column's centre from the edge, in texels (negative in ``a``).
    """
    na, nb = _AXES[a], _AXES[b]
    e = np.cross(na, nb)
    v = (np.arange(face) + 0.5) / face * 2 - 1
    u = np.arange(2 * width) + 0.5 - width
    a_side = np.where(u < 0, 1 - 2 * np.abs(u) / face, 0.0)
    b_side = np.where(u >= 0, 1 - 2 * u / face, 0.0)
    d = (np.where(u[None, :, None] < 0, na + a_side[None, :, None] * nb, nb + b_side[None, :, None] * na)
         + v[:, None, None] * e)
    f, r, c = direction_to_texel(d.reshape(-1, 3), face)
    return np.stack([f, r, c], -1).reshape(face, 2 * width, 3), u


def _candidates(alpha: np.ndarray, patch: int, stride: int) -> tuple[np.ndarray, np.ndarray]:
    """Top-left corners (on a ``stride`` grid) of the source patches that lie inside the tree."""
    import cv2

    a = alpha.astype(np.float32)
    inside = cv2.boxFilter(a, -1, (patch, patch), normalize=True, anchor=(0, 0), borderType=cv2.BORDER_CONSTANT)
    h, w = alpha.shape
    grid = np.zeros_like(alpha, bool)
    grid[:h - patch + 1:stride, :w - patch + 1:stride] = True
    for need in (0.999, 0.9, 0.7):
        ys, xs = np.nonzero(grid & (inside >= need))
        if len(ys) >= 16:
            return ys.astype(np.int64), xs.astype(np.int64)
    raise InputError(f"the tree shows too little crown for {patch}-px texture patches")


def synthesize(canvas: np.ndarray, fixed: np.ndarray, target: np.ndarray, source: np.ndarray,
               source_alpha: np.ndarray, *, patch: int = 32, overlap: int = 8, tries: int = 600,
               tolerance: float = 0.1, seed: int = 0) -> np.ndarray:
    """Fill the ``target`` pixels of ``canvas`` with patches of ``source`` (patch-based synthesis).

    Windows of ``patch``² pixels on a grid of step ``patch - overlap`` that hold target pixels
    are filled nearest-to-the-known-pixels first (onion peeling); each takes, among ``tries``
    random source patches inside ``source_alpha``, one whose squared difference to the
    window's known pixels is within ``1 + tolerance`` of the best (Efros & Freeman 2001), and
    overlapping patches are cross-faded with tent weights.

    Parameters
    ----------
    canvas : ndarray, shape (H, W, 3), uint8 or float
        Known colours where ``fixed``.
    fixed, target : ndarray, shape (H, W), bool
        Pixels that stay as they are, and pixels to fill.
    source : ndarray, shape (h, w, 3), uint8
    source_alpha : ndarray, shape (h, w), bool
        Where ``source`` shows the texture (patches are taken from inside it).
    patch, overlap, tries, tolerance, seed
        As above; same inputs and seed give the same result.

    Returns
    -------
    ndarray, shape (H, W, 3), uint8

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> src = rng.integers(0, 255, (64, 64, 3)).astype(np.uint8)
    >>> canvas = np.zeros((80, 80, 3), np.uint8); fixed = np.zeros((80, 80), bool)
    >>> out = synthesize(canvas, fixed, ~fixed, src, np.ones((64, 64), bool), patch=16, overlap=4)
    >>> out.shape, bool(out.std() > 30)
    ((80, 80, 3), True)
    """
    import scipy.ndimage as ndi

    from treeform.crown._kernels import quilt

    patch = check_int(patch, "patch", 4, 256)
    overlap = check_int(overlap, "overlap", 0, patch - 1)
    tries = check_int(tries, "tries", 1, 1_000_000)
    canvas = np.asarray(canvas)
    fixed = np.asarray(fixed, bool)
    target = np.asarray(target, bool) & ~fixed
    if canvas.ndim != 3 or canvas.shape[2] != 3 or fixed.shape != canvas.shape[:2] or target.shape != fixed.shape:
        raise InputError(f"canvas: expected (H, W, 3) with (H, W) masks, got {canvas.shape}, {fixed.shape}")
    src = np.ascontiguousarray(np.asarray(source)[..., :3], np.float32)
    if src.shape[0] < patch or src.shape[1] < patch:
        raise InputError(f"source: smaller than one {patch}-px patch ({src.shape[1]}x{src.shape[0]})")
    cy, cx = _candidates(np.asarray(source_alpha, bool), patch, max(1, patch // 8))
    H, W = fixed.shape
    if H < patch or W < patch:
        raise InputError(f"canvas: smaller than one {patch}-px patch ({W}x{H})")
    step = patch - overlap
    ys = np.unique(np.r_[np.arange(0, H - patch + 1, step), H - patch])  # windows inside the canvas
    xs = np.unique(np.r_[np.arange(0, W - patch + 1, step), W - patch])
    gy, gx = np.meshgrid(ys, xs, indexing="ij")
    gy, gx = gy.ravel(), gx.ravel()
    cum = np.pad(np.cumsum(np.cumsum(target, 0), 1), ((1, 0), (1, 0)))
    p0, p1 = gy + patch, gx + patch
    has = (cum[p0, p1] - cum[gy, p1] - cum[p0, gx] + cum[gy, gx]) > 0
    gy, gx = gy[has], gx[has]
    dist = ndi.distance_transform_edt(~fixed) if fixed.any() else np.zeros(fixed.shape)
    order = np.lexsort((gx, gy, dist[gy + patch // 2, gx + patch // 2]))
    work = np.ascontiguousarray(canvas, np.float32).copy()
    wsum = np.zeros((H, W), np.float32)
    quilt(work, wsum, fixed, target, src, cy, cx, gy[order].astype(np.int64), gx[order].astype(np.int64),
          patch, tries, float(tolerance), int(seed))
    out = np.where(fixed[..., None], canvas, work)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def color_cubemap(image: np.ndarray, *, face: int = 256, patch: int = 32, overlap: int = 8, band: int = 6,
                  tries: int = 600, seed: int = 0) -> np.ndarray:
    """The colour cubemap (6, F, F, 3) of a tree from one RGBA view of it (seed 001 §3.3).

    Parameters
    ----------
    image : ndarray, shape (H, W, 4), uint8
        The tree seen from the front (+Z toward the viewer), alpha > 127 on the tree: a
        segmented photo or a render.
    face : int
        Face edge ``F`` in texels (the canvas is 4F × 3F; the paper's 1024 × 768 is F = 256).
    patch, overlap, tries, seed
        Of :func:`synthesize`.
    band : int
        Half-width in texels of the band synthesized again across each cube edge the cross
        does not join.

    Returns
    -------
    ndarray, shape (6, F, F, 3), uint8
        Faces in OpenGL order (+X, -X, +Y, -Y, +Z, -Z), texel (row, col) along
        :func:`treeform.structures.rdm.texel_directions`.

    Raises
    ------
    InputError
        Not an RGBA image, or too little tree in it for the patches.
    """
    import cv2

    face = check_int(face, "face", 32, 2048)
    band = check_int(band, "band", 1, face // 4)
    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] != 4 or img.dtype != np.uint8:
        raise InputError(f"image: expected an (H, W, 4) uint8 RGBA array, got {img.shape} {img.dtype}")
    alpha = img[..., 3] > 127
    if alpha.sum() < patch * patch:
        raise InputError("image: the tree covers too few pixels for a colour cubemap")
    rows, cols = np.nonzero(alpha.any(1))[0], np.nonzero(alpha.any(0))[0]
    crop = img[rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1]
    side = int(round(5 * face / 3))  # the front face and a third of each neighbour (5/12 of 4F, 5/9 of 3F)
    sq = cv2.resize(crop, (side, side), interpolation=cv2.INTER_AREA)
    sq_alpha = sq[..., 3] > 127
    layout = cross_layout(face)
    canvas = np.zeros((3 * face, 4 * face, 3), np.uint8)
    fixed = np.zeros(layout.shape, bool)
    y0 = x0 = int(round(1.5 * face - side / 2))
    canvas[y0:y0 + side, x0:x0 + side] = sq[..., :3]
    fixed[y0:y0 + side, x0:x0 + side] = sq_alpha
    fixed &= layout >= 0
    canvas = synthesize(canvas, fixed, layout >= 0, sq[..., :3], sq_alpha, patch=patch, overlap=overlap,
                        tries=tries, seed=seed)
    faces = np.ascontiguousarray(faces_from_cross(canvas))
    # the seven edges the cross does not join: synthesize a band across each, in a flat strip
    width = max(2 * band, patch)
    for k, (a, b, joined) in enumerate(cube_edges()):
        if joined:
            continue
        tex, u = edge_strip(a, b, face, width)
        strip = faces[tex[..., 0], tex[..., 1], tex[..., 2]]
        inner = np.broadcast_to(np.abs(u)[None, :] < band, strip.shape[:2])
        strip = synthesize(strip, ~inner, inner, sq[..., :3], sq_alpha, patch=min(patch, 2 * band + 4),
                           overlap=min(overlap, band), tries=tries, seed=seed + 1 + k)
        t = tex[inner]
        faces[t[:, 0], t[:, 1], t[:, 2]] = strip[inner]
    return faces
