"""Stages shared by the single-photo methods (envelope 001, learned 003): photo in, segmentation, cameras.

- :func:`load_photo` — a path / array / Photo reduced to a working size, and an optional user mask;
- :func:`segment_or_mask` — the automatic segmentation, or the user's mask labelled;
- :func:`photo_camera` — the camera that took the photo, in a world where the trunk base is the origin;
- :func:`continued_crown`, :func:`on_canvas` — a crown the frame cuts, continued past it, and the
  photo's masks on the larger canvas that holds it;
- :func:`render_previews` — front, side and top renders framed on the tree (also ``treeform grow``'s);
- :func:`photo_metrics` — how the renders agree with the photo (silhouette, depth, colour, structure).
"""

from __future__ import annotations

import math

import numpy as np

from treeform._shared.errors import InputError
from treeform.structures import Camera, Photo

__all__ = ["as_photo", "fit_photo", "load_photo", "segment_or_mask", "photo_camera", "continued_crown", "on_canvas",
           "render_previews", "photo_metrics"]


def as_photo(photo, max_size: int) -> Photo:
    from treeform.io.images import read_photo

    if isinstance(photo, Photo):
        return photo
    if isinstance(photo, np.ndarray):
        if photo.ndim != 3 or photo.shape[2] != 3 or photo.dtype != np.uint8:
            raise InputError(f"photo: expected an (H, W, 3) uint8 array, got {photo.shape} {photo.dtype}")
        return Photo(np.ascontiguousarray(photo))
    return read_photo(photo, max_size=max_size)


def fit_photo(photo: Photo, max_size: int) -> Photo:
    """Downscale so the long side is at most ``max_size``."""
    h, w = photo.shape
    s = max_size / max(h, w)
    if s >= 1:
        return photo
    from PIL import Image

    im = Image.fromarray(photo.image).resize((max(1, round(w * s)), max(1, round(h * s))), Image.LANCZOS)
    return Photo(np.asarray(im), photo.source, photo.scale * s)


def photo_camera(width: int, height: int, layout, tree_height: float, fov_y: float) -> tuple[Camera, float]:
    """The camera that took the photo, in a world where the trunk base is the origin.

    The tree spans ``layout.height_px`` pixels and is ``tree_height`` metres tall, which
    fixes metres per pixel m on the plane z = 0 through the trunk; the camera at distance
    D = focal · m on +Z looks along -Z at that plane, so the plane maps onto the photo
    pixel for pixel.

    Returns
    -------
    camera : Camera
    m : float
        Metres per pixel on the z = 0 plane.
    """
    m = tree_height / layout.height_px
    focal = 0.5 * height / math.tan(math.radians(fov_y) / 2)
    dist = focal * m
    bu, bv = layout.base
    cx = (width / 2 - bu) * m
    cy = (bv - height / 2) * m
    cam = Camera(width, height, fov_y, (cx, cy, dist), (cx, cy, 0.0), (0.0, 1.0, 0.0),
                 near=max(dist - 4 * tree_height, dist * 0.05), far=dist + 4 * tree_height)
    return cam, m


def continued_crown(layout, *, enabled: bool = True) -> tuple[np.ndarray, tuple[int, int], object]:
    """A crown the photo's frame cuts, continued past it (:func:`treeform.crown.frame.beyond_frame`).

    Parameters
    ----------
    layout : TreeLayout
        The photo's tree layout (:func:`treeform.crown.layout.tree_layout`).
    enabled : bool
        False: the crown as the photo shows it (no canvas around the frame).

    Returns
    -------
    crown : ndarray, shape (H + top, W + left + right), bool
        The crown's silhouette on a canvas around the photo, continued past the edges it cuts.
    offset : (int, int)
        ``(top, left)``: the photo's pixel (u, v) is ``crown[v + top, u + left]``.
    layout : TreeLayout
        ``layout`` with its ``top_row`` at the continued crown's top (above the photo: negative),
        so that :func:`photo_camera` gives the whole tree its height.
    """
    import dataclasses

    from treeform.crown.frame import beyond_frame

    if not enabled:
        return layout.crown_mask, (0, 0), layout
    crown, (top, left) = beyond_frame(layout.crown_mask)
    top_row = min(layout.top_row, int(np.flatnonzero(crown.any(1))[0]) - top) if crown.any() else layout.top_row
    return crown, (top, left), dataclasses.replace(layout, top_row=top_row)


