"""preview.png: photo | segmentation overlay | front | side | top, side by side, each panel labelled.

- :func:`preview_cameras` — front, side and top cameras that show the whole tree with a margin
  (the front may be the photo's own camera, widened);
- :func:`photo_window` — where the photo's frame lies in the widened front view;
- :func:`preview_windows` — the part of each render a panel shows: the tree and a margin;
- :func:`preview_strip` — the labelled panels of preview.png;
- :func:`compose_strip` — tiles scaled to one height, left to right, with a label above each;
- :func:`segmentation_overlay`, :func:`over_checkerboard` — tiles for masks and RGBA images.
"""

from __future__ import annotations

import math

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from treeform._shared.errors import InputError
from treeform.structures.camera import Camera
from treeform.structures.segmentation import Segmentation

PREVIEW_LABELS = {"photo": "photo", "segmentation": "segmentation", "front": "front", "side": "side (from the right)",
                  "top": "top (from above)"}
"""Panel labels of preview.png, by panel name."""

PREVIEW_MARGIN = 0.04
"""Background round the tree in a preview panel, as a fraction of the front view's height."""


def segmentation_overlay(image: np.ndarray, seg: Segmentation) -> np.ndarray:
    """Photo with background dimmed, foliage tinted green and wood tinted red.

    Returns
    -------
    ndarray, shape (H, W, 3), uint8
    """
    img = image.astype(np.float32)
    out = img * 0.35
    fol, wood = seg.foliage_mask, seg.wood_mask
    out[fol] = 0.55 * img[fol] + 0.45 * np.float32([40, 220, 60])
    out[wood] = 0.55 * img[wood] + 0.45 * np.float32([230, 50, 40])
    edge = seg.tree_mask & ~np.pad(seg.tree_mask, 1)[2:, 1:-1] | seg.tree_mask & ~np.pad(seg.tree_mask, 1)[:-2, 1:-1]
    out[edge] = (255, 255, 0)
    return np.clip(out, 0, 255).astype(np.uint8)


def _font(size: int):
    """Pillow's bundled font at ``size`` pixels (the fixed bitmap font without FreeType)."""
    try:
        return ImageFont.load_default(size=size)
    except (TypeError, ImportError, OSError):  # Pillow < 10.1 or no FreeType
        return ImageFont.load_default()


def compose_strip(tiles: list, *, labels=None, height: int = 360, gap: int = 6,
                  background=(255, 255, 255)) -> np.ndarray:
    """Scale every (H, W, 3) uint8 tile to ``height`` and place them left to right.

    Parameters
    ----------
    tiles : list of ndarray, shape (H, W, 3) or (H, W, 4), uint8
        Only the first three channels are used.
    labels : list of str, optional
        One per tile: written in dark grey in a band above the tile (Pillow's bundled font,
        scaled with ``height``), and a thin grey frame drawn round each tile so white
        renders stand apart. A tile narrower than its label is widened with ``background``
        (the picture centred), so no label runs into the next.
    height : int
        Height of every tile in pixels.
    gap : int
        Pixels between tiles and round the strip.
    background : sequence of 3 ints

    Returns
    -------
    ndarray, shape (height + 2 gap [+ label band], W, 3), uint8
    """
    if labels is not None and len(labels) != len(tiles):
        raise InputError(f"labels: expected {len(tiles)} labels (one per tile), got {len(labels)}")
    scaled = []
    for t in tiles:
        im = Image.fromarray(np.ascontiguousarray(np.asarray(t)[..., :3]))
        w = max(1, round(im.width * height / im.height))
        scaled.append(np.asarray(im.resize((w, height), Image.LANCZOS)))
    band = 0 if labels is None else max(12, round(0.075 * height))
    if labels is not None:  # a tile narrower than its label is widened (centred on the background)
        font = _font(max(8, round(0.72 * band)))
        probe = ImageDraw.Draw(Image.new("RGB", (1, 1)))
        for i, text in enumerate(labels):
            need = int(np.ceil(probe.textlength(str(text), font=font))) + 4
            if need > scaled[i].shape[1]:
                left = (need - scaled[i].shape[1]) // 2
                pad = np.empty((height, need, 3), np.uint8)
                pad[:] = background
                pad[:, left:left + scaled[i].shape[1]] = scaled[i]
                scaled[i] = pad
    total = sum(s.shape[1] for s in scaled) + gap * (len(scaled) + 1)
    out = np.empty((height + 2 * gap + band, total, 3), np.uint8)
    out[:] = background
    x, top = gap, gap + band
    boxes = []
    for s in scaled:
        out[top:top + height, x:x + s.shape[1]] = s
        boxes.append(x)
        x += s.shape[1] + gap
    if labels is None:
        return out
    img = Image.fromarray(out)
    draw = ImageDraw.Draw(img)
    baseline = draw.textbbox((0, 0), "Aphotog", font=font)[3]  # one baseline for every label
    for x0, s, text in zip(boxes, scaled, labels):
        if gap > 0:
            draw.rectangle([x0 - 1, top - 1, x0 + s.shape[1], top + height], outline=(200, 200, 200))
        draw.text((x0 + 2, top - 3 - baseline), str(text), fill=(40, 40, 40), font=font)
    return np.asarray(img)


