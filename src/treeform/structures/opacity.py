"""OpacityGrid: how much a tree blocks the light per metre of a ray, on a regular grid of voxels.

A crown is porous: the radial distance map (:mod:`treeform.structures.rdm`) keeps only its
outer surface, so a relief impostor drawn from it is solid where the mesh shows sky through
the crown. The grid keeps, per voxel, the extinction coefficient ``sigma`` (1/m) of the
leaves and wood inside it (:func:`treeform.geometry.opacity.opacity_grid`); a ray blocks
``1 - exp(-integral of sigma)`` of what lies behind (Beer-Lambert), and the relief impostor
hits the tree where that reaches one half (:mod:`treeform.render.impostor`).

Wood thinner than a voxel would fade in the grid (its share of a voxel blocks less than half a
ray through it), so the trunk and the limbs that show at a distance are kept beside it as
capsules (:attr:`OpacityGrid.wood`): opaque, hit exactly, drawn in the bark's colour.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from treeform._shared.errors import InputError
from treeform.structures._npz import load_npz, save_npz

MAX_WOOD = 32
"""Most capsules an :class:`OpacityGrid` holds (the shader's fixed uniform arrays)."""
HALF_COVERAGE = float(np.log(2.0))
"""Optical depth at which a ray is half blocked: where the impostor's surface lies along it."""


def trilinear_corners(q: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The 8 voxels around each point of a grid of ``n^3`` and their trilinear weights.

    ``q`` (N, 3) are positions in voxel units (0 at the grid's corner, voxel centres at
    ``i + 0.5``). Returns the flat ``[z, y, x]`` indices (8, N), clamped to the grid's edge as a
    linearly filtered texture clamps them, and the weights (8, N), summing to 1 for each point.
    """
    p = np.asarray(q, np.float64).reshape(-1, 3) - 0.5
    i0 = np.floor(p).astype(np.int64)
    f = p - i0
    cells, weights = [], []
    for dz in (0, 1):
        for dy in (0, 1):
            for dx in (0, 1):
                idx = np.clip(i0 + (dx, dy, dz), 0, n - 1)
                cells.append((idx[:, 2] * n + idx[:, 1]) * n + idx[:, 0])
                weights.append(np.where(dx, f[:, 0], 1 - f[:, 0]) * np.where(dy, f[:, 1], 1 - f[:, 1])
                               * np.where(dz, f[:, 2], 1 - f[:, 2]))
    return np.stack(cells), np.stack(weights)


@dataclass
class OpacityGrid:
    """Extinction coefficient per voxel of an axis-aligned cube of ``N^3`` voxels.

    Parameters
    ----------
    sigma : ndarray, shape (N, N, N), float32
        Extinction coefficient in 1/m, indexed ``[z, y, x]`` (x fastest: a 3D texture's order);
        voxel ``(k, j, i)`` spans ``origin + voxel * (i, j, k)`` to ``origin + voxel * (i + 1, j + 1, k + 1)``
        and its value holds at its centre.
    origin : ndarray, shape (3,)
        The cube's lowest corner, metres.
    voxel : float
        Edge of a voxel, metres.
    wood : ndarray, shape (K, 7), float32, optional
        Opaque capsules beside the grid, ``(ax, ay, az, bx, by, bz, r)`` in metres (segment ``a``-``b``
        swept by a sphere of radius ``r``), at most :data:`MAX_WOOD`: the trunk and the limbs the grid
        would fade (:func:`treeform.geometry.opacity.wood_capsules`). Their area is not in ``sigma``.
    bark : ndarray, shape (3,), optional
        The capsules' albedo, RGB in [0, 1].

    Examples
    --------
    >>> g = OpacityGrid(np.full((4, 4, 4), 2.0, np.float32), np.zeros(3), 0.25)
    >>> round(float(g.optical_depth(np.array([[-1.0, 0.5, 0.5]]), np.array([[1.0, 0, 0]]))[0]), 2)
    2.0
    """

    sigma: np.ndarray
    origin: np.ndarray
    voxel: float
    wood: np.ndarray | None = None
    bark: np.ndarray | None = None

    def __post_init__(self):
        self.sigma = np.ascontiguousarray(self.sigma, np.float32)
        self.origin = np.asarray(self.origin, np.float64).reshape(3)
        self.voxel = float(self.voxel)
        self.wood = np.zeros((0, 7), np.float32) if self.wood is None else np.ascontiguousarray(self.wood, np.float32)
        self.bark = np.array([0.35, 0.28, 0.22]) if self.bark is None else np.asarray(self.bark, np.float64).reshape(-1)
        self.validate()

    @property
    def resolution(self) -> int:
        return self.sigma.shape[0]

    @property
    def extent(self) -> float:
        """Edge of the whole cube, metres."""
        return self.voxel * self.resolution

    def validate(self) -> None:
        s = self.sigma
        if s.ndim != 3 or len(set(s.shape)) != 1 or s.shape[0] < 1:
            raise InputError(f"OpacityGrid.sigma: expected (N, N, N), got {s.shape}")
        if not np.all(np.isfinite(s)) or s.min() < 0:
            raise InputError("OpacityGrid.sigma: must be finite and non-negative")
        if not np.all(np.isfinite(self.origin)) or not (np.isfinite(self.voxel) and self.voxel > 0):
            raise InputError("OpacityGrid: origin must be finite and voxel > 0")
        w = self.wood
        if w.ndim != 2 or w.shape[1] != 7 or len(w) > MAX_WOOD:
            raise InputError(f"OpacityGrid.wood: expected (K, 7) capsules, K <= {MAX_WOOD}, got {w.shape}")
        if not np.all(np.isfinite(w)) or (len(w) and w[:, 6].min() <= 0):
            raise InputError("OpacityGrid.wood: capsules must be finite with a radius > 0")
        if self.bark.shape != (3,) or not np.all((self.bark >= 0) & (self.bark <= 1)):
            raise InputError(f"OpacityGrid.bark: expected an RGB albedo in [0, 1], got {self.bark}")

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The cube's (min, max) corners."""
        return self.origin.copy(), self.origin + self.extent

    def sample(self, points: np.ndarray) -> np.ndarray:
        """Trilinear ``sigma`` (N,) at points (N, 3), as a linearly filtered 3D texture clamped to its
        edge reads it; 0 outside the cube."""
        q = (np.asarray(points, np.float64).reshape(-1, 3) - self.origin) / self.voxel
        n = self.resolution
        cells, weights = trilinear_corners(q, n)
        out = (self.sigma.reshape(-1)[cells] * weights).sum(0)
        return np.where(np.all((q >= 0) & (q <= n), axis=1), out, 0.0)

    def optical_depth(self, origins: np.ndarray, directions: np.ndarray, *, steps: int | None = None) -> np.ndarray:
        """Integral of ``sigma`` (N,) along each ray (N, 3) + t (N, 3) through the cube (midpoint rule)."""
        o = np.asarray(origins, np.float64).reshape(-1, 3)
        d = np.asarray(directions, np.float64).reshape(-1, 3)
        d = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
        lo, hi = self.bounds()
        with np.errstate(divide="ignore", invalid="ignore"):
            ta, tb = (lo - o) / d, (hi - o) / d
        t0 = np.nanmax(np.minimum(ta, tb), axis=1).clip(min=0.0)
        t1 = np.nanmin(np.maximum(ta, tb), axis=1)
        steps = int(steps or 4 * self.resolution)
        span = np.clip(t1 - t0, 0.0, None)
        dt = span / steps
        tau = np.zeros(len(o))
        for k in range(steps):
            t = t0 + dt * (k + 0.5)
            tau += self.sample(o + d * t[:, None]) * dt
        return tau

    def wood_hit(self, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """Distance (N,) along each ray to its first capsule of :attr:`wood`, ``inf`` where it meets none
        (the shader's test, for checks on the CPU)."""
        o = np.asarray(origins, np.float64).reshape(-1, 3)
        d = np.asarray(directions, np.float64).reshape(-1, 3)
        d = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
        best = np.full(len(o), np.inf)
        for ax, ay, az, bx, by, bz, r in self.wood.astype(np.float64):
            best = np.minimum(best, capsule_hit(o, d, np.array([ax, ay, az]), np.array([bx, by, bz]), r))
        return best

    def save(self, path):
        return save_npz(path, "OpacityGrid", sigma=self.sigma, origin=self.origin, voxel=np.float64(self.voxel),
                        wood=self.wood, bark=self.bark)

    @classmethod
    def load(cls, path) -> "OpacityGrid":
        d = load_npz(path, "OpacityGrid")
        return cls(d["sigma"], d["origin"], float(d["voxel"]), d.get("wood"), d.get("bark"))


def capsule_hit(o: np.ndarray, d: np.ndarray, a: np.ndarray, b: np.ndarray, r: float) -> np.ndarray:
    """Distance (N,) along rays ``o + t d`` (unit ``d``, both (N, 3)) to where they enter the capsule
    ``a``-``b`` of radius ``r``; ``inf`` for a ray that misses it or starts inside it.

    The cylinder's side first (a quadratic in ``t`` with the part along the axis removed), then,
    where that hit falls beyond an end, the sphere at that end.

    Examples
    --------
    >>> t = capsule_hit(np.array([[0.0, 0.5, -5.0]]), np.array([[0.0, 0.0, 1.0]]), np.zeros(3),
    ...                 np.array([0.0, 1.0, 0.0]), 0.1)
    >>> round(float(t[0]), 6)
    4.9
    """
    tm = np.einsum("ij,ij->i", 0.5 * (a + b) - o, d)
    ba = b - a
    L2 = float(ba @ ba)
    oa = o + d * tm[:, None] - a  # from the ray's point nearest the middle: no cancellation for a far eye
    bd = d @ ba
    bo = oa @ ba
    # |(oa + t d) x ba|^2 = r^2 |ba|^2: the side of the infinite cylinder
    qa = L2 - bd * bd
    qb = L2 * np.einsum("ij,ij->i", d, oa) - bo * bd
    qc = L2 * np.einsum("ij,ij->i", oa, oa) - bo * bo - r * r * L2
    h = qb * qb - qa * qc
    out = np.full(len(o), np.inf)
    slanted = qa > 1e-9 * L2
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(slanted, (-qb - np.sqrt(np.maximum(h, 0.0))) / np.where(slanted, qa, 1.0), 0.0)
    y = np.where(slanted, bo + t * bd, -bd)  # (along the axis: the end the ray comes to first)
    body = (h >= 0) & slanted & (y > 0) & (y < L2)
    side = body & (tm + t > 0)
    out[side] = (tm + t)[side]
    # the end caps: the sphere at the end the side's hit went past
    rest = (h >= 0) & ~body
    oc = oa - np.where((y <= 0)[:, None], 0.0, ba)
    sb = np.einsum("ij,ij->i", d, oc)
    sc = np.einsum("ij,ij->i", oc, oc) - r * r
    sh = sb * sb - sc
    ts = tm - sb - np.sqrt(np.maximum(sh, 0.0))
    cap = rest & (sh >= 0) & (ts > 0)
    out[cap] = ts[cap]
    return out