def on_canvas(frame: np.ndarray, crown: np.ndarray, offset: tuple[int, int], fill=True) -> np.ndarray:
    """``frame`` (the photo's mask or labels) placed on ``crown``'s canvas, the continued crown around it as ``fill``.

    >>> crown = np.zeros((4, 5), bool); crown[0, 1:4] = True            # the crown continued one row up
    >>> on_canvas(np.ones((3, 5), np.uint8) * 2, crown, (1, 0), fill=1)[:, 2].tolist()
    [1, 2, 2, 2]
    """
    frame = np.asarray(frame)
    out = np.where(crown, fill, 0).astype(frame.dtype)
    top, left = offset
    out[top:top + frame.shape[0], left:left + frame.shape[1]] = frame
    return out


def load_photo(photo, mask=None, *, max_size: int) -> tuple[Photo, np.ndarray | None]:
    """The photo reduced to ``max_size`` on its long side, and the user's tree mask at its size (or None).

    A cut-out (an image file whose alpha leaves part of it transparent, e.g. an RGBA PNG of a
    tree alone) brings its own mask: without ``mask``, its alpha is the tree (over half
    opaque), and the tree's pixels keep their own colours rather than the blend with white
    that :func:`~treeform.io.images.read_photo` draws.
    """
    from treeform.io.images import read_cutout, read_mask

    ph = fit_photo(as_photo(photo, max(max_size, 64)), max_size)
    user_mask = None
    if mask is not None:
        user_mask = read_mask(mask, ph.shape) if not isinstance(mask, np.ndarray) else np.asarray(mask)
    elif not isinstance(photo, (np.ndarray, Photo)):
        cut = read_cutout(photo, ph.shape)
        if cut is not None:
            alpha, rgb = cut
            user_mask = alpha >= 0.5
            image = ph.image.copy()
            image[user_mask] = rgb[user_mask]
            ph = Photo(image, ph.source, ph.scale)
    return ph, user_mask


def segment_or_mask(image: np.ndarray, user_mask, *, segmenter: str, seed: int):
    """The user's mask labelled foliage / wood, or the automatic segmentation (``segmenter``; a photo
    without a tree raises :class:`NoTreeFoundError`, see :func:`treeform.segment.segment`)."""
    from treeform.segment import mask_to_segmentation, segment

    if user_mask is not None:
        return mask_to_segmentation(user_mask, image)
    return segment(image, method=segmenter, seed=seed, require_tree=True)


def render_previews(mesh, *, front: Camera | None = None, lighting=None, fov_y: float = 35.0,
                    size: int = 512, samples: int = 1) -> dict:
    """Front, side and top renders of ``mesh``, every view framed on the whole tree.

    The cameras are :func:`treeform.report.preview_cameras` of the mesh's vertices: with
    ``front`` (the photo's camera) the front view keeps that camera and only widens its
    image, so :func:`treeform.report.photo_window` cuts the photo's view back out of it;
    the side view shares the front's scale; the top view looks down on the whole crown.

    Parameters
    ----------
    mesh : Mesh
    front : Camera, optional
        The photo's camera; without it the front camera is fitted (``fov_y``, ``size``
        pixels high).
    lighting : Lighting, optional
    fov_y, size
        Field of view (degrees) and image height of a fitted front camera.
    samples : int
        MSAA samples (:class:`treeform.render.Renderer`). One by default: the depth pre-pass
        then shades each pixel once (three views 0.35 -> 0.16 s on llvmpipe), MSAA would
        smooth only triangle edges (not the alpha-tested leaf cards that make most of a
        crown's outline), and the preview panels are downscaled with a Lanczos filter.

    Returns
    -------
    dict
        ``{"front", "side", "top"} -> RenderResult`` (each with its ``camera``).
    """
    from treeform.render import Renderer
    from treeform.report import preview_cameras

    pts = [part.positions for part in mesh.parts if part.n_vertices]
    cams = preview_cameras(np.concatenate(pts) if pts else np.zeros((1, 3)), front=front, fov_y=fov_y, size=size)
    renderer = Renderer(cams["front"], lighting=lighting, samples=samples)
    renders = {}
    try:
        for name, view in cams.items():
            renderer.camera = view
            renders[name] = renderer.render(mesh)
    finally:
        renderer.release()
    return renders


