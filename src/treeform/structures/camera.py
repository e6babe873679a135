"""Camera: a pinhole perspective camera in treeform's world (metres, Y up)."""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from treeform._shared.errors import InputError


def _normalize(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


@dataclass
class Camera:
    """Perspective camera; image row 0 is the top of the picture.

    Parameters
    ----------
    width, height : int
        Image size in pixels.
    fov_y : float
        Vertical field of view in degrees.
    position, target, up : sequence of 3 floats
        Eye, look-at point and up vector in world coordinates.
    near, far : float
        Clip distances in metres.

    Examples
    --------
    >>> cam = Camera(100, 100, 90.0, (0, 0, 1), (0, 0, 0))
    >>> uvz = cam.project(np.array([[0.0, 0.0, 0.0]]))
    >>> np.allclose(uvz, [[50, 50, 1]])
    True
    """

    width: int
    height: int
    fov_y: float
    position: tuple = (0.0, 0.0, 10.0)
    target: tuple = (0.0, 0.0, 0.0)
    up: tuple = (0.0, 1.0, 0.0)
    near: float = 0.1
    far: float = 1000.0

    def __post_init__(self):
        self.position = tuple(float(x) for x in self.position)
        self.target = tuple(float(x) for x in self.target)
        self.up = tuple(float(x) for x in self.up)
        self.validate()

    def validate(self) -> None:
        if int(self.width) < 1 or int(self.height) < 1:
            raise InputError(f"Camera: image size must be positive, got {self.width}x{self.height}")
        if not (0 < self.fov_y < 180):
            raise InputError(f"Camera.fov_y: expected 0 < fov_y < 180 degrees, got {self.fov_y}")
        if not (0 < self.near < self.far):
            raise InputError(f"Camera: expected 0 < near < far, got {self.near}, {self.far}")
        if np.allclose(self.position, self.target):
            raise InputError("Camera: position and target coincide")

    @property
    def focal(self) -> float:
        """Focal length in pixels."""
        return 0.5 * self.height / math.tan(math.radians(self.fov_y) / 2)

    def axes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Right, true-up and forward unit vectors (world)."""
        f = _normalize(np.subtract(self.target, self.position))
        r = _normalize(np.cross(f, self.up))
        u = np.cross(r, f)
        return r, u, f

    def view_matrix(self) -> np.ndarray:
        """(4, 4) world -> eye (OpenGL: camera looks down -Z)."""
        r, u, f = self.axes()
        m = np.eye(4)
        m[0, :3], m[1, :3], m[2, :3] = r, u, -f
        m[:3, 3] = -m[:3, :3] @ np.asarray(self.position)
        return m

    def projection_matrix(self) -> np.ndarray:
        """(4, 4) OpenGL perspective projection."""
        t = 1.0 / math.tan(math.radians(self.fov_y) / 2)
        a = self.width / self.height
        n, fa = self.near, self.far
        return np.array([
            [t / a, 0, 0, 0],
            [0, t, 0, 0],
            [0, 0, (fa + n) / (n - fa), 2 * fa * n / (n - fa)],
            [0, 0, -1, 0],
        ])

    def project(self, points: np.ndarray, *, dtype=np.float64) -> np.ndarray:
        """World points (N, 3) -> (N, 3): pixel column u, pixel row v, depth along the view axis.

        Pixel (0, 0) is the top-left corner of the image; pixel centres are at +0.5. ``dtype``
        float32 halves the memory and time of projecting millions of points (texels).
        """
        p = np.asarray(points, dtype).reshape(-1, 3) - np.asarray(self.position, dtype)
        r, u, f = (np.asarray(a, dtype) for a in self.axes())
        x, y, z = p @ r, p @ u, p @ f
        fl = dtype(self.focal)
        with np.errstate(divide="ignore", invalid="ignore"):
            return np.stack([self.width / 2 + fl * x / z, self.height / 2 - fl * y / z, z], axis=1)

    def unproject(self, u, v, depth) -> np.ndarray:
        """Pixel coordinates and depth along the view axis -> world points (N, 3)."""
        u, v, depth = (np.asarray(a, np.float64).reshape(-1) for a in (u, v, depth))
        r, up, f = self.axes()
        fl = self.focal
        x = (u - self.width / 2) * depth / fl
        y = (self.height / 2 - v) * depth / fl
        return np.asarray(self.position) + np.outer(x, r) + np.outer(y, up) + np.outer(depth, f)

    def orbit(self, yaw_deg: float = 0.0, pitch_deg: float = 0.0) -> "Camera":
        """A copy rotated about the target: yaw about +Y, then pitch up (degrees)."""
        off = np.subtract(self.position, self.target)
        dist = float(np.linalg.norm(off))
        yaw, pitch = math.radians(yaw_deg), math.radians(pitch_deg)
        d0 = off / dist
        az = math.atan2(d0[0], d0[2]) + yaw
        el = math.asin(np.clip(d0[1], -1, 1)) + pitch
        el = float(np.clip(el, -math.radians(89.9), math.radians(89.9)))
        d = np.array([math.sin(az) * math.cos(el), math.sin(el), math.cos(az) * math.cos(el)])
        pos = np.asarray(self.target) + dist * d
        return Camera(self.width, self.height, self.fov_y, tuple(pos), self.target, (0.0, 1.0, 0.0), self.near, self.far)

    def to_dict(self) -> dict:
        return asdict(self)

    def save(self, path) -> Path:
        path = Path(path)
        path.write_text(json.dumps(self.to_dict(), indent=1))
        return path

    @classmethod
    def load(cls, path) -> "Camera":
        try:
            return cls(**json.loads(Path(path).read_text()))
        except (OSError, json.JSONDecodeError, TypeError) as exc:
            raise InputError(f"{path}: not a treeform camera file ({type(exc).__name__})") from None


def box_camera(lo, hi, azimuth: float, elevation: float, size: int) -> Camera:
    """A narrow-angle (near-orthographic, 8°) square camera looking at the box lo..hi's centre.

    It stands on the direction (azimuth about +Y from +Z, elevation up from the horizon, in
    degrees) at the distance where the box's bounding sphere fills the image; looking straight
    down or up (|elevation| > 80°), image up is -Z.

    Examples
    --------
    >>> cam = box_camera(np.zeros(3), np.ones(3), 0.0, 0.0, 64)
    >>> [round(float(x), 3) for x in cam.project(np.array([[0.5, 0.5, 0.5]]))[0, :2]]
    [32.0, 32.0]
    """
    lo, hi = np.asarray(lo, np.float64), np.asarray(hi, np.float64)
    center = 0.5 * (lo + hi)
    radius = max(1e-3, 0.5 * float(np.linalg.norm(hi - lo)))
    fov = 8.0
    dist = radius / math.sin(math.radians(fov) / 2)
    az, el = math.radians(azimuth), math.radians(elevation)
    d = np.array([math.cos(el) * math.sin(az), math.sin(el), math.cos(el) * math.cos(az)])
    up = (0.0, 0.0, -1.0) if abs(elevation) > 80 else (0.0, 1.0, 0.0)
    return Camera(int(size), int(size), fov, tuple(float(x) for x in center + dist * d),
                  tuple(float(x) for x in center), up, near=max(1e-3, dist - 1.2 * radius), far=dist + 1.2 * radius)
