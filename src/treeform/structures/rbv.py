"""RadialBoundingVolume: a tree's outer shape as layers x sectors of radii (seed 003 §4.1).

An RBV is an upright cylinder around the tree, of the tree's height ``h`` and maximum
horizontal extent ``r``, sliced into ``n`` layers (slabs of height ``h / n`` along +Y) and
every layer into ``m`` angular sectors around the vertical axis. Each sector stores the
outermost radial distance (from the vertical axis through the tree base) of the tree geometry
inside it, so the union of the sectors is a tight, concave bounding volume.

Conventions (fixed here, used by every treeform method):

* the axis is the vertical line through ``origin`` (the tree base); a point's local
  coordinates are ``p - origin``;
* layer ``i`` holds ``i * h / n <= y < (i + 1) * h / n`` (the top layer also holds
  ``y == h``), layer 0 at the base;
* the angle of a point is ``atan2(z, x)`` in ``[0, 2π)``, sector ``j`` holds
  ``j * 2π / m <= angle < (j + 1) * 2π / m``; sector 0 starts on +X and sectors advance
  from +X towards +Z;
* points below the base (``y < 0``) or above the top (``y > h``) are outside.

Resolutions follow the paper's five levels: level ``k`` has ``2**(k-1)`` layers and
``2**(k-1)`` sectors (1x1, 2x2, 4x4, 8x8, 16x16).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from treeform._shared.errors import InputError
from treeform.structures._npz import load_npz, save_npz

__all__ = ["LEVELS", "RadialBoundingVolume", "level_size"]

LEVELS = (1, 2, 3, 4, 5)
"""The RBV resolution levels of seed 003 §4.2.3: level k is 2**(k-1) layers x 2**(k-1) sectors."""

_TWO_PI = 2.0 * math.pi


def level_size(level) -> int:
    """Number of layers (= number of sectors) of RBV ``level`` (1..5): ``2**(level-1)``.

    Examples
    --------
    >>> [level_size(k) for k in LEVELS]
    [1, 2, 4, 8, 16]
    """
    if isinstance(level, bool) or not isinstance(level, (int, np.integer)) or int(level) not in LEVELS:
        raise InputError(f"level: expected an integer in 1..5, got {level!r}")
    return 2 ** (int(level) - 1)


def _polar(local: np.ndarray):
    """Local (N, 3) points -> (y (N,), radial distance (N,), angle fraction t in [0, 1) (N,))."""
    x, y, z = local[:, 0], local[:, 1], local[:, 2]
    r = np.hypot(x, z)
    ang = np.mod(np.arctan2(z, x), _TWO_PI)
    return y, r, ang / _TWO_PI


def _indices(y, t, height: float, n: int):
    """Layer and sector index (N,) each; y in [0, height] and t in [0, 1].

    ``y / height`` and ``t`` are multiplied by a power of two, so the index at level k is
    exactly the index at level k+1 divided by 2 (coarse cells are unions of fine cells).
    """
    layer = np.clip(np.floor(y / height * n).astype(np.int64), 0, n - 1)
    sector = np.clip(np.floor(t * n).astype(np.int64), 0, n - 1)
    return layer, sector


@dataclass(eq=False)
class RadialBoundingVolume:
    """Radial bounding volume of a tree (seed 003 §4.1).

    Parameters
    ----------
    radii : ndarray, shape (n, n), float64
        Outermost radial extent of each (layer, sector), in units of ``radial_scale``
        metres; row 0 is the bottom layer, column 0 the sector starting on +X. ``n`` is
        ``2**(level-1)`` for a level in 1..5. An empty sector has radius 0.
    height : float
        Cylinder height ``h`` (the tree's height above its base), in units of
        ``height_scale`` metres.
    origin : ndarray, shape (3,), float64
        The tree base in world metres: the axis is the vertical line through it and layer 0
        starts at its height. Not affected by normalisation.
    radial_scale, height_scale : float
        Metres per unit of ``radii`` and of ``height``: the physical volume has radii
        ``radii * radial_scale`` and height ``height * height_scale``. 1 for a volume in
        metres; :meth:`normalized` sets them (the per-species normalisation of §4.2.3 / §4.4)
        and :meth:`denormalized` folds them back into the values. The physical volume, and so
        :meth:`contains`, does not depend on them.

    Examples
    --------
    >>> pts = np.array([[1.0, 0, 0], [0, 2, 1], [-0.5, 4, 0]])
    >>> rbv = RadialBoundingVolume.from_points(pts, level=2)
    >>> rbv.radii.tolist(), rbv.height
    ([[1.0, 0.0], [1.0, 0.5]], 4.0)
    >>> rbv.contains(np.array([[0.9, 0.1, 0.01], [0.9, 0.1, -0.01], [0, 5, 0]])).tolist()
    [True, False, False]
    >>> rbv.at_level(1).radii.tolist()
    [[1.0]]
    """

    radii: np.ndarray
    height: float
    origin: np.ndarray = None
    radial_scale: float = 1.0
    height_scale: float = 1.0

    def __post_init__(self):
        self.radii = np.array(self.radii, dtype=np.float64, copy=True)
        try:
            self.height = float(self.height)
            self.radial_scale = float(self.radial_scale)
            self.height_scale = float(self.height_scale)
        except (TypeError, ValueError):
            raise InputError("RadialBoundingVolume: height, radial_scale and height_scale must be numbers") from None
        origin = np.zeros(3) if self.origin is None else self.origin
        self.origin = np.array(origin, dtype=np.float64, copy=True).reshape(-1)
        self.validate()

    # ------------------------------------------------------------------ properties
    @property
    def level(self) -> int:
        """Resolution level k (1..5): ``n_layers == n_sectors == 2**(k-1)``."""
        return int(self.radii.shape[0]).bit_length()

    @property
    def n_layers(self) -> int:
        return int(self.radii.shape[0])

    @property
    def n_sectors(self) -> int:
        return int(self.radii.shape[1])

    @property
    def radius(self) -> float:
        """Cylinder radius ``r`` (the largest sector radius), in units of ``radial_scale``."""
        return float(self.radii.max())

    @property
    def physical_radii(self) -> np.ndarray:
        """(n, n) sector radii in metres: ``radii * radial_scale``."""
        return self.radii * self.radial_scale

    @property
    def physical_height(self) -> float:
        """Cylinder height in metres: ``height * height_scale``."""
        return self.height * self.height_scale

    def layer_edges(self) -> np.ndarray:
        """(n + 1,) layer boundaries in metres above the base, from 0 to the physical height."""
        return np.linspace(0.0, self.physical_height, self.n_layers + 1)

    def sector_edges(self) -> np.ndarray:
        """(m + 1,) sector boundary angles in radians, from 0 to 2π (angle = atan2(z, x))."""
        return np.linspace(0.0, _TWO_PI, self.n_sectors + 1)

    def volume(self) -> float:
        """Enclosed volume in m³: ``Σ (2π / m) / 2 · r_ij² · h / n`` over all sectors."""
        dh = self.physical_height / self.n_layers
        return float(np.sum(self.physical_radii ** 2) * (math.pi / self.n_sectors) * dh)

    # ------------------------------------------------------------------ checks
    def validate(self) -> None:
        """Raise :class:`InputError` unless the arrays and scalars are consistent.

        ``radii`` must be (n, n) with n in {1, 2, 4, 8, 16}, finite and non-negative;
        ``height`` and both scales positive and finite; ``origin`` three finite numbers.
        """
        r = self.radii
        if r.ndim != 2 or r.shape[0] != r.shape[1] or r.shape[0] not in [level_size(k) for k in LEVELS]:
            raise InputError(f"RadialBoundingVolume.radii: expected shape (n, n) with n in 1, 2, 4, 8, 16; got {r.shape}")
        if not np.all(np.isfinite(r)) or r.min() < 0:
            raise InputError("RadialBoundingVolume.radii: must be finite and non-negative")
        for name in ("height", "radial_scale", "height_scale"):
            v = getattr(self, name)
            if not math.isfinite(v) or v <= 0:
                raise InputError(f"RadialBoundingVolume.{name}: expected a positive finite number, got {v!r}")
        if self.origin.shape != (3,) or not np.all(np.isfinite(self.origin)):
            raise InputError(f"RadialBoundingVolume.origin: expected 3 finite numbers, got shape {self.origin.shape}")

    # ------------------------------------------------------------------ construction
    @classmethod
    def _from_samples(cls, local: np.ndarray, extra: np.ndarray | None, level, origin) -> "RadialBoundingVolume":
        n = level_size(level)
        if len(local) == 0:
            raise InputError("points: expected at least one point, got none")
        y, r, t = _polar(local)
        around = None
        if extra is not None:
            # a branch tube that encloses the axis (distance < radius, e.g. the trunk)
            # reaches at least radius - distance in every direction of its layer
            around = np.maximum(extra - r, 0.0)
            r = r + extra
        if y.min() < 0:
            raise InputError(f"points: {int(np.sum(y < 0))} point(s) lie below the base (lowest y - origin = "
                             f"{y.min():.6g} m); the axis origin must be the tree base")
        height = float(y.max())
        if height <= 0:
            raise InputError("points: all points lie at the base height; an RBV needs a positive height")
        layer, sector = _indices(y, t, height, n)
        radii = np.zeros(n * n)
        np.maximum.at(radii, layer * n + sector, r)
        radii = radii.reshape(n, n)
        if around is not None and around.max() > 0:
            floor = np.zeros(n)
            np.maximum.at(floor, layer, around)
            radii = np.maximum(radii, floor[:, None])
        return cls(radii, height, origin)

    @classmethod
    def from_points(cls, points, *, level=4, axis_origin=(0.0, 0.0, 0.0)) -> "RadialBoundingVolume":
        """Fit an RBV tightly around a point set (seed 003 §4.1).

        The cylinder height is the highest point above ``axis_origin``; each sector's radius
        is the largest horizontal distance from the axis of the points falling in it (0 for
        an empty sector). Every input point is then :meth:`contains`-ed by the result.

        Parameters
        ----------
        points : array_like, shape (N, 3)
            Tree geometry in metres, Y up (e.g. mesh vertices or branch samples), N >= 1.
        level : int, keyword-only
            Resolution level 1..5 (``2**(level-1)`` layers and sectors); default 4 (8x8).
        axis_origin : array_like, shape (3,), keyword-only
            The tree base: the axis is the vertical line through it.

        Returns
        -------
        RadialBoundingVolume

        Raises
        ------
        InputError
            Bad shape, non-finite values, no points, a point below the base, or zero height.
        """
        pts = _as_points(points, "points")
        origin = _as_origin(axis_origin)
        return cls._from_samples(pts - origin, None, level, origin)

    @classmethod
    def from_skeleton(cls, skeleton, *, level=4, samples_per_segment=4) -> "RadialBoundingVolume":
        """Fit an RBV around a :class:`~treeform.structures.skeleton.TreeSkeleton`.

        Every segment (parent -> child) is sampled at ``samples_per_segment + 1`` evenly
        spaced points (its ends included), so long internodes that cross a layer or a sector
        still count; each sample's radial distance is grown by the branch radius interpolated
        there (the branch surface, not only its centre line; the radius is added in the
        sector of the centre line, a close bound for thin branches). The axis passes through
        the root node (``positions[0]``). A node below the root (a weeping branch reaching
        under the foot) counts in the lowest layer.

        Parameters
        ----------
        skeleton : TreeSkeleton
        level : int, keyword-only
            Resolution level 1..5; default 4.
        samples_per_segment : int, keyword-only
            Sub-segments per skeleton segment, >= 1.

        Returns
        -------
        RadialBoundingVolume
        """
        from treeform.structures.skeleton import TreeSkeleton

        if not isinstance(skeleton, TreeSkeleton):
            raise InputError(f"skeleton: expected a TreeSkeleton, got {type(skeleton).__name__}")
        if (isinstance(samples_per_segment, bool) or not isinstance(samples_per_segment, (int, np.integer))
                or samples_per_segment < 1):
            raise InputError(f"samples_per_segment: expected an integer >= 1, got {samples_per_segment!r}")
        origin = skeleton.positions[0].copy()
        pos, rad = skeleton.positions, skeleton.radius
        if skeleton.n_nodes == 1:
            samples, radius = pos[:1], rad[:1]
        else:
            child = np.arange(1, skeleton.n_nodes)
            par = skeleton.parent[1:]
            f = np.linspace(0.0, 1.0, int(samples_per_segment) + 1)[:, None]  # (S+1, 1)
            samples = (pos[par][None] * (1 - f[..., None]) + pos[child][None] * f[..., None]).reshape(-1, 3)
            radius = (rad[par][None] * (1 - f) + rad[child][None] * f).reshape(-1)
        local = samples - origin
        local[:, 1] = np.maximum(local[:, 1], 0.0)
        return cls._from_samples(local, radius, level, origin)

    # ------------------------------------------------------------------ queries
    def contains(self, points) -> np.ndarray:
        """Whether each point lies inside the volume (vectorised).

        A point is inside when ``0 <= y <= h`` (local, physical units) and its radial
        distance from the axis is at most the radius of the sector it falls in.

        Parameters
        ----------
        points : array_like, shape (N, 3)
            World positions in metres.

        Returns
        -------
        ndarray, shape (N,), bool
        """
        pts = _as_points(points, "points", allow_empty=True)
        if len(pts) == 0:
            return np.zeros(0, bool)
        y, r, t = _polar(pts - self.origin)
        h = self.physical_height
        n = self.n_layers
        inside = (y >= 0) & (y <= h)
        layer, sector = _indices(np.clip(y, 0.0, h), t, h, n)
        return inside & (r <= self.physical_radii[layer, sector])

    def sector_of(self, points):
        """(layer (N,), sector (N,)) int64 indices of world points; -1 where outside the height.

        Parameters
        ----------
        points : array_like, shape (N, 3)
        """
        pts = _as_points(points, "points", allow_empty=True)
        y, _, t = _polar(pts - self.origin)
        h = self.physical_height
        layer, sector = _indices(np.clip(y, 0.0, h), t, h, self.n_layers)
        out = (y < 0) | (y > h)
        return np.where(out, -1, layer), np.where(out, -1, sector)

    # ------------------------------------------------------------------ levels
    def at_level(self, level) -> "RadialBoundingVolume":
        """The same volume at another resolution level (1..5).

        Coarsening takes, for every coarse sector, the maximum of the fine sectors it
        contains (a coarse cell is exactly the union of 2^d x 2^d fine cells), so the coarse
        volume contains the fine one. Refining copies each sector's radius into the finer
        sectors it splits into (the same volume, resolved finer: no detail is invented).
        ``at_level(k).at_level(self.level)`` equals ``self`` when k >= ``self.level``.

        Parameters
        ----------
        level : int
            Target level 1..5.

        Returns
        -------
        RadialBoundingVolume
            A new volume; height, origin and scales are kept.
        """
        n = level_size(level)
        cur = self.n_layers
        if n == cur:
            radii = self.radii.copy()
        elif n < cur:
            f = cur // n
            radii = self.radii.reshape(n, f, n, f).max(axis=(1, 3))
        else:
            f = n // cur
            radii = np.repeat(np.repeat(self.radii, f, axis=0), f, axis=1)
        return RadialBoundingVolume(radii, self.height, self.origin, self.radial_scale, self.height_scale)

    def levels(self) -> list[np.ndarray]:
        """All five levels' radii, ``[(1, 1), (2, 2), (4, 4), (8, 8), (16, 16)]`` arrays.

        Levels coarser than ``self.level`` are exact maxima; finer levels are refinements
        (see :meth:`at_level`). These are the five regression targets of §4.2.3.

        Returns
        -------
        list of ndarray, shapes (2**(k-1), 2**(k-1)) for k = 1..5
        """
        return [self.at_level(k).radii for k in LEVELS]

    # ------------------------------------------------------------------ normalisation
    def normalized(self, *, height_scale=None, radial_scale=None) -> "RadialBoundingVolume":
        """A scale-free copy: radii and height divided by scale factors (seed 003 §4.2.3, §4.4).

        The paper trains on sector values "normalized per each species", storing "a scaling
        factor to obtain the final tree size" with the species, and notes that "the estimated
        RBV is normalized in vertical height". By default both factors are the volume's own
        physical height, so the result has height 1 and radii relative to the height (the
        shape's aspect is kept); pass a species' reference height (and, optionally, a separate
        radial reference) for a per-species normalisation. The factors are stored in
        ``height_scale`` / ``radial_scale``, so the result describes the same physical volume
        and :meth:`denormalized` is the inverse.

        Parameters
        ----------
        height_scale : float, keyword-only, optional
            Metres per normalised height unit; default the physical height.
        radial_scale : float, keyword-only, optional
            Metres per normalised radius unit; default ``height_scale``.

        Returns
        -------
        RadialBoundingVolume
        """
        hs = self.physical_height if height_scale is None else _positive(height_scale, "height_scale")
        rs = hs if radial_scale is None else _positive(radial_scale, "radial_scale")
        return RadialBoundingVolume(self.physical_radii / rs, self.physical_height / hs, self.origin, rs, hs)

    def denormalized(self) -> "RadialBoundingVolume":
        """The inverse of :meth:`normalized`: values in metres, both scales 1."""
        return RadialBoundingVolume(self.physical_radii, self.physical_height, self.origin, 1.0, 1.0)

    # ------------------------------------------------------------------ io
    def save(self, path):
        """Write an ``.npz`` file atomically; :meth:`load` restores it bit for bit."""
        return save_npz(path, "RadialBoundingVolume", radii=self.radii, height=np.float64(self.height),
                        origin=self.origin, radial_scale=np.float64(self.radial_scale),
                        height_scale=np.float64(self.height_scale))

    @classmethod
    def load(cls, path) -> "RadialBoundingVolume":
        """Read a file written by :meth:`save`; :class:`InputError` for anything else."""
        d = load_npz(path, "RadialBoundingVolume")
        try:
            return cls(d["radii"], d["height"][()], d["origin"], d["radial_scale"][()], d["height_scale"][()])
        except KeyError as exc:
            raise InputError(f"{path}: RadialBoundingVolume file lacks the array {exc}") from None


def _as_points(points, name: str, *, allow_empty: bool = False) -> np.ndarray:
    try:
        arr = np.asarray(points, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected an (N, 3) array of numbers") from None
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise InputError(f"{name}: expected shape (N, 3), got {arr.shape}")
    if not allow_empty and len(arr) == 0:
        raise InputError(f"{name}: expected at least one point, got none")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name}: contains NaN or infinite values")
    return arr


def _as_origin(value) -> np.ndarray:
    try:
        o = np.asarray(value, dtype=np.float64).reshape(-1)
    except (TypeError, ValueError):
        raise InputError(f"axis_origin: expected 3 numbers, got {value!r}") from None
    if o.shape != (3,) or not np.all(np.isfinite(o)):
        raise InputError(f"axis_origin: expected 3 finite numbers, got {value!r}")
    return o


def _positive(value, name: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected a positive number, got {value!r}") from None
    if not math.isfinite(v) or v <= 0:
        raise InputError(f"{name}: expected a positive number, got {value!r}")
    return v