def photo_metrics(renders: dict, photo_camera: Camera, image: np.ndarray, tree_mask: np.ndarray) -> dict:
    """How the reconstruction's renders agree with the photo it came from.

    The photo's frame is cut from the widened front render (:func:`treeform.report.photo_window`);
    where the render is empty the photo shows through, so the colour figures judge the tree
    pixels only.

    Parameters
    ----------
    renders : dict
        :func:`render_previews` with ``front=photo_camera``.
    photo_camera : Camera
    image : ndarray, shape (H, W, 3), uint8
        The photo.
    tree_mask : ndarray, shape (H, W), bool
        The segmentation's tree pixels.

    Returns
    -------
    dict
        ``reprojection_error`` (seed 004 eq. 3) and ``iou`` of the front silhouette against
        ``tree_mask``; ``depth_width_ratio`` (side extent over front extent); ``front_ssim``
        (mean SSIM inside ``tree_mask``) and ``front_color_distance`` (Hellinger distance of
        the RGB histograms inside ``tree_mask``, 0 = same colours) of the front render
        against the photo; ``side_color_distance``: the side render's tree pixels against
        the photo's (the side shows cards the camera never saw: their colours should still
        be the photo tree's, not its sky or its background).
    """
    from treeform.metrics import color_distance, extent_ratio, iou, reprojection_error, ssim
    from treeform.report import photo_window

    window = photo_window(renders["front"].camera, photo_camera)
    front = renders["front"]
    mask = front.mask[window]
    shown = np.where(mask[..., None], front.color[window][..., :3], image)
    tree = np.asarray(tree_mask, bool)
    has_tree = bool(tree.any())
    return {
        "reprojection_error": reprojection_error(mask, tree),
        "iou": iou(mask, tree),
        "depth_width_ratio": extent_ratio(renders["side"].mask, front.mask),
        "front_ssim": round(ssim(shown, image, tree), 4) if has_tree else 0.0,
        "front_color_distance": round(color_distance(shown, image, tree), 4) if has_tree else 1.0,
        "side_color_distance": (round(color_distance(renders["side"].color[..., :3], image, renders["side"].mask,
                                                     reference_mask=tree), 4)
                                if has_tree and renders["side"].mask.any() else 1.0),
    }


def load_and_segment(photo, mask, *, max_size: int, segmenter: str, seed: int, timer):
    """The "load" and "segment" stages every single-photo method starts with.

    Returns
    -------
    (Photo, Segmentation, TreeLayout)
        The photo reduced to ``max_size``, its segmentation (or the user's mask) and the tree's
        layout (:func:`treeform.crown.layout.tree_layout`).
    """
    with timer.stage("load"):
        ph, user_mask = load_photo(photo, mask, max_size=max_size)
    with timer.stage("segment"):
        from treeform.crown.layout import tree_layout

        seg = segment_or_mask(ph.image, user_mask, segmenter=segmenter, seed=seed)
        layout = tree_layout(seg)
    return ph, seg, layout


def model_metrics(skeleton, foliage, mesh, *, photo_size, metres_per_pixel: float) -> dict:
    """The model's size and shape figures every single-photo method reports in metrics.json."""
    from treeform.metrics.treeform_metrics import crown_extents, stems_at, tree_height

    return {
        "nodes": skeleton.n_nodes,
        "tips": int(len(skeleton.tips())),
        "leaves": len(foliage),
        "vertices": mesh.n_vertices,
        "triangles": mesh.n_triangles,
        "photo_size": [int(v) for v in photo_size],
        "metres_per_pixel": metres_per_pixel,
        "tree_height_m": tree_height(skeleton),
        "stems_at_5_percent": stems_at(skeleton, fraction=0.05),
        **crown_extents(skeleton),
    }
