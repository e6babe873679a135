"""Leaf-cluster cards textured with the photo's own crown (seed 001 §3.3, §4.2: texture from the photo).

Each card gets a tile of one texture atlas. The tile is the photo as the card sees it from
the photo's camera: every texel is the point of the card it stands for, projected into the
photo, so seen from the front the crown shows the photo's foliage pixel for pixel, and from
the side and back the same leaves carry the same real texture. The tile's alpha is a leaf
cluster's outline (the procedural texture of the foliage kind, in several shapes) times the
photo's foliage alpha, so gaps in the photographed crown stay gaps and no card reaches past
the silhouette.
"""

from __future__ import annotations

import math

import numpy as np

from treeform._shared.checks import check_int
from treeform._shared.errors import InputError
from treeform._shared.rng import as_rng
from treeform.structures.camera import Camera
from treeform.structures.foliage import Foliage

__all__ = ["photo_leaf_atlas", "face_camera", "camera_sees"]

_SHAPES = 4  # distinct cluster outlines; each also turned by 0/90/180/270 degrees and mirrored


def face_camera(foliage: Foliage, camera: Camera, which, rng, scatter: float = 0.5) -> Foliage:
    """``foliage`` with the cards ``which`` turned to face the camera, give or take ``scatter``.

    A photo-textured card seen by the camera shows the photo where it projects; facing the
    camera it shows that patch unstretched and lit evenly (measured on real photos with the
    envelope route: front SSIM +0.12, silhouette error -0.5 points, against cards facing out
    of the crown).

    Parameters
    ----------
    foliage : Foliage
        M cards.
    camera : Camera
    which : array_like, shape (M,), bool
        The cards to turn (those the camera sees).
    rng : int or numpy.random.Generator
    scatter : float
        Standard deviation of the random tilt, in units of the unit normal.

    Examples
    --------
    >>> cam = Camera(64, 64, 40.0, (0, 0, 10.0), (0, 0, 0), (0, 1, 0))
    >>> f = Foliage([[0, 0, 0], [1, 0, 0]], [[1, 0, 0], [1, 0, 0]], [[0, 1, 0], [0, 1, 0]], [1.0, 1.0],
    ...             [[1, 1, 1], [1, 1, 1]])
    >>> g = face_camera(f, cam, [True, False], 0, scatter=0.0)
    >>> g.normals.round(2).tolist()
    [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]
    """
    rng = as_rng(rng)
    to_cam = np.asarray(camera.position, np.float64) - foliage.positions
    to_cam /= np.maximum(np.linalg.norm(to_cam, axis=1, keepdims=True), 1e-12)
    turned = to_cam + scatter * rng.normal(size=to_cam.shape) / math.sqrt(3.0)
    turned /= np.maximum(np.linalg.norm(turned, axis=1, keepdims=True), 1e-12)
    normals = np.where(np.asarray(which, bool)[:, None], turned, foliage.normals)
    return Foliage(foliage.positions, normals, foliage.up, foliage.size, foliage.color, foliage.node)


