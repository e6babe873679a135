"""Trees of one photo placed on a common ground plane from their feet's pixels (issue 16 item 2).

Seed 003 (Fig. 16) crops the trees of a photo by hand and places the reconstructions by hand.
Here the photo's camera places them. The model:

- a pinhole camera of vertical field of view ``fov_y``, level (its axis horizontal), at a height
  ``h`` above flat ground, so the horizon is the row ``v_h`` through the principal point;
- every tree stands on that ground: its foot at pixel (u, v), v below the horizon, is at depth
  ``Z = f h / (v - v_h)`` and lateral offset ``X = (u - c_x) Z / f`` (f: focal length in pixels);
  its top row gives its height ``(v - top) Z / f``;
- one absolute scale: the camera is ``camera_height`` metres above the ground (1.6 m: a photo
  taken standing), or, when ``main_height`` is given, the reference tree (by default the
  tallest in pixels) is that tall, which fixes ``h`` (a single photo has no absolute scale;
  the single-tree routes assume a tree height the same way).

If a foot is at or above the centre row (the camera looked up), the horizon is taken just above
the highest foot instead. The scene's frame is the single-tree routes' frame: Y up, metres, the
reference tree's foot at the origin, the camera on the +Z side looking along -Z. Each tree is
turned to face the camera (the side the photo shows), as the single-tree routes face it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from treeform._shared.errors import InputError
from treeform.structures import Camera

__all__ = ["GroundPlacement", "place_on_ground"]


@dataclass
class GroundPlacement:
    """Where :func:`place_on_ground` put the trees, and the camera that saw them."""

    camera: Camera
    """The photo's camera in the scene's frame."""
    camera_height: float
    """Metres above the ground."""
    horizon_row: float
    """Image row of the horizon (y down)."""
    positions: np.ndarray
    """(N, 3) feet on the ground (y = 0), the reference tree at the origin."""
    yaws: np.ndarray
    """(N,) turn about +Y (radians) so each tree shows the camera its photographed side."""
    heights: np.ndarray
    """(N,) metres."""
    distances: np.ndarray
    """(N,) depth along the camera's axis, metres."""
    reference: int
    """Index of the tree whose height set the scale."""


def place_on_ground(bases, tops, width: int, height: int, *, fov_y: float = 40.0, camera_height: float = 1.6,
                    main_height: float | None = None, reference: int | None = None) -> GroundPlacement:
    """Place trees seen in one photo on the ground plane.

    Parameters
    ----------
    bases : array_like, shape (N, 2)
        (u, v) pixel of each tree's foot (u: column, v: row, y down).
    tops : array_like, shape (N,)
        Each tree's highest row.
    width, height : int
        The photo's size in pixels.
    fov_y : float
        Vertical field of view in degrees (the single-photo routes' default: 40).
    camera_height : float
        Metres from the ground to the camera (the scale, unless ``main_height`` is given).
    main_height : float, optional
        Height of the reference tree in metres (then it sets the scale and the camera's height).
    reference : int, optional
        Index of the reference tree (default: the tallest in pixels); the scene's origin is its foot.

    Returns
    -------
    GroundPlacement

    Examples
    --------
    A tree 10 m tall on the left, and on the right a smaller one whose foot is nearer the
    horizon (row 240): it stands farther, right and behind; the feet project back onto their pixels.

    >>> p = place_on_ground([[100, 400], [500, 300]], [100, 200], 640, 480, main_height=10.0, reference=0)
    >>> p.heights.round(2).tolist(), p.positions.round(2).tolist()
    ([10.0, 8.95], [[0.0, 0.0, 0.0], [23.26, 0.0, -36.51]])
    >>> p.camera.project(p.positions)[:, :2].round(3).tolist()
    [[100.0, 400.0], [500.0, 300.0]]
    """
    b = np.asarray(bases, np.float64).reshape(-1, 2)
    t = np.asarray(tops, np.float64).reshape(-1)
    if len(b) == 0 or len(t) != len(b):
        raise InputError(f"bases / tops: expected N >= 1 feet and N tops, got {len(b)} and {len(t)}")
    if not (np.all(np.isfinite(b)) and np.all(np.isfinite(t))):
        raise InputError("bases / tops: expected finite pixels")
    if not 5.0 <= fov_y <= 120.0:
        raise InputError(f"fov_y: expected 5..120 degrees, got {fov_y}")
    for name, val in (("camera_height", camera_height), ("main_height", main_height)):
        if val is not None and not (val > 0 and math.isfinite(val)):
            raise InputError(f"{name}: expected a positive number of metres, got {val}")
    px = b[:, 1] - t + 1.0
    if np.any(px <= 0):
        raise InputError("tops: every tree's top must be above its foot")
    f = 0.5 * height / math.tan(math.radians(fov_y) / 2)
    cx, cy = 0.5 * width, 0.5 * height
    # the horizon lies above the feet: a foot above the centre says the camera looked up. With three
    # feet or more the second highest decides, so one foot alone above the others (a false one in a
    # crown or on a far hedge, a tree up a slope) does not lift the horizon and push every other tree
    # away; a foot above the horizon is placed as far as one 2 % of the photo under it (where the
    # foot that sets the horizon stands, too)
    rows = np.sort(b[:, 1])
    horizon = min(cy, float(rows[1 if len(rows) >= 3 else 0]) - 0.02 * height)
    ref = int(np.argmax(px)) if reference is None else int(reference)
    if not 0 <= ref < len(b):
        raise InputError(f"reference: expected 0..{len(b) - 1}, got {reference}")
    drop = np.maximum(b[:, 1] - horizon, 0.02 * height)  # pixels below the horizon, > 0
    cam_h = float(camera_height) if main_height is None else main_height * drop[ref] / px[ref]
    depth = f * cam_h / drop
    lateral = (b[:, 0] - cx) * depth / f
    heights = px * depth / f
    # camera-centred: trees at (X, 0, -Z), the camera at (0, h, 0); shifted so the reference is the origin
    pos = np.stack([lateral - lateral[ref], np.zeros(len(b)), depth[ref] - depth], 1)
    cam_pos = np.array([-lateral[ref], cam_h, depth[ref]])
    yaws = np.arctan2(-lateral, depth)  # each tree's +Z (its photographed side) toward the camera
    pitch_row = horizon - cy  # a raised horizon: the camera looked up by the angle of that many rows
    pitch = math.atan2(-pitch_row, f)
    target = cam_pos + np.array([0.0, math.tan(pitch) * 10.0, -10.0])
    near = max(0.05, 0.2 * float(depth.min()))
    cam = Camera(int(width), int(height), float(fov_y), tuple(cam_pos), tuple(target), (0.0, 1.0, 0.0),
                 near=near, far=max(2000.0, float(depth.max()) * 4.0 + 10.0 * float(heights.max())))
    return GroundPlacement(cam, float(cam_h), float(horizon), pos, yaws, heights, depth, ref)
