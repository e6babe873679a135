"""Photo: an EXIF-oriented RGB image with its provenance."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from treeform._shared.errors import InputError
from treeform.structures._npz import load_npz, save_npz


@dataclass
class Photo:
    """An RGB photograph, already rotated upright by its EXIF orientation.

    Parameters
    ----------
    image : ndarray, shape (H, W, 3), uint8
        RGB pixels, row 0 at the top.
    source : str
        Where it was read from ("" for in-memory images).
    scale : float
        Pixels of ``image`` per pixel of the original file (< 1 when downscaled).

    Examples
    --------
    >>> p = Photo(np.zeros((4, 5, 3), np.uint8))
    >>> p.shape
    (4, 5)
    """

    image: np.ndarray
    source: str = ""
    scale: float = 1.0

    def __post_init__(self):
        self.validate()

    @property
    def shape(self) -> tuple[int, int]:
        return self.image.shape[:2]

    @property
    def height(self) -> int:
        return self.image.shape[0]

    @property
    def width(self) -> int:
        return self.image.shape[1]

    def validate(self) -> None:
        im = self.image
        if not isinstance(im, np.ndarray) or im.ndim != 3 or im.shape[2] != 3 or im.dtype != np.uint8:
            raise InputError(f"Photo.image: expected (H, W, 3) uint8, got {getattr(im, 'shape', None)} {getattr(im, 'dtype', None)}")
        if min(im.shape[:2]) < 1:
            raise InputError("Photo.image: empty image")
        if not (self.scale > 0):
            raise InputError(f"Photo.scale: expected > 0, got {self.scale}")

    def save(self, path):
        return save_npz(path, "Photo", image=self.image, source=np.array(self.source), scale=np.array(self.scale))

    @classmethod
    def load(cls, path) -> "Photo":
        d = load_npz(path, "Photo")
        return cls(d["image"], str(d["source"]), float(d["scale"]))
