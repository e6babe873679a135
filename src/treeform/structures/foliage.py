"""Foliage: leaf (or leaf-cluster) instances as arrays."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from treeform._shared.errors import InputError
from treeform.structures._npz import load_npz, save_npz


@dataclass
class Foliage:
    """Leaf instances, each a square card.

    Parameters
    ----------
    positions : ndarray, shape (M, 3)
        Card centres in metres.
    normals : ndarray, shape (M, 3)
        Unit card normals.
    up : ndarray, shape (M, 3)
        Unit in-plane "up" vector of each card (orthogonal to its normal).
    size : ndarray, shape (M,)
        Card edge length in metres.
    color : ndarray, shape (M, 3), float32 in [0, 1]
        Linear-ish RGB tint of each card (multiplies the leaf texture).
    node : ndarray, shape (M,), int64
        Skeleton node the leaf hangs on (-1 if none).
    uv : ndarray, shape (M, 4), float32, optional
        Each card's rectangle ``(u0, v0, u1, v1)`` in its texture (glTF: v = 0 at the top),
        for cards that share a texture atlas; None: every card spans the whole texture.
    """

    positions: np.ndarray
    normals: np.ndarray
    up: np.ndarray
    size: np.ndarray
    color: np.ndarray
    node: np.ndarray | None = None
    uv: np.ndarray | None = None

    def __post_init__(self):
        self.positions = np.ascontiguousarray(self.positions, np.float64).reshape(-1, 3)
        m = len(self.positions)
        self.normals = np.ascontiguousarray(self.normals, np.float64).reshape(-1, 3)
        self.up = np.ascontiguousarray(self.up, np.float64).reshape(-1, 3)
        self.size = np.ascontiguousarray(self.size, np.float64).reshape(-1)
        self.color = np.ascontiguousarray(self.color, np.float32).reshape(-1, 3)
        self.node = np.full(m, -1, np.int64) if self.node is None else np.ascontiguousarray(self.node, np.int64).reshape(-1)
        if self.uv is not None:
            self.uv = np.ascontiguousarray(self.uv, np.float32).reshape(-1, 4)
        self.validate()

    def __len__(self) -> int:
        return len(self.positions)

    @classmethod
    def empty(cls) -> "Foliage":
        z = np.zeros((0, 3))
        return cls(z, z, z, np.zeros(0), z)

    def subset(self, index) -> "Foliage":
        """The leaves selected by ``index`` (a boolean mask or integer indices), in that order.

        Examples
        --------
        >>> f = Foliage(np.zeros((3, 3)), [[0, 0, 1.]] * 3, [[0, 1, 0.]] * 3, [0.1, 0.2, 0.3], np.zeros((3, 3)))
        >>> f.subset([2, 0]).size.tolist()
        [0.3, 0.1]
        """
        i = np.asarray(index)
        return Foliage(self.positions[i], self.normals[i], self.up[i], self.size[i], self.color[i], self.node[i],
                       None if self.uv is None else self.uv[i])

    def with_colors(self, color, uv=None) -> "Foliage":
        """The same cards with new tints (and, if given, new texture rectangles)."""
        return Foliage(self.positions, self.normals, self.up, self.size, color, self.node,
                       self.uv if uv is None else uv)

    def validate(self) -> None:
        m = len(self.positions)
        names = ("normals", "up", "size", "color", "node") + (("uv",) if self.uv is not None else ())
        for name in names:
            if len(getattr(self, name)) != m:
                raise InputError(f"Foliage.{name}: length {len(getattr(self, name))} != {m} leaves")
        if m and (np.any(self.size <= 0) or not np.all(np.isfinite(self.positions))):
            raise InputError("Foliage: sizes must be positive and positions finite")
        if m and (self.color.min() < 0 or self.color.max() > 1):
            raise InputError("Foliage.color: values must lie in [0, 1]")
        if m and self.uv is not None and (not np.all(np.isfinite(self.uv)) or self.uv.min() < 0 or self.uv.max() > 1):
            raise InputError("Foliage.uv: texture rectangles must lie in [0, 1]")

    def save(self, path):
        extra = {} if self.uv is None else {"uv": self.uv}
        return save_npz(path, "Foliage", positions=self.positions, normals=self.normals, up=self.up,
                        size=self.size, color=self.color, node=self.node, **extra)

    @classmethod
    def load(cls, path) -> "Foliage":
        return cls(**load_npz(path, "Foliage"))
