"""RadialDistanceMap: crown radius per direction, stored as a cubemap (seed 001 §3.5)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from treeform._shared.errors import InputError
from treeform.structures._npz import load_npz, save_npz

# Cubemap faces in OpenGL order: +X, -X, +Y, -Y, +Z, -Z. For each face the rows give
# (sc, tc, ma) as linear functions of the direction (OpenGL spec table 8.19).
CUBE_FACE_MATRICES = np.array([
    [[0, 0, -1], [0, -1, 0], [1, 0, 0]],    # +X
    [[0, 0, 1], [0, -1, 0], [-1, 0, 0]],    # -X
    [[1, 0, 0], [0, 0, 1], [0, 1, 0]],      # +Y
    [[1, 0, 0], [0, 0, -1], [0, -1, 0]],    # -Y
    [[1, 0, 0], [0, -1, 0], [0, 0, 1]],     # +Z
    [[-1, 0, 0], [0, -1, 0], [0, 0, -1]],   # -Z
], dtype=np.float64)


def direction_to_texel(directions: np.ndarray, resolution: int):
    """Directions (N, 3) -> (face, row, col) integer arrays of a cubemap of side ``resolution``.

    Row index follows the face's t coordinate (row 0 at t = -1).
    """
    d = np.asarray(directions, np.float64).reshape(-1, 3)
    a = np.abs(d)
    axis = np.argmax(a, axis=1)
    neg = d[np.arange(len(d)), axis] < 0
    face = axis * 2 + neg
    m = CUBE_FACE_MATRICES[face]
    sc = np.einsum("nj,nj->n", m[:, 0], d)
    tc = np.einsum("nj,nj->n", m[:, 1], d)
    ma = np.maximum(np.einsum("nj,nj->n", m[:, 2], d), 1e-12)
    col = np.clip(((sc / ma + 1) * 0.5 * resolution).astype(np.int64), 0, resolution - 1)
    row = np.clip(((tc / ma + 1) * 0.5 * resolution).astype(np.int64), 0, resolution - 1)
    return face, row, col


def texel_directions(resolution: int) -> np.ndarray:
    """Unit directions through every texel centre: shape (6, R, R, 3)."""
    c = (np.arange(resolution) + 0.5) / resolution * 2 - 1
    tc, sc = np.meshgrid(c, c, indexing="ij")
    local = np.stack([sc, tc, np.ones_like(sc)], axis=-1)  # (R, R, 3) in (sc, tc, ma)
    out = np.empty((6, resolution, resolution, 3))
    for f in range(6):
        # rows of the face matrix are orthonormal, so its transpose maps (sc, tc, ma) back
        out[f] = local @ CUBE_FACE_MATRICES[f]
    return out / np.linalg.norm(out, axis=-1, keepdims=True)


@dataclass
class RadialDistanceMap:
    """Distance from the crown centre to the crown surface, per direction.

    Parameters
    ----------
    center : ndarray, shape (3,)
        Crown centre ``c`` in metres.
    radii : ndarray, shape (6, R, R), float32
        Radius per cubemap texel, faces in OpenGL order (+X, -X, +Y, -Y, +Z, -Z).

    Examples
    --------
    >>> rdm = RadialDistanceMap(np.zeros(3), np.ones((6, 8, 8), np.float32))
    >>> rdm.contains(np.array([[0.5, 0, 0], [0, 2.0, 0]])).tolist()
    [True, False]
    """

    center: np.ndarray
    radii: np.ndarray

    def __post_init__(self):
        self.center = np.asarray(self.center, np.float64).reshape(3)
        self.radii = np.ascontiguousarray(self.radii, np.float32)
        self.validate()

    @property
    def resolution(self) -> int:
        return self.radii.shape[1]

    def validate(self) -> None:
        r = self.radii
        if r.ndim != 3 or r.shape[0] != 6 or r.shape[1] != r.shape[2] or r.shape[1] < 1:
            raise InputError(f"RadialDistanceMap.radii: expected (6, R, R), got {r.shape}")
        if not np.all(np.isfinite(r)) or r.min() < 0:
            raise InputError("RadialDistanceMap.radii: must be finite and non-negative")
        if not np.all(np.isfinite(self.center)):
            raise InputError("RadialDistanceMap.center: must be finite")

    def lookup(self, directions: np.ndarray) -> np.ndarray:
        """Radius (N,) along each direction (N, 3); directions need not be unit length.

        The texel is :func:`direction_to_texel`'s, found by a compiled loop (the crown
        sampling and ray marching call this hundreds of thousands of times a tree).
        """
        from treeform._shared import rdm_kernels as _rdm_kernels

        d = np.ascontiguousarray(np.asarray(directions, np.float64).reshape(-1, 3))
        return _rdm_kernels.lookup(d, self.radii)

    def contains(self, points: np.ndarray) -> np.ndarray:
        """(N,) bool: whether each point (N, 3) lies inside the crown (within the radius of its direction)."""
        from treeform._shared import rdm_kernels as _rdm_kernels

        p = np.ascontiguousarray(np.asarray(points, np.float64).reshape(-1, 3))
        return _rdm_kernels.contains(p, self.center, self.radii)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Axis-aligned bounding box (min, max) of the crown surface points (one per texel,
        along :func:`texel_directions`)."""
        from treeform._shared import rdm_kernels as _rdm_kernels

        lo, hi = _rdm_kernels.bounds(CUBE_FACE_MATRICES, self.center, self.radii)
        return lo, hi

    def mean_radius(self) -> float:
        return float(self.radii.mean())

    def save(self, path):
        return save_npz(path, "RadialDistanceMap", center=self.center, radii=self.radii)

    @classmethod
    def load(cls, path) -> "RadialDistanceMap":
        return cls(**load_npz(path, "RadialDistanceMap"))
