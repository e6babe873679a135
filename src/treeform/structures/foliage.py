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
    """

    positions: np.ndarray
    normals: np.ndarray
    up: np.ndarray
    size: np.ndarray
    color: np.ndarray
    node: np.ndarray | None = None

    def __post_init__(self):
        self.positions = np.ascontiguousarray(self.positions, np.float64).reshape(-1, 3)
        m = len(self.positions)
        self.normals = np.ascontiguousarray(self.normals, np.float64).reshape(-1, 3)
        self.up = np.ascontiguousarray(self.up, np.float64).reshape(-1, 3)
        self.size = np.ascontiguousarray(self.size, np.float64).reshape(-1)
        self.color = np.ascontiguousarray(self.color, np.float32).reshape(-1, 3)
        self.node = np.full(m, -1, np.int64) if self.node is None else np.ascontiguousarray(self.node, np.int64).reshape(-1)
        self.validate()

    def __len__(self) -> int:
        return len(self.positions)

    @classmethod
    def empty(cls) -> "Foliage":
        z = np.zeros((0, 3))
        return cls(z, z, z, np.zeros(0), z)

    def validate(self) -> None:
        m = len(self.positions)
        for name in ("normals", "up", "size", "color", "node"):
            if len(getattr(self, name)) != m:
                raise InputError(f"Foliage.{name}: length {len(getattr(self, name))} != {m} leaves")
        if m and (np.any(self.size <= 0) or not np.all(np.isfinite(self.positions))):
            raise InputError("Foliage: sizes must be positive and positions finite")
        if m and (self.color.min() < 0 or self.color.max() > 1):
            raise InputError("Foliage.color: values must lie in [0, 1]")

    def save(self, path):
        return save_npz(path, "Foliage", positions=self.positions, normals=self.normals, up=self.up,
                        size=self.size, color=self.color, node=self.node)

    @classmethod
    def load(cls, path) -> "Foliage":
        return cls(**load_npz(path, "Foliage"))
