"""Exemplar processing: RGBA tree image -> normalised image, crown/trunk, Cr and Cs (seed 000 §4).

Steps (one call of :func:`process_exemplar`):

1. **Normalisation** (§4.1): alpha thresholded at 0.5; transparent pixels set to black
   (and alpha 0); crop to the opaque box; pad to a square; resize to ``size`` x ``size``
   (1024 by default). The tree is centred horizontally and stands on the bottom margin,
   so that every exemplar's bottom pin B lies on the same row.
2. **Crown / trunk** (§4.3): the paper fine-tunes DeepLabv3+; here the classical wood
   colour model of :mod:`treeform.segment` labels wood inside the alpha mask, and the
   trunk is the wood connected to the bottom of the tree, plus the narrow stem at the
   bottom of the mask (for bark that is not brown: white birch, black snags).
3. **Contours** (§4.2): border following, overall contour C = longest exterior contour.
4. **Pins** B, L, R (§4.4), **resampling** to N = 2000 points (§4.5) and the
   **simplified contour** Cs of M points (§4.6).
"""

from __future__ import annotations

import hashlib
import os
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from treeform._shared.errors import InputError, NoTreeFoundError
from treeform.contour import (
    DEFAULT_COUNTS,
    crown_baseline,
    longest_exterior_contour,
    pin_points,
    resample_contour,
    simplify_contour,
)
from treeform.contour.normalize import check_rgba, normalize_rgba

__all__ = ["Exemplar", "normalize_rgba", "split_crown_trunk", "process_exemplar", "file_hash",
           "IMAGE_SUFFIXES", "CROWN", "TRUNK"]

CROWN, TRUNK = 1, 2
"""Exemplar labels: 0 background, 1 crown, 2 trunk."""

IMAGE_SUFFIXES = (".png", ".webp", ".tif", ".tiff")
"""Files of a library directory that are read as exemplars (formats with an alpha channel)."""

_FORMAT_VERSION = 1
_SEG_SIDE = 256


# --------------------------------------------------------------------------- reading