def _span(hit: np.ndarray, keep: slice | None, margin: int, n: int) -> slice:
    """``hit``'s first..last True index, joined with ``keep``, widened by ``margin``, within [0, n)."""
    idx = np.flatnonzero(hit)
    lo, hi = (int(idx[0]), int(idx[-1]) + 1) if len(idx) else (0, n)
    if keep is not None:
        lo, hi = min(lo, keep.start), max(hi, keep.stop)
    return slice(max(lo - margin, 0), min(hi + margin, n))


def preview_windows(masks: dict, *, keep: tuple | None = None, margin: int | None = None) -> dict:
    """The part of each view's image a preview panel shows: the tree's silhouette and a margin.

    Parameters
    ----------
    masks : dict
        ``{"front", "side", "top"} -> (H, W) bool`` silhouettes of :func:`preview_cameras`'
        views (front and side share their height).
    keep : (slice, slice), optional
        Rows and columns of the front view that stay in its panel whatever the silhouette
        (the photo's frame, :func:`photo_window`).
    margin : int, optional
        Background pixels kept round the silhouette; default :data:`PREVIEW_MARGIN` of the
        front's height (at least 2).

    Returns
    -------
    dict
        ``name -> (rows, cols)`` slices. Front and side keep the same rows, so they stay at
        one scale, the ground at the same height.
    """
    h = (masks["front"] if "front" in masks else next(iter(masks.values()))).shape[0]
    m = max(2, round(PREVIEW_MARGIN * h)) if margin is None else int(margin)
    keep_r, keep_c = keep if keep is not None else (None, None)
    out = {}
    upright = [k for k in ("front", "side") if k in masks and masks[k].shape[0] == h]
    if upright:
        rows_hit = np.logical_or.reduce([np.asarray(masks[k], bool).any(axis=1) for k in upright])
        rows = _span(rows_hit, keep_r if "front" in upright else None, m, h)
    for name, mask in masks.items():
        mask = np.asarray(mask, bool)
        k_c = keep_c if name == "front" else None
        cols = _span(mask.any(axis=0), k_c, m, mask.shape[1])
        r = rows if name in upright else _span(mask.any(axis=1), None, m, mask.shape[0])
        out[name] = (r, cols)
    return out


def preview_strip(renders: dict, *, photo: np.ndarray | None = None, segmentation: Segmentation | None = None,
                  keep: tuple | None = None, height: int = 360) -> np.ndarray:
    """preview.png: [photo | segmentation overlay |] front | side | top, each panel labelled.

    Parameters
    ----------
    renders : dict
        ``{"front", "side", "top"} ->`` render results of :func:`preview_cameras`' views
        (objects with ``mask`` and ``rgb()``, e.g. :class:`treeform.render.RenderResult`);
        each panel shows its :func:`preview_windows` window.
    photo : ndarray, shape (H, W, 3), uint8, optional
        The photo, shown first.
    segmentation : Segmentation, optional
        Shown over ``photo`` (:func:`segmentation_overlay`) as the second panel.
    keep : (slice, slice), optional
        The photo's frame in the front view (:func:`photo_window`), kept in its panel.
    height : int
        Panel height in pixels.

    Returns
    -------
    ndarray, shape (H, W, 3), uint8
    """
    tiles, labels = [], []
    if photo is not None:
        tiles.append(photo)
        labels.append(PREVIEW_LABELS["photo"])
        if segmentation is not None:
            tiles.append(segmentation_overlay(photo, segmentation))
            labels.append(PREVIEW_LABELS["segmentation"])
    names = [k for k in ("front", "side", "top") if k in renders]
    windows = preview_windows({k: renders[k].mask for k in names}, keep=keep)
    for name in names:
        tiles.append(renders[name].rgb()[windows[name]])
        labels.append(PREVIEW_LABELS[name])
    return compose_strip(tiles, labels=labels, height=height)


