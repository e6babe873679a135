"""SfmResult: registered cameras and 3D points of a photo collection (seed 002 §3, capture and SfM).

The container every multi-view stage reads. Camera axes follow OpenCV (x right, y down,
z forward); ``cam_to_world`` maps camera coordinates to the world of the result. Until
:func:`treeform.sfm.align.to_tree_frame` runs, the world is COLMAP's (arbitrary similarity);
afterwards it is treeform's (metres, Y up, tree base at the origin).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from treeform._shared.errors import InputError

__all__ = ["SfmResult", "render_camera"]


@dataclass
class SfmResult:
    """Cameras and points of one structure-from-motion model.

    Attributes
    ----------
    names : list of str, length C
        File names of the registered photos (the input folder's names), sorted.
    K : ndarray, shape (C, 3, 3)
        Pinhole intrinsics per registered photo, in pixels of ``sizes``.
    cam_to_world : ndarray, shape (C, 4, 4)
        Camera-to-world rigid transforms (OpenCV camera axes).
    sizes : ndarray, shape (C, 2), int
        (width, height) of each photo as the SfM saw it (EXIF orientation applied).
    points : ndarray, shape (P, 3), float64
        3D points in the world of the result.
    colors : ndarray, shape (P, 3), uint8
    errors : ndarray, shape (P,)
        Mean reprojection error of each point in pixels.
    tracks : list of ndarray, length P
        For each point an (n, 3) float array of (camera index into ``names``, x, y) observations.
    unregistered : list of str
        Photos given but not registered.
    meta : dict
        JSON-serialisable notes (focal prior source, timings, model count ...).
    """

    names: list
    K: np.ndarray
    cam_to_world: np.ndarray
    sizes: np.ndarray
    points: np.ndarray
    colors: np.ndarray
    errors: np.ndarray
    tracks: list
    unregistered: list = field(default_factory=list)
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        self.K = np.asarray(self.K, np.float64).reshape(-1, 3, 3)
        self.cam_to_world = np.asarray(self.cam_to_world, np.float64).reshape(-1, 4, 4)
        self.sizes = np.asarray(self.sizes, np.int64).reshape(-1, 2)
        self.points = np.asarray(self.points, np.float64).reshape(-1, 3)
        self.colors = np.asarray(self.colors, np.uint8).reshape(-1, 3)
        self.errors = np.asarray(self.errors, np.float64).reshape(-1)
        self.validate()

    @property
    def n_cameras(self) -> int:
        return len(self.names)

    @property
    def centers(self) -> np.ndarray:
        """(C, 3) camera centres in the world."""
        return self.cam_to_world[:, :3, 3].copy()

    def world_to_cam(self) -> np.ndarray:
        """(C, 4, 4) inverses of ``cam_to_world``."""
        return np.linalg.inv(self.cam_to_world)

    def project(self, points: np.ndarray, i: int) -> np.ndarray:
        """World points (N, 3) -> (N, 3): pixel x, pixel y, depth along camera ``i``'s z axis.

        Pixel (0, 0) is the top-left pixel's corner; a pixel's centre is at +0.5 (COLMAP's
        convention).
        """
        p = np.asarray(points, np.float64).reshape(-1, 3)
        w2c = np.linalg.inv(self.cam_to_world[i])
        pc = p @ w2c[:3, :3].T + w2c[:3, 3]
        z = pc[:, 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            uv = (pc @ self.K[i].T)[:, :2] / z[:, None]
        return np.column_stack([uv, z])

    def render_camera(self, i: int, *, near: float = 0.1, far: float = 1000.0, scale: float = 1.0):
        """Camera ``i`` as a treeform :class:`~treeform.structures.Camera` (for the renderer).

        The principal point is taken at the image centre and lens distortion is ignored
        (what the renderer can draw); ``scale`` resizes the image (e.g. 0.5 for half size).
        """
        return render_camera(self.K[i], self.cam_to_world[i], self.sizes[i], near=near, far=far, scale=scale)

    def transformed(self, scale: float, rotation: np.ndarray, translation: np.ndarray) -> "SfmResult":
        """The same model under x -> scale * R x + t (cameras stay rigid, their centres move)."""
        R = np.asarray(rotation, np.float64).reshape(3, 3)
        t = np.asarray(translation, np.float64).reshape(3)
        c2w = self.cam_to_world.copy()
        c2w[:, :3, :3] = R @ c2w[:, :3, :3]
        c2w[:, :3, 3] = scale * c2w[:, :3, 3] @ R.T + t
        return SfmResult(list(self.names), self.K.copy(), c2w, self.sizes.copy(),
                         scale * self.points @ R.T + t, self.colors.copy(), self.errors.copy(),
                         [tr.copy() for tr in self.tracks], list(self.unregistered), dict(self.meta))

    def cameras_json(self) -> dict:
        """``{name: {"K": 3x3, "cam_to_world": 4x4, "size": [w, h]}}`` (the multiview output's cameras.json)."""
        return {n: {"K": np.round(self.K[i], 6).tolist(), "cam_to_world": np.round(self.cam_to_world[i], 6).tolist(),
                    "size": [int(v) for v in self.sizes[i]]} for i, n in enumerate(self.names)}

    def validate(self) -> None:
        c = len(self.names)
        if not (len(self.K) == len(self.cam_to_world) == len(self.sizes) == c):
            raise InputError(f"SfmResult: {c} names but K {len(self.K)}, cam_to_world {len(self.cam_to_world)}, "
                             f"sizes {len(self.sizes)}")
        p = len(self.points)
        if not (len(self.colors) == len(self.errors) == len(self.tracks) == p):
            raise InputError(f"SfmResult: {p} points but colors {len(self.colors)}, errors {len(self.errors)}, "
                             f"tracks {len(self.tracks)}")
        if p and not np.all(np.isfinite(self.points)):
            raise InputError("SfmResult.points: must be finite")


def render_camera(K, cam_to_world, size, *, near: float = 0.1, far: float = 1000.0, scale: float = 1.0):
    """An OpenCV camera (x right, y down, z forward) as a treeform :class:`~treeform.structures.Camera`.

    The inverse of :func:`treeform.sfm.evaluate.opencv_camera`: the principal point is taken at
    the image centre and lens distortion is ignored (what the renderer can draw).

    Parameters
    ----------
    K : array_like, shape (3, 3)
    cam_to_world : array_like, shape (4, 4)
    size : (width, height)
        Pixels of the image ``K`` belongs to.
    near, far : float, keyword-only
    scale : float, keyword-only
        Resizes the image (e.g. 0.5 for half size; the field of view stays).

    Returns
    -------
    Camera

    Examples
    --------
    >>> T = np.eye(4); T[:3, 3] = (0.0, 1.0, 5.0); T[:3, 1:3] *= -1  # at z = 5, looking down -Z
    >>> cam = render_camera(np.array([[100.0, 0, 50], [0, 100.0, 40], [0, 0, 1]]), T, (100, 80))
    >>> cam.target, cam.up, round(cam.fov_y, 2)
    ((0.0, 1.0, 4.0), (0.0, 1.0, 0.0), 43.6)
    """
    from treeform.structures import Camera

    T = np.asarray(cam_to_world, np.float64).reshape(4, 4)
    R, c = T[:3, :3], T[:3, 3]
    sw, sh = (float(v) for v in size)
    w, h = max(1, int(round(sw * scale))), max(1, int(round(sh * scale)))
    fov_y = float(np.degrees(2.0 * np.arctan(0.5 * sh / float(np.asarray(K, np.float64)[1, 1]))))
    return Camera(w, h, fov_y, tuple(c), tuple(c + R[:, 2]), tuple(-R[:, 1]), near=near, far=far)
