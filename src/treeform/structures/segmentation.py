"""Segmentation: per-pixel labels background / foliage / wood, plus a float alpha."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from treeform._shared.errors import InputError
from treeform.structures._npz import load_npz, save_npz

BACKGROUND, FOLIAGE, WOOD = 0, 1, 2


@dataclass
class Segmentation:
    """Labels of a photo: 0 background, 1 foliage, 2 wood; alpha in [0, 1].

    Parameters
    ----------
    labels : ndarray, shape (H, W), uint8
    alpha : ndarray, shape (H, W), float32, optional
        Soft tree coverage; defaults to ``labels > 0``.

    Examples
    --------
    >>> lab = np.zeros((3, 3), np.uint8); lab[1, 1] = 1
    >>> int(Segmentation(lab).tree_mask.sum())
    1
    """

    labels: np.ndarray
    alpha: np.ndarray | None = None

    BACKGROUND = BACKGROUND
    FOLIAGE = FOLIAGE
    WOOD = WOOD

    def __post_init__(self):
        self.labels = np.ascontiguousarray(self.labels, dtype=np.uint8)
        if self.alpha is None:
            self.alpha = (self.labels > 0).astype(np.float32)
        self.alpha = np.ascontiguousarray(self.alpha, dtype=np.float32)
        self.validate()

    @property
    def shape(self) -> tuple[int, int]:
        return self.labels.shape

    @property
    def tree_mask(self) -> np.ndarray:
        """(H, W) bool: foliage or wood."""
        return self.labels > 0

    @property
    def foliage_mask(self) -> np.ndarray:
        return self.labels == FOLIAGE

    @property
    def wood_mask(self) -> np.ndarray:
        return self.labels == WOOD

    def validate(self) -> None:
        if self.labels.ndim != 2 or min(self.labels.shape) < 1:
            raise InputError(f"Segmentation.labels: expected (H, W), got {self.labels.shape}")
        if self.labels.size and self.labels.max() > 2:
            raise InputError("Segmentation.labels: values must be 0, 1 or 2")
        if self.alpha.shape != self.labels.shape:
            raise InputError(f"Segmentation.alpha: shape {self.alpha.shape} != labels {self.labels.shape}")
        if self.alpha.size and (not np.all(np.isfinite(self.alpha)) or self.alpha.min() < 0 or self.alpha.max() > 1):
            raise InputError("Segmentation.alpha: values must lie in [0, 1]")

    def save(self, path):
        return save_npz(path, "Segmentation", labels=self.labels, alpha=self.alpha)

    @classmethod
    def load(cls, path) -> "Segmentation":
        d = load_npz(path, "Segmentation")
        return cls(d["labels"], d["alpha"])