def _view_tangents(position, target, up, points: np.ndarray):
    """Points in a camera's frame: (x / z, y / z, z) with x right, y up, z along the view."""
    cam = Camera(2, 2, 90.0, position, target, up)
    r, u, f = cam.axes()
    rel = points - np.asarray(cam.position)
    z = np.maximum(rel @ f, 1e-9)
    return rel @ r / z, rel @ u / z, z


def _clip_planes(depth: np.ndarray, near: float | None = None, far: float | None = None) -> tuple[float, float]:
    """Near and far planes that keep every depth (widening ``near``/``far`` when given)."""
    lo, hi = float(depth.min()), float(depth.max())
    n = max(0.5 * lo, 1e-4 * hi, 1e-4)
    f = 1.5 * hi + 1e-3
    if near is not None:
        n, f = min(near, n), max(far, f)
    return n, f


def _ceil(x: float) -> int:
    """Ceiling that ignores float noise (200.0000001 -> 200)."""
    return math.ceil(x - 1e-6)


def preview_cameras(points, *, front: Camera | None = None, fov_y: float = 35.0, size: int = 512,
                    margin: float = PREVIEW_MARGIN) -> dict:
    """Front, side and top cameras that show every point with a margin of background.

    * **front** — with ``front`` given (a photo's camera), that camera's position, view and
      focal length are kept and only its image grows, by the same number of pixels on
      opposite sides, until every point projects at least ``margin`` inside it; the photo's
      frame is then the centre window (:func:`photo_window`), pixel for pixel. Without it,
      a camera on +Z looks along -Z at the centre of the points' box from the distance at
      which the points fill ``size`` pixels of height, and the image is as wide as they need.
    * **side** — looks along -X from +X at the same height and distance (from the box's
      centre) and with the same focal length and image height as the front, so the two share
      one scale and a silhouette's widths compare (e.g. the depth / width ratio); its width
      is what the points need.
    * **top** — looks straight down (image up = -Z, so the tree's front, +Z, is at the
      bottom) at the box's centre, from the distance at which the crown's larger horizontal
      extent fills the image height (the front's).

    Parameters
    ----------
    points : array_like, shape (N, 3)
        What must be in view, e.g. every vertex of the tree's mesh (metres, Y up).
    front : Camera, optional
        The front camera to keep (its image is widened, never cropped).
    fov_y : float
        Vertical field of view in degrees of a fitted front (without ``front``).
    size : int
        Image height in pixels of a fitted front (without ``front``).
    margin : float
        Background margin round the points, as a fraction of the front image's height
        (at least 2 pixels).

    Returns
    -------
    dict
        ``{"front": Camera, "side": Camera, "top": Camera}``.

    Examples
    --------
    >>> pts = np.array([[-2.0, 0, -1], [2, 0, 1], [0, 6, 0]])
    >>> cams = preview_cameras(pts, size=200)
    >>> uv = cams["top"].project(pts)
    >>> bool(np.all((uv[:, :2] > 2) & (uv[:, :2] < [[cams["top"].width - 2, cams["top"].height - 2]])))
    True
    """
    p = np.asarray(points, np.float64).reshape(-1, 3)
    if len(p) == 0 or not np.all(np.isfinite(p)):
        raise InputError(f"points: expected a non-empty (N, 3) array of finite values, got shape {p.shape}")
    if front is not None and not isinstance(front, Camera):
        raise InputError(f"front: expected a Camera, got {type(front).__name__}")
    lo, hi = p.min(0), p.max(0)
    c = 0.5 * (lo + hi)
    span = float(max((hi - lo).max(), 1e-3))
    if front is None:
        if not 0 < fov_y < 180:
            raise InputError(f"fov_y: expected 0 < fov_y < 180 degrees, got {fov_y!r}")
        if int(size) < 8:
            raise InputError(f"size: expected an image height of at least 8 pixels, got {size!r}")
        focal = 0.5 * size / math.tan(math.radians(fov_y) / 2)
        m = max(2.0, margin * size)
        k = (0.5 * size - m) / focal  # tan of the half-angle the points may fill
        # the nearest distance at which front (along -Z) and side (along -X) both fit the height
        dist = float(np.max(np.abs(p[:, 1] - c[1]) / k + np.maximum(p[:, 2] - c[2], p[:, 0] - c[0])))
        dist = max(dist, float(np.max(np.maximum(p[:, 2] - c[2], p[:, 0] - c[0]))) + 0.25 * span)
        pos, tgt, up = (c[0], c[1], c[2] + dist), tuple(c), (0.0, 1.0, 0.0)
        w0, h0 = 0, int(size)
        clip = (None, None)
    else:
        focal = front.focal
        m = max(2.0, margin * front.height)
        pos, tgt, up = front.position, front.target, front.up
        dist = float(np.linalg.norm(np.subtract(pos, tgt)))
        w0, h0 = int(front.width), int(front.height)
        clip = (front.near, front.far)
    fx, fy, fz = _view_tangents(pos, tgt, up, p)
    side_tgt = (c[0], tgt[1], c[2])
    sx, sy, sz = _view_tangents((c[0] + dist, tgt[1], c[2]), side_tgt, (0.0, 1.0, 0.0), p)
    half_h = max(0.5 * h0, focal * np.abs(fy).max() + m, focal * np.abs(sy).max() + m)
    if front is None:
        fw, fh = 2 * _ceil(focal * np.abs(fx).max() + m), 2 * _ceil(half_h)
    else:
        fw = w0 + 2 * max(0, _ceil(focal * np.abs(fx).max() + m - 0.5 * w0))
        fh = h0 + 2 * max(0, _ceil(half_h - 0.5 * h0))
    fov = math.degrees(2 * math.atan(0.5 * fh / focal))
    cams = {"front": Camera(fw, fh, fov, pos, tgt, up, *_clip_planes(fz, *clip))}
    sw = 2 * _ceil(focal * np.abs(sx).max() + m)
    cams["side"] = Camera(sw, fh, fov, (c[0] + dist, tgt[1], c[2]), side_tgt, (0.0, 1.0, 0.0), *_clip_planes(sz))
    # top: the distance above the highest point at which the larger horizontal extent fits
    k = (0.5 * fh - m) / focal
    below = hi[1] - p[:, 1]
    reach = np.maximum(np.abs(p[:, 0] - c[0]), np.abs(p[:, 2] - c[2]))
    rise = max(float(np.max(reach / k - below)), 0.25 * span)
    top_tgt = (c[0], hi[1], c[2])
    top_pos = (c[0], hi[1] + rise, c[2])
    tx, ty, tz = _view_tangents(top_pos, top_tgt, (0.0, 0.0, -1.0), p)
    tw = 2 * _ceil(focal * np.abs(tx).max() + m)
    cams["top"] = Camera(tw, fh, fov, top_pos, top_tgt, (0.0, 0.0, -1.0), *_clip_planes(tz))
    return cams