def camera_sees(foliage: Foliage, camera: Camera, mask: np.ndarray, *, band: float = 2.0) -> tuple[np.ndarray, np.ndarray]:
    """Which cards the photo's camera sees, by a depth buffer of the cards, and a shade for the others.

    The image is cut into cells of about a card's size; a card whose centre projects onto
    ``mask`` is seen when it lies within ``band`` card sizes behind the nearest card of its
    cell. A hidden card takes a shade from 1 (at the front of its cell) to 0.55 (half the
    crown's depth or more behind it), like the other routes' cards deep in the crown.

    Parameters
    ----------
    foliage : Foliage
        M cards in the camera's world.
    camera : Camera
    mask : ndarray, shape (H, W), bool
        The tree in the photo (the camera's image).
    band : float
        Depth, in card sizes, behind the frontmost card that still shows.

    Returns
    -------
    visible : ndarray, shape (M,), bool
    shade : ndarray, shape (M,), float in [0.55, 1] (1 where visible)

    Examples
    --------
    >>> cam = Camera(64, 64, 40.0, (0, 0, 10.0), (0, 0, 0), (0, 1, 0))
    >>> f = Foliage([[0, 0, 1.0], [0, 0, -1.0], [0, 0, 0.9]], [[0, 0, 1]] * 3, [[0, 1, 0]] * 3, [0.2] * 3,
    ...             [[1, 1, 1]] * 3)
    >>> vis, shade = camera_sees(f, cam, np.ones((64, 64), bool))
    >>> vis.tolist(), bool(shade[1] < 0.7)
    ([True, False, True], True)
    """
    mask = np.asarray(mask, bool)
    if mask.shape != (camera.height, camera.width):
        raise InputError(f"mask: expected shape {(camera.height, camera.width)}, got {mask.shape}")
    m = len(foliage)
    if m == 0:
        return np.zeros(0, bool), np.ones(0)
    uvz = camera.project(foliage.positions)
    depth = uvz[:, 2]
    px = foliage.size * camera.focal / np.maximum(depth, 1e-9)  # each card's size in pixels
    cell = max(float(np.median(px)), 1.0)
    h, w = mask.shape
    u = np.clip(np.floor(uvz[:, 0]).astype(np.int64), 0, w - 1)
    v = np.clip(np.floor(uvz[:, 1]).astype(np.int64), 0, h - 1)
    inside = (uvz[:, 0] >= 0) & (uvz[:, 0] < w) & (uvz[:, 1] >= 0) & (uvz[:, 1] < h) & (depth > 0)
    inside &= mask[v, u]
    cu, cv = (u / cell).astype(np.int64), (v / cell).astype(np.int64)
    key = cv * (int(w / cell) + 2) + cu
    _, k = np.unique(key, return_inverse=True)
    front = np.full(k.max() + 1, np.inf)
    np.minimum.at(front, k[inside], depth[inside])
    behind = depth - front[k]
    visible = inside & (behind <= band * foliage.size)
    spread = float(np.percentile(depth, 95) - np.percentile(depth, 5)) if m > 1 else 1.0
    far = np.clip(np.where(np.isfinite(behind), behind, spread) / max(0.5 * spread, 1e-9), 0.0, 1.0)
    shade = np.where(visible, 1.0, 1.0 - 0.45 * far)
    return visible, shade


def _finish_tiles(sample, shape_alpha, detail_lum, pick, dark, detail):
    """RGBA uint8 tiles (N, T, T, 4) from the photo under each tile (N, T, T, 4 float in [0, 1]).

    alpha = photo alpha × the tile's leaf outline; colour = photo × (1 + detail · (leaf
    shading - 1)) × the card's shade; transparent texels take the tile's alpha-weighted mean
    colour (the photo's mean where the tile is empty), so filtering leaves no dark fringe.
    One compiled pass (numba) instead of a dozen full-size NumPy temporaries.
    """
    from treeform.crown._kernels import finish_tiles

    return finish_tiles(np.ascontiguousarray(sample, np.float32), shape_alpha, detail_lum,
                        np.ascontiguousarray(pick, np.int64), dark, detail)


def _shapes(tile: int, kind: str, seed: int, grow: int) -> tuple[np.ndarray, np.ndarray]:
    """(K, tile, tile) alpha outlines and luminance detail (mean 1 inside) of leaf clusters.

    The outlines are the drawn clusters' alpha grown by a ``grow``-texel maximum filter
    (broadleaf kinds; needles and scales keep their fine outline): the photo's alpha already
    carries the crown's real gaps, so the shape only has to read as leaves from the side,
    and a fuller one lets the front cover the photo's crown.
    """
    from treeform.geometry.leaves import _default_leaf

    import scipy.ndimage as ndi

    alpha, detail = [], []
    for k in range(_SHAPES):
        t = _default_leaf(tile, seed + k, kind).astype(np.float32) / 255.0
        # fuller than the drawn cluster: the photo's own alpha carries the crown's real gaps
        a = ndi.grey_dilation(t[..., 3], size=(grow, grow)) if grow > 1 else t[..., 3]
        lum = t[..., :3] @ np.float32([0.3, 0.59, 0.11])
        lum = lum / max(float((lum * a).sum() / max(a.sum(), 1e-6)), 1e-6)
        for rot in range(4):
            for flip in (False, True):
                aa, ll = np.rot90(a, rot), np.rot90(lum, rot)
                if flip:
                    aa, ll = aa[:, ::-1], ll[:, ::-1]
                alpha.append(aa)
                detail.append(ll)
    return np.stack(alpha), np.stack(detail)


