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

__all__ = ["photo_leaf_atlas", "views_leaf_atlas", "choose_views", "face_camera", "camera_sees", "carve_texels"]

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


def camera_sees(foliage: Foliage, camera: Camera, mask: np.ndarray, *, band: float = 2.0,
                pixels: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Which cards the photo's camera sees, by a depth buffer of the cards, and a shade for the others.

    A card whose centre projects onto ``mask`` is seen where it is the nearest card in at
    least one pixel, each card drawn as the square of its size on the image, nearest first (a
    painter's depth buffer). With ``pixels=False`` the image is cut into cells of about a
    card's size instead, and a card is seen when it lies within ``band`` card sizes behind
    the nearest card of its cell (coarser: a card behind a gap between the front cards, or a
    small card beside a large one, is taken for hidden). A hidden card takes a shade from 1
    (at the front of its cell) to 0.55 (half the crown's depth or more behind it), like the
    other routes' cards deep in the crown.

    Parameters
    ----------
    foliage : Foliage
        M cards in the camera's world.
    camera : Camera
    mask : ndarray, shape (H, W), bool
        The tree in the photo (the camera's image).
    band : float
        Depth, in card sizes, behind the frontmost card that still shows (cells only).
    pixels : bool
        Decide by the pixels each card covers (default), not by cells.

    Returns
    -------
    visible : ndarray, shape (M,), bool
    shade : ndarray, shape (M,), float in [0.55, 1] (1 where visible)

    Examples
    --------
    A card in front, one far behind it, one just behind it, and one just behind it but half
    beside it:

    >>> cam = Camera(64, 64, 40.0, (0, 0, 10.0), (0, 0, 0), (0, 1, 0))
    >>> f = Foliage([[0, 0, 1.0], [0, 0, -1.0], [0, 0, 0.9], [0.1, 0, 0.9]], [[0, 0, 1]] * 4, [[0, 1, 0]] * 4,
    ...             [0.2] * 4, [[1, 1, 1]] * 4)
    >>> vis, shade = camera_sees(f, cam, np.ones((64, 64), bool))
    >>> vis.tolist(), bool(shade[1] < 0.7)
    ([True, False, False, True], True)
    >>> camera_sees(f, cam, np.ones((64, 64), bool), pixels=False)[0].tolist()  # cells: near enough behind
    [True, False, True, True]
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
    if pixels:
        from treeform.crown._kernels import frontmost_squares

        visible = inside & frontmost_squares(uvz[:, 0], uvz[:, 1], depth, 0.5 * px, inside, h, w)
    else:
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


def _check_tile_options(kind: str, detail: float, oblique: float) -> None:
    """One-line errors for the tile options shared by :func:`photo_leaf_atlas` and :func:`views_leaf_atlas`."""
    from treeform.geometry.leaves import TEXTURE_KINDS

    if kind not in TEXTURE_KINDS:
        raise InputError(f"kind: expected one of {TEXTURE_KINDS}, got {kind!r}")
    for name, v in (("detail", detail), ("oblique", oblique)):
        if not 0.0 <= float(v) <= 1.0:
            raise InputError(f"{name}: expected a number in [0, 1], got {v!r}")


def _tile_shapes(tile: int, kind: str, seed) -> tuple[np.ndarray, np.ndarray]:
    """The cluster outlines of the tiles (:func:`_shapes`), grown for broadleaf kinds."""
    return _shapes(tile, kind, int(seed) if not isinstance(seed, np.random.Generator) else 0,
                   grow=max(1, tile // 6) if kind in ("cluster", "leaf") else 1)


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
        (``visible`` False) share the tile of the nearest visible card in the photo. With the
        automatic ``tile`` and more visible cards than this, the tiles halve (down to 8 texels)
        and four times as many fit in the same texels.
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
    if not isinstance(foliage, Foliage):
        raise InputError(f"foliage: expected a Foliage, got {type(foliage).__name__}")
    image = np.asarray(image)
    if image.ndim != 3 or image.shape[2] != 3 or image.dtype != np.uint8:
        raise InputError(f"image: expected an (H, W, 3) uint8 array, got {image.shape} {image.dtype}")
    alpha = np.asarray(alpha, np.float32)
    if alpha.shape != image.shape[:2]:
        raise InputError(f"alpha: expected shape {image.shape[:2]}, got {alpha.shape}")
    _check_tile_options(kind, detail, oblique)
    max_tiles = check_int(max_tiles, "max_tiles", 1, 1 << 20)
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

    if tile is None:
        tile = _tile_size(_card_pixels(foliage, camera))
        # more cards the camera sees than tiles: smaller tiles, four times as many in the same texels,
        # rather than visible cards wearing other cards' patches
        while int(vis.sum()) > max_tiles and tile > 8:
            tile, max_tiles = tile // 2, max_tiles * 4
    tile = check_int(tile, "tile", 8, 128)

    # tiles: every card its own while they fit, else the hidden ones borrow a visible one's
    owner = np.arange(m)
    if m > max_tiles:
        from scipy.spatial import cKDTree

        c = camera.project(foliage.positions)
        own = np.flatnonzero(vis)
        if len(own) > max_tiles:
            own = np.sort(rng.choice(own, max_tiles, replace=False))
        if len(own) == 0:
            own = np.sort(rng.choice(m, min(m, max_tiles), replace=False))
        borrow = np.setdiff1d(np.arange(m), own)
        _, j = cKDTree(c[own, :2]).query(c[borrow, :2])
        owner[borrow] = own[j]
    tiles, tile_of = np.unique(owner, return_inverse=True)
    shape_alpha, detail_lum = _tile_shapes(tile, kind, seed)
    pick = rng.integers(0, len(shape_alpha), len(tiles))
    tex = _card_tiles(foliage, tiles, camera, image, alpha, vis[tiles], dark[tiles], tile=tile, oblique=oblique,
                      shapes=(shape_alpha, detail_lum), pick=pick, detail=detail)
    atlas, rects = _pack(tex)
    rect = rects[tile_of]
    return atlas, foliage.with_colors(foliage.color, uv=rect)


def _card_pixels(foliage: Foliage, camera: Camera) -> np.ndarray:
    """(M,) each card's edge in ``camera``'s pixels, were it facing the camera."""
    return foliage.size * camera.focal / np.maximum(camera.project(foliage.positions)[:, 2], 1e-9)


def _tile_size(pixels: np.ndarray) -> int:
    """Tile edge in texels: the median card's size in pixels, as a power of two in [16, 32]."""
    return int(np.clip(2 ** round(math.log2(max(float(np.median(pixels)), 1.0))), 16, 32))


def _card_tiles(foliage: Foliage, cards: np.ndarray, camera: Camera, image: np.ndarray, alpha: np.ndarray,
                vis: np.ndarray, dark: np.ndarray, *, tile: int, oblique: float, shapes: tuple, pick: np.ndarray,
                detail: float) -> np.ndarray:
    """(len(cards), tile, tile, 4) float tiles of the cards ``cards``: the photo under each texel, in a cluster outline.

    ``vis``, ``dark`` and ``pick`` are per tile (aligned with ``cards``); see :func:`photo_leaf_atlas`.
    """
    import cv2

    from treeform.geometry.leaves import card_frames

    n_tiles = len(cards)
    if n_tiles == 0:
        return np.zeros((0, tile, tile, 4), np.float32)
    sub = foliage.subset(cards)
    # each card's centre and half-axes in photo pixels (an affine map: the camera is far away)
    _, up, right = card_frames(sub)
    half = 0.5 * sub.size[:, None]
    c = camera.project(sub.positions)
    a = camera.project(sub.positions + half * right)[:, :2] - c[:, :2]  # texture +s
    b = camera.project(sub.positions - half * up)[:, :2] - c[:, :2]  # texture +t (down)
    past = ~vis & ((c[:, 0] < 0) | (c[:, 0] >= image.shape[1]) | (c[:, 1] < 0) | (c[:, 1] >= image.shape[0]))
    c[past, :2] = _into_foliage(c[past, :2], alpha)  # a crown continued past the frame wears the crown in it
    facing = 0.5 * sub.size * camera.focal / np.maximum(c[:, 2], 1e-9)  # a camera-facing card's half size
    edge_on = (np.abs(a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]) < oblique * facing**2) | ~vis
    # oblique cards would stretch a sliver of the photo over the whole tile (streaks from the
    # side), and hidden ones gain nothing from the exact projection: they show the patch a
    # card facing the camera would, turned as the card is
    ang = np.arctan2(a[edge_on, 1], a[edge_on, 0])
    rot = np.column_stack([np.cos(ang), np.sin(ang)])
    a[edge_on] = facing[edge_on, None] * rot
    b[edge_on] = facing[edge_on, None] * np.column_stack([-rot[:, 1], rot[:, 0]])
    # sample the photo (colour and alpha) under every texel of every tile
    g = (np.arange(tile, dtype=np.float32) + 0.5) / tile - 0.5  # texel centres in [-0.5, 0.5)
    s = g[None, None, :]  # along +s (columns)
    t = g[None, :, None]  # along +t (rows)
    cc, aa, bb = c[:, :2].astype(np.float32), a.astype(np.float32), b.astype(np.float32)
    px = cc[:, 0, None, None] + 2 * (s * aa[:, 0, None, None] + t * bb[:, 0, None, None])
    py = cc[:, 1, None, None] + 2 * (s * aa[:, 1, None, None] + t * bb[:, 1, None, None])
    photo = np.concatenate([image.astype(np.float32) / 255.0, np.asarray(alpha, np.float32)[..., None]], axis=2)
    # bilinear, pixel centres at +0.5, the border repeated; tiles stacked into tall images
    # (OpenCV maps stay under 32767 rows)
    step = 32000 // tile
    sample = np.concatenate([
        cv2.remap(photo, (px[i:i + step] - 0.5).reshape(-1, tile), (py[i:i + step] - 0.5).reshape(-1, tile),
                  cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE).reshape(-1, tile, tile, 4)
        for i in range(0, n_tiles, step)])
    shape_alpha, detail_lum = shapes
    return _finish_tiles(sample, shape_alpha.astype(np.float32), detail_lum.astype(np.float32), pick,
                         np.asarray(dark, np.float32), np.float32(detail))


def _into_foliage(uv: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """Pixel positions (N, 2) (u, v) moved into the photo's foliage: a position past the frame is
    mirrored into it at the edge (a crown continued past the frame, :mod:`treeform.crown.frame`, takes
    the texture of the crown inside it), then one off the foliage (``alpha`` <= 0.5) goes to the
    nearest foliage pixel. Unchanged where the photo shows no foliage at all.

    >>> a = np.zeros((10, 10)); a[:, 5:] = 1.0
    >>> _into_foliage(np.array([[7.5, -3.0], [12.0, 4.5], [1.5, 2.5]]), a).tolist()
    [[7.5, 3.0], [8.0, 4.5], [5.5, 2.5]]
    """
    import scipy.ndimage as ndi

    uv = np.array(uv, np.float64).reshape(-1, 2)
    H, W = alpha.shape
    off = alpha <= 0.5
    if len(uv) == 0 or off.all():
        return uv
    for k, n in ((0, W), (1, H)):
        x = uv[:, k]
        x = np.where(x < 0, -x, np.where(x >= n, 2 * n - x, x))
        uv[:, k] = np.clip(x, 0, n - 1e-3)
    iu, iv = uv[:, 0].astype(np.int64), uv[:, 1].astype(np.int64)
    bad = off[iv, iu]
    if bad.any():
        _, (ny, nx) = ndi.distance_transform_edt(off, return_indices=True)
        uv[bad, 0] = nx[iv[bad], iu[bad]] + 0.5
        uv[bad, 1] = ny[iv[bad], iu[bad]] + 0.5
    return uv


def choose_views(foliage: Foliage, cameras, masks, images=None, *,
                 agree: float = 30.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For each card, the photo of several that shows it best, whether it shows there, and its shade.

    A card is seen by a view when :func:`camera_sees` says so (it projects onto the view's tree
    mask, near the front of the cards there). With ``images``, a view must also agree with the
    others on the card's colour: the photo's colour at the card's centre within ``agree`` (RGB,
    0-255) of the median over the views that see it, so a view where something else covers the
    card (a neighbouring tree, a facade or sky the mask took in) is not its view unless none
    agrees (then the view nearest the median). Among those views, the one it faces most (its
    outward direction from the crown's centre against the direction to the camera) is its
    view; a card no view sees takes the view it faces most, as hidden, with that view's shade.

    Parameters
    ----------
    foliage : Foliage
        M cards in the cameras' world.
    cameras : sequence of Camera
        V cameras.
    masks : sequence of ndarray, shape (H_k, W_k), bool
        The tree in each view (each camera's image size).
    images : sequence of ndarray, shape (H_k, W_k, 3), uint8, optional
        The photos, for the colour agreement.
    agree : float
        Largest distance of a view's colour from the median one (RGB units).

    Returns
    -------
    view : ndarray, shape (M,), int
    visible : ndarray, shape (M,), bool
    shade : ndarray, shape (M,), float in [0.55, 1]

    Examples
    --------
    >>> cams = [Camera(64, 64, 40.0, (0, 0, z), (0, 0, 0), (0, 1, 0)) for z in (10.0, -10.0)]
    >>> f = Foliage([[0, 0, 1.0], [0, 0, -1.0]], [[0, 0, 1], [0, 0, -1]], [[0, 1, 0]] * 2, [0.2] * 2,
    ...             [[1, 1, 1]] * 2)
    >>> view, vis, _ = choose_views(f, cams, [np.ones((64, 64), bool)] * 2)
    >>> view.tolist(), vis.tolist()
    ([0, 1], [True, True])
    """
    cameras, masks = list(cameras), list(masks)
    if not cameras or len(cameras) != len(masks):
        raise InputError(f"cameras, masks: expected as many masks as cameras (at least one), got {len(cameras)} "
                         f"and {len(masks)}")
    m = len(foliage)
    if m == 0:
        return np.zeros(0, np.int64), np.zeros(0, bool), np.ones(0)
    out = foliage.positions - np.median(foliage.positions, axis=0)
    out /= np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-12)
    faces = np.empty((len(cameras), m))
    seen = np.empty((len(cameras), m), bool)
    shades = np.empty((len(cameras), m))
    for k, (cam, mask) in enumerate(zip(cameras, masks)):
        seen[k], shades[k] = camera_sees(foliage, cam, mask)
        to_cam = np.asarray(cam.position, np.float64) - foliage.positions
        to_cam /= np.maximum(np.linalg.norm(to_cam, axis=1, keepdims=True), 1e-12)
        faces[k] = (to_cam * out).sum(1)
    visible = seen.any(0)
    ok = seen
    if images is not None:
        images = list(images)
        if len(images) != len(cameras):
            raise InputError(f"images: expected {len(cameras)} photos, got {len(images)}")
        col = np.full((len(cameras), m, 3), np.nan, np.float32)
        for k, (cam, img) in enumerate(zip(cameras, images)):
            img = np.asarray(img)
            if img.shape[:2] != (cam.height, cam.width):
                raise InputError(f"images[{k}]: expected shape {(cam.height, cam.width)}, got {img.shape[:2]}")
            j = np.flatnonzero(seen[k])
            uv = cam.project(foliage.positions[j])
            u = np.clip(np.floor(uv[:, 0]).astype(np.int64), 0, cam.width - 1)
            v = np.clip(np.floor(uv[:, 1]).astype(np.int64), 0, cam.height - 1)
            col[k, j] = img[v, u, :3]
        from treeform._shared.nanstats import nanmedian_views

        med = nanmedian_views(col)  # NaN for the cards no view sees
        dev = np.linalg.norm(col - med[None], axis=2)
        dev = np.where(seen, dev, np.inf)
        ok = dev <= agree
        ok |= seen & (dev <= dev.min(0, initial=np.inf)[None]) & ~ok.any(0)[None]  # none agrees: the nearest
    view = np.where(visible, np.argmax(np.where(ok, faces, -np.inf), axis=0), np.argmax(faces, axis=0))
    shade = np.where(visible, 1.0, shades[view, np.arange(m)])
    return view.astype(np.int64), visible, shade


def views_leaf_atlas(foliage: Foliage, cameras, images, alphas, view, *, visible=None, shade=None,
                     kind: str = "cluster", tile: int | None = None, detail: float = 0.35, oblique: float = 0.3,
                     masks=None, tolerance: float = 0.1, spare: int = 0, seed=0) -> tuple[np.ndarray, Foliage]:
    """:func:`photo_leaf_atlas` over several photos: each card's tile is cut from its own view.

    Parameters
    ----------
    foliage : Foliage
        M cards in the cameras' world.
    cameras : sequence of Camera
        V cameras; camera k's image is ``images[k]``'s size.
    images : sequence of ndarray, shape (H_k, W_k, 3), uint8
    alphas : sequence of ndarray, shape (H_k, W_k), float in [0, 1]
        Where each photo shows foliage.
    view : array_like, shape (M,), int
        The view each card's tile comes from (:func:`choose_views`).
    visible, shade : array_like, shape (M,), optional
        As :func:`photo_leaf_atlas`, each for the card's own view.
    kind, tile, detail, oblique, seed
        As :func:`photo_leaf_atlas`; ``tile`` defaults to the median card's size in its view's
        pixels, as a power of two in [16, 32].
    masks : sequence of ndarray, shape (H_k, W_k), bool, optional
        The tree in each view: every texel is also carved against all of them
        (:func:`carve_texels`), so the parts of a card that some views see through are transparent.
    tolerance : float
        Share of the views holding a texel that may see background there (:func:`carve_texels`).
    spare : int
        Views that may see background there whatever their share (:func:`carve_texels`).

    Returns
    -------
    atlas : ndarray, shape (S, S, 4), uint8
    foliage : Foliage
        The cards with ``uv`` set to their tiles.

    Examples
    --------
    >>> cams = [Camera(64, 64, 40.0, (0, 0, z), (0, 0, 0), (0, 1, 0)) for z in (10.0, -10.0)]
    >>> f = Foliage([[0, 0, 1.0], [0, 0, -1.0]], [[0, 0, 1], [0, 0, -1]], [[0, 1, 0]] * 2, [1.0] * 2,
    ...             [[1, 1, 1]] * 2)
    >>> red = np.zeros((64, 64, 3), np.uint8); red[..., 0] = 200
    >>> blue = np.zeros((64, 64, 3), np.uint8); blue[..., 2] = 200
    >>> atlas, f2 = views_leaf_atlas(f, cams, [red, blue], [np.ones((64, 64))] * 2, [0, 1], tile=16)
    >>> bool(atlas[:16, :16, 0].max() > 150), bool(atlas[:16, 16:32, 2].max() > 150)   # card 0 red, card 1 blue
    (True, True)
    """
    if not isinstance(foliage, Foliage):
        raise InputError(f"foliage: expected a Foliage, got {type(foliage).__name__}")
    cameras, images, alphas = list(cameras), [np.asarray(i) for i in images], [np.asarray(a, np.float32) for a in alphas]
    if not cameras or not len(cameras) == len(images) == len(alphas):
        raise InputError(f"cameras, images, alphas: expected the same number (at least one), got {len(cameras)}, "
                         f"{len(images)} and {len(alphas)}")
    for k, (cam, img, al) in enumerate(zip(cameras, images, alphas)):
        if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
            raise InputError(f"images[{k}]: expected an (H, W, 3) uint8 array, got {img.shape} {img.dtype}")
        if al.shape != img.shape[:2] or img.shape[:2] != (cam.height, cam.width):
            raise InputError(f"alphas[{k}], cameras[{k}]: expected the image's size {img.shape[:2]}, got "
                             f"{al.shape} and {(cam.height, cam.width)}")
    _check_tile_options(kind, detail, oblique)
    m = len(foliage)
    if m == 0:
        return np.zeros((4, 4, 4), np.uint8), foliage
    view = np.asarray(view, np.int64).reshape(-1)
    if len(view) != m or view.min() < 0 or view.max() >= len(cameras):
        raise InputError(f"view: expected {m} view indices in [0, {len(cameras)})")
    vis = np.ones(m, bool) if visible is None else np.asarray(visible, bool).reshape(-1)
    dark = np.ones(m, np.float32) if shade is None else np.asarray(shade, np.float32).reshape(-1)
    if len(vis) != m or len(dark) != m or not np.all((dark >= 0) & (dark <= 1)):
        raise InputError(f"visible, shade: expected {m} flags and {m} numbers in [0, 1]")
    rng = as_rng(seed)
    if tile is None:
        px = np.empty(m)
        for k in np.unique(view):
            px[view == k] = _card_pixels(foliage.subset(view == k), cameras[k])
        tile = _tile_size(px)
    tile = check_int(tile, "tile", 8, 128)
    shapes = _tile_shapes(tile, kind, seed)
    pick = rng.integers(0, len(shapes[0]), m)
    tex = np.empty((m, tile, tile, 4), np.uint8)
    for k in np.unique(view):
        cards = np.flatnonzero(view == k)
        tex[cards] = _card_tiles(foliage, cards, cameras[k], images[k], alphas[k], vis[cards], dark[cards], tile=tile,
                                 oblique=oblique, shapes=shapes, pick=pick[cards], detail=detail)
    if masks is not None:
        tex[..., 3] *= carve_texels(foliage, cameras, masks, tile, tolerance=tolerance, spare=spare)
    atlas, rects = _pack(tex)
    return atlas, foliage.with_colors(foliage.color, uv=rects)


def carve_texels(foliage: Foliage, cameras, masks, tile: int, *, tolerance: float = 0.1, spare: int = 0,
                 chunk: int = 2048) -> np.ndarray:
    """Which texels of each card lie inside every view's tree: the visual hull at the texels' resolution.

    Texel ``(row t, column s)`` of a card stands for the point ``p + s size right - t size up``
    (``s, t`` the texel centres in [-0.5, 0.5), the card's frame as
    :func:`~treeform.geometry.leaf_cards` draws it). A texel is kept when it falls on the tree
    mask in all but ``tolerance`` of the views whose image holds it, or all but ``spare`` of
    them where that is more (a mask's errors and occluders are tolerated): a card on the visual
    hull of a porous crown keeps the parts every photo sees as tree, and what some photos see
    through goes.

    Parameters
    ----------
    foliage : Foliage
        M cards.
    cameras : sequence of Camera
    masks : sequence of ndarray, shape (H_k, W_k), bool
        The tree in each view (each camera's image size).
    tile : int
        Texels along a tile's edge.
    tolerance : float in [0, 0.5)
    spare : int
        Views that may see background at a kept texel however few views hold it: with a share
        alone, ten views tolerate none at 0.05 and one mask's stray pixel cuts the texel.
    chunk : int
        Cards per batch (memory).

    Returns
    -------
    ndarray, shape (M, tile, tile), uint8
        1 where the texel is kept.

    Examples
    --------
    A card facing +z (its texture's columns run along +x), seen from the front, where it is all
    tree, and from behind, where the right half of the image (world -x) is background:

    >>> cams = [Camera(64, 64, 40.0, (0, 0, 10.0), (0, 0, 0), (0, 1, 0)),
    ...         Camera(64, 64, 40.0, (0, 0, -10.0), (0, 0, 0), (0, 1, 0))]
    >>> f = Foliage([[0, 0, 0]], [[0, 0, 1]], [[0, 1, 0]], [2.0], [[1, 1, 1]])
    >>> back = np.ones((64, 64), bool); back[:, 32:] = False
    >>> carve_texels(f, cams, [np.ones((64, 64), bool), back], 4, tolerance=0.0)[0].tolist()
    [[0, 0, 1, 1], [0, 0, 1, 1], [0, 0, 1, 1], [0, 0, 1, 1]]
    """
    from treeform.geometry.leaves import card_frames

    cameras, masks = list(cameras), [np.asarray(mk, bool) for mk in masks]
    if len(cameras) != len(masks):
        raise InputError(f"masks: expected {len(cameras)} masks, got {len(masks)}")
    if not 0.0 <= float(tolerance) < 0.5:
        raise InputError(f"tolerance: expected a share in [0, 0.5), got {tolerance!r}")
    tile = check_int(tile, "tile", 1, 128)
    spare = check_int(spare, "spare", 0, 1 << 16)
    m = len(foliage)
    keep = np.ones((m, tile, tile), np.uint8)
    if m == 0:
        return keep
    _, up, right = card_frames(foliage)
    g = ((np.arange(tile) + 0.5) / tile - 0.5).astype(np.float32)
    for lo in range(0, m, chunk):
        sl = slice(lo, min(m, lo + chunk))
        size = foliage.size[sl, None, None, None].astype(np.float32)
        pts = (foliage.positions[sl, None, None, :].astype(np.float32)
               + g[None, None, :, None] * size * right[sl, None, None, :].astype(np.float32)
               - g[None, :, None, None] * size * up[sl, None, None, :].astype(np.float32)).reshape(-1, 3)
        held = np.zeros(len(pts), np.int16)
        tree = np.zeros(len(pts), np.int16)
        for cam, mk in zip(cameras, masks):
            uvz = cam.project(pts, dtype=np.float32)
            (h, w), u, v = mk.shape, np.floor(uvz[:, 0]), np.floor(uvz[:, 1])
            inside = (u >= 0) & (u < w) & (v >= 0) & (v < h) & (uvz[:, 2] > 0)
            held += inside
            tree += inside & mk.ravel()[np.where(inside, v * w + u, 0).astype(np.int64)]
        allowed = np.maximum(tolerance * held, spare)
        keep[sl] = (held - tree <= allowed).reshape(-1, tile, tile)
    return keep