def file_hash(path) -> str:
    """SHA-256 hex digest of a file's bytes (the cache key of a processed exemplar)."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


# --------------------------------------------------------------------------- normalisation


# --------------------------------------------------------------------------- crown / trunk


def _components_touching(mask: np.ndarray, seeds: np.ndarray) -> np.ndarray:
    n, lab = cv2.connectedComponents(mask.astype(np.uint8), connectivity=8)
    hit = np.zeros(n, bool)
    hit[np.unique(lab[seeds & mask])] = True
    hit[0] = False
    return hit[lab]


def _narrow_stem(mask: np.ndarray) -> np.ndarray:
    """Rows at the bottom of the tree where it is a narrow stem (< 12 % of its width)."""
    h, w = mask.shape
    counts = mask.sum(1)
    rows = np.nonzero(counts)[0]
    if rows.size == 0:
        return np.zeros_like(mask)
    width = float(counts.max())
    limit = max(0.12 * width, 2.0)
    top = bottom = int(rows.max())
    while top - 1 >= rows.min() and 0 < counts[top - 1] <= limit:
        top -= 1
    if counts[bottom] > limit or bottom - top + 1 < 0.04 * (rows.max() - rows.min() + 1):
        return np.zeros_like(mask)
    stem = np.zeros_like(mask)
    stem[top:bottom + 1] = mask[top:bottom + 1]
    return _components_touching(stem, _bottom_band(mask, 0.01))


def _bottom_band(mask: np.ndarray, frac: float) -> np.ndarray:
    rows = np.nonzero(mask.any(1))[0]
    band = np.zeros_like(mask)
    if rows.size:
        y1 = int(rows.max())
        y0 = y1 - max(1, int(round(frac * (y1 - rows.min() + 1))))
        band[y0:y1 + 1] = True
    return band & mask


def split_crown_trunk(rgba) -> np.ndarray:
    """Crown / trunk labels of a normalised exemplar (seed 000 §4.3).

    The segmentation runs on a copy reduced to 256 px: wood is labelled inside the alpha
    mask by :func:`treeform.segment.mask_to_segmentation` (the project's bark colour
    model); the trunk is the wood connected to the bottom of the tree (its lowest 3 %),
    together with the narrow stem the tree stands on, and everything below the crown
    baseline (the lowest row of the crown after a morphological opening, which drops
    slivers of unlabelled bark along the trunk). The rest of the tree is crown.

    Parameters
    ----------
    rgba : ndarray, shape (S, S, 4), uint8
        Normalised exemplar (:func:`normalize_rgba`).

    Returns
    -------
    ndarray, shape (S, S), uint8
        0 background, 1 crown, 2 trunk.
    """
    from treeform.segment import mask_to_segmentation

    a = check_rgba(rgba)
    h, w = a.shape[:2]
    mask = a[..., 3] >= 128
    if not mask.any():
        raise NoTreeFoundError("rgba: no opaque pixel (alpha >= 0.5)")
    sc = min(1.0, _SEG_SIDE / max(h, w))
    if sc < 1.0:
        small = cv2.resize(a, (max(8, round(w * sc)), max(8, round(h * sc))), interpolation=cv2.INTER_AREA)
    else:
        small = a
    m_s = small[..., 3] >= 128
    labels = np.where(mask, CROWN, 0).astype(np.uint8)
    if not m_s.any():
        return labels
    seg = mask_to_segmentation(m_s, np.ascontiguousarray(small[..., :3]))
    wood = seg.wood_mask
    trunk_s = _components_touching(wood, _bottom_band(m_s, 0.03)) | _narrow_stem(m_s)
    if not trunk_s.any():
        return labels
    trunk = cv2.resize(trunk_s.astype(np.uint8), (w, h), interpolation=cv2.INTER_NEAREST)
    r = max(1, int(round(1 / sc)))  # one reduced pixel: the trunk's edge at full size
    trunk = cv2.dilate(trunk, np.ones((2 * r + 1, 2 * r + 1), np.uint8)).astype(bool) & mask
    # the crown baseline ignores slivers of crown along the trunk's edges (bark pixels
    # the colour model missed): the crown is opened first; whatever lies below the
    # baseline then belongs to the trunk
    crown = mask & ~trunk
    k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (4 * r + 1, 4 * r + 1))
    opened = cv2.morphologyEx(crown.astype(np.uint8), cv2.MORPH_OPEN, k).astype(bool)
    base = crown_baseline(opened if opened.any() else crown, ignore=0.002)
    if base is not None:
        trunk |= mask & (np.arange(h)[:, None] > base)
    labels[trunk] = TRUNK
    return labels


# --------------------------------------------------------------------------- exemplar


@dataclass
class Exemplar:
    """A processed exemplar (seed 000 §4): normalised image, labels and contours.

    Parameters
    ----------
    rgba : ndarray, shape (S, S, 4), uint8
        Normalised image (:func:`normalize_rgba`).
    labels : ndarray, shape (S, S), uint8
        0 background, 1 crown, 2 trunk.
    resampled : ndarray, shape (N, 2), float64
        Cr: ``(x, y)`` pixels, ``Cr[0]`` = B, ``Cr[counts[0]]`` = R,
        ``Cr[counts[0] + counts[1]]`` = L.
    simplified : ndarray, shape (M, 2), float64
        Cs, for mean value coordinates.
    counts : tuple of 3 int
        Points of Cr on B -> R, R -> L, L -> B.
    baseline : float
        Row of the crown baseline (NaN when the tree has no trunk).
    name : str
        Source file name (or "").
    key : str
        Cache key (hash of the source file and of the processing options).
    dilate : int
        Dilation iterations used for Cs.
    """

    rgba: np.ndarray
    labels: np.ndarray
    resampled: np.ndarray
    simplified: np.ndarray
    counts: tuple = DEFAULT_COUNTS
    baseline: float = float("nan")
    name: str = ""
    key: str = ""
    dilate: int = 8
    _prem: np.ndarray | None = field(default=None, repr=False, compare=False)
    _cs: dict = field(default_factory=dict, repr=False, compare=False)
    _form: str | None = field(default=None, repr=False, compare=False)

    @property
    def size(self) -> int:
        return int(self.rgba.shape[0])

    @property
    def has_trunk(self) -> bool:
        c0, c1, _ = self.counts
        cr = self.resampled
        return not (np.allclose(cr[c0], cr[0]) and np.allclose(cr[c0 + c1], cr[0]))

    @property
    def pins(self) -> np.ndarray:
        """(3, 2) positions of B, L, R."""
        c0, c1, _ = self.counts
        return self.resampled[[0, c0 + c1, c0]]

    @property
    def form(self) -> str:
        """Growth form read from the silhouette, 'broadleaf', 'conifer' or 'palm'
        (:func:`~treeform.contour.form.classify_form`; computed once)."""
        if self._form is None:
            from treeform.contour.form import classify_form

            self._form = classify_form(self.rgba)
        return self._form

    @property
    def vector(self) -> np.ndarray:
        """u: the (2N,) flattened, mean-subtracted coordinates of Cr (seed 000 §3)."""
        return (self.resampled - self.resampled.mean(0)).ravel()

    @property
    def premultiplied(self) -> np.ndarray:
        """(S, S, 4) float32 premultiplied RGBA in [0, 1] (computed once)."""
        if self._prem is None:
            f = self.rgba.astype(np.float32) / 255.0
            f[..., :3] *= f[..., 3:4]
            self._prem = f
        return self._prem

    def simplified_contour(self, m: int) -> np.ndarray:
        """Cs with ``m`` points (the stored one when ``m`` matches)."""
        if m == len(self.simplified):
            return self.simplified
        if m not in self._cs:
            self._cs[m] = simplify_contour(self.resampled, self.rgba.shape[:2], m=m, dilate=self.dilate,
                                           counts=self.counts)
        return self._cs[m]

    def save(self, path) -> Path:
        """Write an npz (atomic: temporary file, then rename)."""
        path = Path(path)
        tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp.npz")
        try:
            np.savez_compressed(tmp, __kind__=np.array("VariationsExemplar"), version=np.array(_FORMAT_VERSION),
                                rgba=self.rgba, labels=self.labels, resampled=self.resampled,
                                simplified=self.simplified, counts=np.array(self.counts),
                                baseline=np.array(self.baseline), name=np.array(self.name),
                                key=np.array(self.key), dilate=np.array(self.dilate))
            os.replace(tmp, path)
        finally:
            if tmp.exists():
                tmp.unlink()
        return path

    @classmethod
    def load(cls, path) -> "Exemplar":
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as z:
                d = {k: z[k] for k in z.files}
        except FileNotFoundError:
            raise InputError(f"{path}: no such file") from None
        except Exception as exc:
            raise InputError(f"{path}: not a processed exemplar file ({type(exc).__name__})") from None
        if str(d.get("__kind__", "")) != "VariationsExemplar" or int(d.get("version", -1)) != _FORMAT_VERSION:
            raise InputError(f"{path}: not a processed exemplar file of this treeform version")
        return cls(d["rgba"], d["labels"], d["resampled"], d["simplified"], tuple(int(c) for c in d["counts"]),
                   float(d["baseline"]), str(d["name"]), str(d["key"]), int(d["dilate"]))


def process_exemplar(rgba, *, size: int = 1024, counts=DEFAULT_COUNTS, m: int = 20, dilate: int = 8,
                     margin: int | None = None, name: str = "", key: str = "") -> Exemplar:
    """Process one RGBA tree image into an :class:`Exemplar` (seed 000 §4.1–4.6).

    Parameters
    ----------
    rgba : ndarray, shape (H, W, 4), uint8
        Tree on a transparent background.
    size : int
        Side of the normalised image (paper: 1024).
    counts : tuple of 3 int
        Points of Cr on the right trunk, crown and left trunk segments (paper: 200, 1600,
        200; N = 2000).
    m : int
        Points of the simplified contour Cs (paper: M = 20).
    dilate : int
        Dilation iterations before Cs is extracted (paper: 8 at 1024 px).
    margin : int, optional
        Transparent border of the normalised image (default ``size // 64``).
    name, key : str
        Stored with the exemplar (file name, cache key).

    Returns
    -------
    Exemplar

    Raises
    ------
    InputError
        ``rgba`` is not an (H, W, 4) uint8 array, or an option is out of range.
    NoTreeFoundError
        No pixel has alpha >= 0.5.
    """
    img = normalize_rgba(rgba, size=size, margin=margin)
    labels = split_crown_trunk(img)
    contour = longest_exterior_contour(labels > 0)
    trunk = labels == TRUNK
    base = crown_baseline(labels == CROWN) if trunk.any() else None
    pins = pin_points(contour, baseline=base)
    cr = resample_contour(contour, pins, counts=counts)
    cs = simplify_contour(cr, img.shape[:2], m=m, dilate=dilate, counts=counts)
    return Exemplar(img, labels, cr, cs, tuple(int(c) for c in counts),
                    float("nan") if base is None or not pins.has_trunk else float(base), name, key, int(dilate))