def photo_window(preview_front: Camera, photo: Camera) -> tuple[slice, slice]:
    """Rows and columns of ``preview_front``'s image that are ``photo``'s image.

    ``preview_front`` is :func:`preview_cameras`' front for ``front=photo``: the same camera
    with its image grown evenly, so its centre window is the photo's view pixel for pixel.
    """
    r0 = (int(preview_front.height) - int(photo.height)) // 2
    c0 = (int(preview_front.width) - int(photo.width)) // 2
    if r0 < 0 or c0 < 0:
        raise InputError("preview_front: smaller than the photo's camera")
    return slice(r0, r0 + int(photo.height)), slice(c0, c0 + int(photo.width))


def over_checkerboard(rgba, *, cell: int = 16) -> np.ndarray:
    """Composite an RGBA image over a grey checkerboard, so transparency shows.

    Returns
    -------
    ndarray, shape (H, W, 3), uint8
    """
    a = np.asarray(rgba)
    if a.ndim != 3 or a.shape[2] != 4:
        raise InputError(f"rgba: expected an (H, W, 4) array, got {a.shape}")
    h, w = a.shape[:2]
    yy, xx = np.mgrid[:h, :w]
    board = np.where(((yy // cell + xx // cell) % 2) == 0, 232.0, 196.0).astype(np.float32)[..., None]
    al = a[..., 3:4].astype(np.float32) / 255.0
    return np.clip(np.rint(a[..., :3] * al + board * (1.0 - al)), 0, 255).astype(np.uint8)
