"""A photo collection for structure from motion: upright, resized, with a focal-length prior (seed 002 §3).

:func:`load_photos` reads every photo of a folder (or a list of files) as a :class:`PhotoView`:
the pixels EXIF-oriented and reduced to ``max_size`` (through :func:`treeform.io.images.read_photo`),
and the focal length in pixels when the EXIF block allows it, which COLMAP takes as a prior
(``has_prior_focal_length``) instead of guessing 1.2 x the long side.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from treeform._shared.errors import InputError
from treeform.io.images import PHOTO_SUFFIXES

__all__ = ["PhotoView", "load_photos", "exif_focal_px", "PHOTO_SUFFIXES", "MIN_PHOTOS"]

MIN_PHOTOS = 3
"""Fewest photos a multi-view reconstruction accepts."""

DIAGONAL_35MM = math.hypot(36.0, 24.0)
"""Diagonal of the 36 x 24 mm frame (43.27 mm) that a 35 mm-equivalent focal length refers to."""

# EXIF tags (CIPA DC-008)
_EXIF_IFD = 0x8769
_FOCAL_LENGTH = 0x920A
_FOCAL_35MM = 0xA405
_FOCAL_PLANE_X_RES = 0xA20E
_FOCAL_PLANE_Y_RES = 0xA20F
_FOCAL_PLANE_UNIT = 0xA210
_UNIT_MM = {2: 25.4, 3: 10.0, 4: 1.0, 5: 0.001}  # inch, cm, mm, micrometre (1 = "no unit": unusable)

# a focal prior outside this range of the long side (field of view ~ 150° .. 6°) is an EXIF error
_FOCAL_RANGE = (0.3, 10.0)


@dataclass
class PhotoView:
    """One photo of a multi-view collection as the SfM sees it.

    Attributes
    ----------
    name : str
        File name in the input folder (unique within a collection).
    image : ndarray, shape (H, W, 3), uint8
        RGB pixels, upright (EXIF orientation applied), long side <= ``max_size``.
    focal_px : float or None
        Focal-length prior in pixels of ``image``; None when the EXIF block gives none.
    focal_source : str
        ``"exif_35mm"`` (FocalLengthIn35mmFilm), ``"exif_focal_plane"`` (FocalLength and
        FocalPlaneXResolution), ``"given"`` (set by the caller) or ``"none"``.
    source : str
        The path the photo was read from ("" for in-memory views).
    original_size : tuple of int
        (width, height) of the upright photo before resizing.
    """

    name: str
    image: np.ndarray
    focal_px: float | None = None
    focal_source: str = "none"
    source: str = ""
    original_size: tuple = (0, 0)

    def __post_init__(self):
        im = self.image
        if not isinstance(im, np.ndarray) or im.ndim != 3 or im.shape[2] != 3 or im.dtype != np.uint8:
            raise InputError(f"PhotoView.image: expected (H, W, 3) uint8, got {getattr(im, 'shape', None)} "
                             f"{getattr(im, 'dtype', None)}")
        if min(im.shape[:2]) < 16:
            raise InputError(f"PhotoView.image: {self.name}: image too small ({im.shape[1]}\u00d7{im.shape[0]})")
        if self.focal_px is not None:
            f = float(self.focal_px)
            if not (np.isfinite(f) and f > 0):
                raise InputError(f"PhotoView.focal_px: expected a positive number or None, got {self.focal_px!r}")
            self.focal_px = f
        if not self.original_size or min(self.original_size) <= 0:
            self.original_size = (int(im.shape[1]), int(im.shape[0]))

    @property
    def size(self) -> tuple[int, int]:
        """(width, height) of ``image``."""
        return int(self.image.shape[1]), int(self.image.shape[0])

    @property
    def scale(self) -> float:
        """Pixels of ``image`` per pixel of the original photo (<= 1)."""
        return max(self.size) / max(self.original_size)

    @property
    def photo(self):
        """The view as a :class:`~treeform.structures.Photo`."""
        from treeform.structures.photo import Photo

        return Photo(self.image, self.source, float(self.scale))


def _ratio(v) -> float | None:
    """An EXIF rational / int (or a 1-tuple of them) as a float; None when missing or invalid."""
    if isinstance(v, (tuple, list)):
        if len(v) == 2 and all(isinstance(x, (int, np.integer)) for x in v):  # (num, den)
            return float(v[0]) / float(v[1]) if v[1] else None
        v = v[0] if v else None
    try:
        f = float(v)
    except (TypeError, ValueError, ZeroDivisionError):
        return None
    return f if math.isfinite(f) and f > 0 else None


def exif_focal_px(exif, size, original_size=None) -> tuple[float | None, str]:
    """The focal length in pixels an EXIF block implies for an upright image of ``size``.

    Preference order:

    1. ``FocalLengthIn35mmFilm`` (f35). The 35 mm equivalent is defined by the diagonal field of
       view of the 36 x 24 mm frame (it is how a crop factor is quoted: a Four Thirds camera
       writes twice its focal length), so ``f_px = f35 * diag_px / 43.27``; for a 3:2 photo
       this equals ``f35 * long_side_px / 36``.
    2. ``FocalLength`` in mm with the sensor's pixel density ``FocalPlaneXResolution`` /
       ``FocalPlaneResolutionUnit`` (a known sensor width): ``f_px = f_mm * px_per_mm * scale``.
    3. Nothing: ``(None, "none")``.

    A prior whose field of view is implausible (focal outside 0.3 .. 10 x the long side) is
    dropped (broken EXIF blocks exist).

    Parameters
    ----------
    exif : PIL.Image.Exif or mapping
        The photo's EXIF tags (the Exif sub-IFD is read when present).
    size : tuple of int
        (width, height) of the (resized, upright) image the focal refers to.
    original_size : tuple of int, optional
        (width, height) of the upright original; defaults to ``size``.

    Returns
    -------
    focal_px : float or None
    source : str
        ``"exif_35mm"``, ``"exif_focal_plane"`` or ``"none"``.

    Examples
    --------
    >>> exif_focal_px({0xA405: 36}, (1500, 1000))
    (1500.0, 'exif_35mm')
    >>> exif_focal_px({}, (1500, 1000))
    (None, 'none')
    """
    w, h = (float(v) for v in size)
    ow, oh = (float(v) for v in (original_size or size))
    long_side = max(w, h)
    tags = {}
    try:
        tags.update({k: v for k, v in dict(exif).items()})
        if hasattr(exif, "get_ifd"):
            tags.update(dict(exif.get_ifd(_EXIF_IFD)))
    except Exception:  # a malformed EXIF block: no prior
        return None, "none"

    def plausible(f):
        return f is not None and _FOCAL_RANGE[0] * long_side <= f <= _FOCAL_RANGE[1] * long_side

    f35 = _ratio(tags.get(_FOCAL_35MM))
    if f35 is not None:
        f = f35 * math.hypot(w, h) / DIAGONAL_35MM
        if plausible(f):
            return float(f), "exif_35mm"
    f_mm = _ratio(tags.get(_FOCAL_LENGTH))
    res = _ratio(tags.get(_FOCAL_PLANE_X_RES))
    unit = _UNIT_MM.get(int(_ratio(tags.get(_FOCAL_PLANE_UNIT)) or 2))  # EXIF default unit: inch
    if f_mm is not None and res is not None and unit is not None:
        f = f_mm * res / unit * (long_side / max(ow, oh))
        if plausible(f):
            return float(f), "exif_focal_plane"
    return None, "none"


def _list_photos(folder_or_paths) -> list[Path]:
    if isinstance(folder_or_paths, (str, Path)):
        p = Path(folder_or_paths)
        if not p.exists():
            raise InputError(f"{p}: no such folder")
        if p.is_dir():
            return sorted((f for f in p.iterdir() if f.is_file() and not f.name.startswith(".")
                           and f.suffix.lower() in PHOTO_SUFFIXES), key=lambda f: f.name)
        return [p]
    try:
        return [Path(f) for f in folder_or_paths]
    except TypeError:
        raise InputError(f"folder_or_paths: expected a folder or a list of image files, got {folder_or_paths!r}") \
            from None


def load_photos(folder_or_paths, *, max_size: int = 1024) -> list[PhotoView]:
    """Read a photo collection for structure from motion (seed 002 §3, capture).

    Parameters
    ----------
    folder_or_paths : str, path-like, or sequence of them
        A folder (every photo of :data:`treeform.io.images.PHOTO_SUFFIXES` in it, any case:
        JPEG, PNG, WebP, TIFF, BMP, HEIC, AVIF; hidden files skipped, sorted by name) or a list
        of image files (kept in the given order).
    max_size : int, keyword-only
        Longest side of each returned image in pixels (never upscaled).

    Returns
    -------
    list of PhotoView
        Upright (EXIF orientation applied) RGB images, long side <= ``max_size``, with the
        EXIF focal-length prior (see :func:`exif_focal_px`). Sizes may differ between photos.

    Raises
    ------
    InputError
        A missing folder; an unreadable file (the message names it); two files with the same
        name; fewer than :data:`MIN_PHOTOS` photos ("...: need at least 3 photos of the tree,
        found N").
    """
    from treeform.io.images import _open_image, read_photo

    paths = _list_photos(folder_or_paths)
    where = str(folder_or_paths) if isinstance(folder_or_paths, (str, Path)) else "photos"
    if len(paths) < MIN_PHOTOS:
        raise InputError(f"{where}: need at least {MIN_PHOTOS} photos of the tree, found {len(paths)}")
    seen: dict[str, Path] = {}
    for p in paths:
        if p.name in seen:
            raise InputError(f"{p}: the same file name as {seen[p.name]}; photo names must be unique")
        seen[p.name] = p
    views = []
    for p in paths:
        photo = read_photo(p, max_size=max_size)  # InputError naming the file when unreadable
        im = _open_image(p)
        try:
            w0, h0 = im.size
            try:
                exif = im.getexif()
                orientation = int(exif.get(0x0112, 1) or 1)
            except Exception:  # malformed EXIF: no prior, pixels as read_photo left them
                exif, orientation = {}, 1
        finally:
            im.close()
        if orientation in (5, 6, 7, 8):  # a quarter turn: the upright photo is h0 x w0
            w0, h0 = h0, w0
        size = (photo.width, photo.height)
        focal, source = exif_focal_px(exif, size, (w0, h0))
        views.append(PhotoView(p.name, photo.image, focal, source, str(p), (int(w0), int(h0))))
    return views
