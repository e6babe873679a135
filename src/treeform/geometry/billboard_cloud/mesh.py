"""Stage 5 of the billboard cloud: the reference camera's frame and one alpha-tested quad per billboard."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from treeform._shared.checks import check_array, check_positive
from treeform._shared.errors import InputError, NoTreeFoundError
from treeform.geometry.billboard_cloud.placement import Placement
from treeform.structures.camera import Camera
from treeform.structures.mesh import Material, Mesh, MeshPart


@dataclass(frozen=True)
class CloudFrame:
    """Image pixels → world metres, and the reference (photo) camera of a billboard cloud.

    World: metres, Y up, the tree's base at the origin, the picture plane at z = 0 and the
    camera on +Z at distance ``distance`` looking toward -Z through the picture's centre,
    with the vertical field of view ``fov_y``. A point at image position (x, y) and depth
    z (pixels) is put on that camera's ray through (x, y), so the camera sees it at (x, y).

    Parameters
    ----------
    width, height : int
        Picture size (pixels).
    metres_per_pixel : float
        Size of a pixel on the picture plane.
    origin : (float, float)
        Image position of the tree's base (world origin).
    fov_y : float
        Vertical field of view of the reference camera (degrees).
    """

    width: int
    height: int
    metres_per_pixel: float
    origin: tuple
    fov_y: float = 10.0

    @classmethod
    def for_tree(cls, tree, *, tree_height: float = 10.0, fov_y: float = 10.0) -> "CloudFrame":
        """The frame of a picture whose opaque pixels ``tree`` (H, W) are ``tree_height`` metres tall.

        The origin is the middle of the tree's lowest row of pixels, at its bottom edge.
        """
        tree = check_array(tree, "tree", ndim=2).astype(bool)
        check_positive(tree_height, "tree_height")
        if not 0 < float(fov_y) < 120:
            raise InputError(f"fov_y: expected degrees in (0, 120), got {fov_y!r}")
        rows = np.nonzero(tree.any(1))[0]
        if rows.size == 0:
            raise NoTreeFoundError("tree: no opaque pixels")
        bottom = int(rows.max())
        cols = np.nonzero(tree[bottom])[0]
        s = float(tree_height) / (bottom + 1 - rows.min())
        return cls(tree.shape[1], tree.shape[0], s, ((cols.min() + cols.max() + 1) / 2.0, bottom + 1.0),
                   float(fov_y))

    @property
    def distance(self) -> float:
        """Camera distance to the picture plane (metres)."""
        return self.height * self.metres_per_pixel / (2.0 * math.tan(math.radians(self.fov_y) / 2.0))

    @property
    def centre(self) -> np.ndarray:
        """(3,) world position of the picture's centre (the camera's target)."""
        s = self.metres_per_pixel
        return np.array([(self.width / 2.0 - self.origin[0]) * s, (self.origin[1] - self.height / 2.0) * s, 0.0])

    def to_world(self, x, y, z) -> np.ndarray:
        """Image positions and depths (pixels, arrays of one shape) → (..., 3) world points.

        Examples
        --------
        >>> f = CloudFrame(100, 100, 0.1, (50.0, 100.0))
        >>> cam = f.camera()
        >>> p = f.to_world(np.array([20.5, 70.5]), np.array([10.5, 90.5]), np.array([30.0, -25.0]))
        >>> np.allclose(cam.project(p)[:, :2], [[20.5, 10.5], [70.5, 90.5]])
        True
        """
        s = self.metres_per_pixel
        x, y, z = np.broadcast_arrays(*(np.asarray(a, np.float64) for a in (x, y, z)))
        plane = np.stack([(x - self.origin[0]) * s, (self.origin[1] - y) * s, np.zeros_like(x)], axis=-1)
        eye = self.centre + [0.0, 0.0, self.distance]
        t = (self.distance - z * s) / self.distance
        return eye + (plane - eye) * t[..., None]

    def camera(self, width: int | None = None, height: int | None = None) -> Camera:
        """The reference camera, optionally rendering at another size (same field of view)."""
        w = self.width if width is None else int(width)
        h = self.height if height is None else int(height)
        d = self.distance
        reach = 1.5 * max(self.width, self.height) * self.metres_per_pixel
        centre = self.centre
        return Camera(w, h, self.fov_y, tuple(centre + [0.0, 0.0, d]), tuple(centre),
                      near=max(d - reach, 1e-3 * d), far=d + reach)


def cloud_mesh(placement: Placement, boxes, rects, atlas, frame: CloudFrame, *, name: str = "billboard_cloud",
               tolerance: float = 0.1) -> Mesh:
    """Textured quads, one per billboard, in one part with one MASK material (seed 000 §6).

    Each quad is its crop box centred at the billboard's image position, turned by its
    yaw about the vertical line through its centre, every vertex put on the reference
    camera's ray through its image point (:meth:`CloudFrame.to_world`); UVs are the crop's
    atlas rectangle; vertex colours carry the shade. The material is double-sided,
    alpha-tested at 0.5.

    A turned quad on those rays is a trapezoid, whose triangles map the texture affinely
    where the front view needs a projective map; the texture slips by about
    ``(w/K) max(w/K, h) |tan yaw| s / (4 d)`` pixels in a w x h quad cut into K vertical
    strips (s metres per pixel, d the camera distance). K is the smallest count that
    keeps this within ``tolerance``: 1 or 2 for superpixels, dozens for a wide trunk.

    Parameters
    ----------
    placement : Placement
    boxes : ndarray, shape (n, 4), int
        Crop boxes ``(x0, y0, w, h)`` (their sizes are used).
    rects : ndarray, shape (n, 4), int
        Atlas rectangles ``(u0, v0, w, h)`` (:func:`build_atlas`).
    atlas : ndarray, shape (Ha, Wa, 4), uint8
    frame : CloudFrame
    tolerance : float
        Largest texture slip of the front view, pixels.

    Returns
    -------
    Mesh
        One part: 2 (K + 1) vertices and 2 K triangles per billboard.
    """
    boxes = np.asarray(boxes, np.int64)
    rects = np.asarray(rects, np.int64)
    check_positive(tolerance, "tolerance")
    m = len(placement)
    if m == 0:
        raise InputError("placement: no billboards")
    spr = placement.sprite
    w, h = boxes[spr, 2].astype(np.float64), boxes[spr, 3].astype(np.float64)
    tan = np.tan(placement.yaw)
    c = np.abs(tan) * frame.metres_per_pixel / (4.0 * frame.distance * tolerance)
    k = np.maximum(1, np.ceil(np.maximum(w * np.sqrt(c), w * h * c))).astype(np.int64)
    # vertex columns: billboard b has k[b] + 1 of them, each a top and a bottom vertex
    col_start = np.concatenate([[0], np.cumsum(k + 1)])
    b = np.repeat(np.arange(m), k + 1)
    f = (np.arange(col_start[-1]) - col_start[b]) / k[b]  # 0 .. 1 across the billboard
    dx = (f - 0.5) * w[b]
    x = placement.x[b] + dx
    z = placement.z[b] + dx * tan[b]
    top = frame.to_world(x, placement.y[b] - h[b] / 2.0, z)
    bottom = frame.to_world(x, placement.y[b] + h[b] / 2.0, z)
    pos = np.stack([top, bottom], 1).reshape(-1, 3)  # vertex 2c: top of column c, 2c + 1: its bottom
    ah, aw = atlas.shape[:2]
    u = (rects[spr[b], 0] + f * rects[spr[b], 2]) / aw
    v0 = rects[spr[b], 1] / ah
    v1 = (rects[spr[b], 1] + rects[spr[b], 3]) / ah
    uv = np.stack([np.stack([u, v0], 1), np.stack([u, v1], 1)], 1).reshape(-1, 2)
    first = col_start[:-1]  # the normal of a billboard from its first strip (all strips are coplanar)
    nrm = np.cross(bottom[first] - top[first], top[first + 1] - top[first])
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    col = np.ones((len(b), 4))
    col[:, :3] = placement.shade[b, None]
    c = np.flatnonzero(np.arange(col_start[-1]) + 1 < col_start[b + 1])  # columns with a strip to their right
    tl, bl, tr, br = 2 * c, 2 * c + 1, 2 * c + 2, 2 * c + 3
    idx = np.stack([np.stack([tl, bl, br], 1), np.stack([tl, br, tr], 1)], 1).reshape(-1, 3)
    mat = Material(name=name, texture=atlas, alpha_mode="MASK", alpha_cutoff=0.5, double_sided=True,
                   roughness=1.0, metallic=0.0)
    part = MeshPart(pos, np.repeat(nrm[b], 2, axis=0), uv, np.repeat(col, 2, axis=0), idx, mat, name)
    return Mesh([part])