def _pack(tiles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Lay (T, t, t, 4) tiles in rows of a square atlas; returns it and each tile's uv rectangle.

    The rectangles lie half a texel inside their tiles, so filtering stays within a tile.
    """
    n_tiles, tile = len(tiles), tiles.shape[1]
    cols = int(math.ceil(math.sqrt(n_tiles)))
    rows = int(math.ceil(n_tiles / cols))
    side = int(math.ceil(max(cols, rows) * tile / 4) * 4)
    full = np.zeros((rows * cols, tile, tile, 4), np.uint8)
    full[:n_tiles] = tiles
    atlas = np.zeros((side, side, 4), np.uint8)
    atlas[: rows * tile, : cols * tile] = full.reshape(rows, cols, tile, tile, 4).transpose(0, 2, 1, 3, 4).reshape(
        rows * tile, cols * tile, 4)
    col, row = np.arange(n_tiles) % cols, np.arange(n_tiles) // cols
    rect = np.column_stack([col * tile + 0.5, row * tile + 0.5, (col + 1) * tile - 0.5, (row + 1) * tile - 0.5])
    return atlas, (rect / side).astype(np.float32)


def photo_leaf_atlas(foliage: Foliage, camera: Camera, image: np.ndarray, alpha: np.ndarray, *,
                     kind: str = "cluster", tile: int | None = None, max_tiles: int = 16384,
                     visible: np.ndarray | None = None, shade: np.ndarray | None = None, detail: float = 0.35,
                     oblique: float = 0.3, seed=0) -> tuple[np.ndarray, Foliage]:
    """Cut one atlas tile per card from the photo, by projecting the card into it.

    Parameters
    ----------
    foliage : Foliage
        M cards in the photo camera's world.
    camera : Camera
        The camera that took the photo (its image is ``image``'s size).
    image : ndarray, shape (H, W, 3), uint8
    alpha : ndarray, shape (H, W), bool or float in [0, 1]
        Where the photo shows foliage (a mask or a matte).
    kind : {"cluster", "leaf", "needles", "scales"}
        Procedural texture whose outline shapes each tile (:func:`treeform.geometry.leaf_texture`).
    tile : int, optional
        Tile edge in texels (8..128); default the median card's size in photo pixels (the
        photo's own resolution) as a power of two in [16, 32].
    max_tiles : int
        At most this many distinct tiles: past it, the cards hidden from the camera
        (``visible`` False) share the tile of the nearest visible card in the photo.
    visible : ndarray, shape (M,), bool, optional
        Cards the camera sees (default: all).
    shade : ndarray, shape (M,), optional
        Multiplier in [0, 1] baked into each card's own tile (e.g. darker deep in the crown),
        so the cards need no vertex colour (OBJ viewers ignore those); a card that borrows a
        tile shows it unshaded.
    detail : float in [0, 1]
        How much the procedural leaves' shading modulates the photo texture (crisp leaf
        edges where the photo is coarser than the tile).
    oblique : float in [0, 1]
        Visible cards whose projected area is below this fraction of a camera-facing card's
        take the undistorted photo patch around their centre instead of their exact
        projection, as hidden cards always do (1: every card; 0: only the hidden ones).
    seed : int

    Returns
    -------
    atlas : ndarray, shape (S, S, 4), uint8
        The tiles in rows, S a multiple of 4; transparent texels carry their tile's mean
        colour, so filtering leaves no dark fringe.
    foliage : Foliage
        The cards with ``uv`` set to their tiles (colours unchanged).

    Examples
    --------
    >>> cam = Camera(64, 64, 40.0, (0, 0, 10.0), (0, 0, 0), (0, 1, 0))
    >>> f = Foliage([[0, 0, 0]], [[0, 0, 1]], [[0, 1, 0]], [1.0], [[1, 1, 1]])
    >>> img = np.zeros((64, 64, 3), np.uint8); img[:, 32:] = 200
    >>> atlas, f2 = photo_leaf_atlas(f, cam, img, np.ones((64, 64)), tile=16)
    >>> atlas.shape, f2.uv.shape
    ((16, 16, 4), (1, 4))
    >>> red, opaque = atlas[..., 0].astype(int), atlas[..., 3] > 127  # left of the card dark, right bright
    >>> bool(red[:, :6][opaque[:, :6]].mean() < 60 and red[:, 10:][opaque[:, 10:]].mean() > 150)
    True
    """
    import cv2

    from treeform.geometry.leaves import TEXTURE_KINDS, card_frames

    if not isinstance(foliage, Foliage):
        raise InputError(f"foliage: expected a Foliage, got {type(foliage).__name__}")
    image = np.asarray(image)
    if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
        raise InputError(f"image: expected an (H, W, 3) uint8 array, got {image.shape} {image.dtype}")
    alpha = np.asarray(alpha, np.float32)
    if alpha.shape != image.shape[:2]:
        raise InputError(f"alpha: expected shape {image.shape[:2]}, got {alpha.shape}")
    if kind not in TEXTURE_KINDS:
        raise InputError(f"kind: expected one of {TEXTURE_KINDS}, got {kind!r}")
    max_tiles = check_int(max_tiles, "max_tiles", 1, 1 << 20)
    for name, v in (("detail", detail), ("oblique", oblique)):
        if not 0.0 <= float(v) <= 1.0:
            raise InputError(f"{name}: expected a number in [0, 1], got {v!r}")
    m = len(foliage)
    if m == 0:
        return np.zeros((4, 4, 4), np.uint8), foliage
    vis = np.ones(m, bool) if visible is None else np.asarray(visible, bool).reshape(-1)
    if len(vis) != m:
        raise InputError(f"visible: expected {m} flags, got {len(vis)}")
    dark = np.ones(m, np.float32) if shade is None else np.asarray(shade, np.float32).reshape(-1)
    if len(dark) != m or not np.all((dark >= 0) & (dark <= 1)):
        raise InputError(f"shade: expected {m} numbers in [0, 1]")
    rng = as_rng(seed)

    # each card's centre and half-axes in photo pixels (an affine map: the camera is far away)
    _, up, right = card_frames(foliage)
    half = 0.5 * foliage.size[:, None]
    c = camera.project(foliage.positions)
    a = camera.project(foliage.positions + half * right)[:, :2] - c[:, :2]  # texture +s
    b = camera.project(foliage.positions - half * up)[:, :2] - c[:, :2]  # texture +t (down)
    facing = 0.5 * foliage.size * camera.focal / np.maximum(c[:, 2], 1e-9)  # a camera-facing card's half size
    edge_on = (np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]) < oblique * facing**2) | ~vis
    # oblique cards would stretch a sliver of the photo over the whole tile (streaks from the
    # side), and hidden ones gain nothing from the exact projection: they show the patch a
    # card facing the camera would, turned as the card is
    ang = np.arctan2(a[edge_on, 1], a[edge_on, 0])
    rot = np.column_stack([np.cos(ang), np.sin(ang)])
    a[edge_on] = facing[edge_on, None] * rot
    b[edge_on] = facing[edge_on, None] * np.column_stack([-rot[:, 1], rot[:, 0]])
    if tile is None:
        tile = int(np.clip(2 ** round(math.log2(max(2.0 * float(np.median(facing)), 1.0))), 16, 32))
    tile = check_int(tile, "tile", 8, 128)

    # tiles: every card its own while they fit, else the hidden ones borrow a visible one's
    owner = np.arange(m)
    if m > max_tiles:
        from scipy.spatial import cKDTree

        own = np.flatnonzero(vis)
        if len(own) > max_tiles:
            own = np.sort(rng.choice(own, max_tiles, replace=False))
        if len(own) == 0:
            own = np.sort(rng.choice(m, min(m, max_tiles), replace=False))
        borrow = np.setdiff1d(np.arange(m), own)
        _, j = cKDTree(c[own, :2]).query(c[borrow, :2])
        owner[borrow] = own[j]
    tiles, tile_of = np.unique(owner, return_inverse=True)
    n_tiles = len(tiles)

    # sample the photo (colour and alpha) under every texel of every tile
    g = (np.arange(tile, dtype=np.float32) + 0.5) / tile - 0.5  # texel centres in [-0.5, 0.5)
    s = g[None, None, :]  # along +s (columns)
    t = g[None, :, None]  # along +t (rows)
    cc, aa, bb = c[tiles, :2].astype(np.float32), a[tiles].astype(np.float32), b[tiles].astype(np.float32)
    px = cc[:, 0, None, None] + 2 * (s * aa[:, 0, None, None] + t * bb[:, 0, None, None])
    py = cc[:, 1, None, None] + 2 * (s * aa[:, 1, None, None] + t * bb[:, 1, None, None])
    photo = np.concatenate([image.astype(np.float32) / 255.0, alpha[..., None]], axis=2)
    # bilinear, pixel centres at +0.5, the border repeated; tiles stacked into tall images
    # (OpenCV maps stay under 32767 rows)
    step = 32000 // tile
    sample = np.concatenate([
        cv2.remap(photo, (px[i:i + step] - 0.5).reshape(-1, tile), (py[i:i + step] - 0.5).reshape(-1, tile),
                  cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE).reshape(-1, tile, tile, 4)
        for i in range(0, n_tiles, step)])

    shape_alpha, detail_lum = _shapes(tile, kind, int(seed) if not isinstance(seed, np.random.Generator) else 0,
                                      grow=max(1, tile // 6) if kind in ("cluster", "leaf") else 1)
    pick = rng.integers(0, len(shape_alpha), n_tiles)
    tex = _finish_tiles(sample, shape_alpha.astype(np.float32), detail_lum.astype(np.float32), pick,
                        dark[tiles].astype(np.float32), np.float32(detail))
    atlas, rects = _pack(tex)
    rect = rects[tile_of]
    return atlas, foliage.with_colors(foliage.color, uv=rect)
