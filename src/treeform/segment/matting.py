"""Trimaps from a segmentation and alpha matting: photo -> RGBA billboard (seed 000 §4.3, Fig. 4).

The paper derives the trimap from its DeepLabv3+ segmentation: the unknown (grey) band is
a dilation of the segmentation, the foreground (white) the eroded trunk plus random points
sampled inside the eroded crown, the rest background; then it runs a matting network. Here
the segmentation is :func:`treeform.segment.segment_tree` and the matting is closed-form
matting (Levin, Lischinski & Weiss 2008) from PyMatting, with PyMatting's multilevel
foreground estimation (Germer et al. 2021) so that edge pixels carry the tree's colour, not
the sky's.

PyMatting is imported only inside :func:`alpha_matting` and :func:`estimate_foreground`.
Its import compiles its numba kernels (eager signatures, ``cache=True``) unless numba's
on-disk cache holds them: about 50 s once per installation (or per ``NUMBA_CACHE_DIR``),
then about 0.5 s. :func:`kernels_to_compile` tells beforehand whether that will happen, and
the import logs an INFO notice on the ``treeform.segment.matting`` logger when it will
(the command line shows it; a library caller sees it only with logging configured).
"""

from __future__ import annotations

import contextlib
import io
import logging
import os
import sys
import threading

import cv2
import numpy as np

from treeform._shared.errors import InputError
from treeform._shared.jit import cold_kernels
from treeform._shared.rng import as_rng
from treeform.structures.segmentation import Segmentation

__all__ = ["make_trimap", "alpha_matting", "estimate_foreground", "matte_tree", "sky_gaps", "background_gaps", "blue_sky",
           "kernels_to_compile"]

UNKNOWN = 0.5

log = logging.getLogger(__name__)

_QUIET_LOCK = threading.Lock()
_QUIET = {"depth": 0, "saved": None}


@contextlib.contextmanager
def _quiet_stdout():
    """Standard output swallowed while any thread is inside (PyMatting prints its warnings).

    ``contextlib.redirect_stdout`` is not safe across threads: two overlapping redirects restore
    each other's buffers and the process's output is lost for good. Here the first thread in
    swaps ``sys.stdout`` for a sink and the last one out puts the original back.
    """
    with _QUIET_LOCK:
        if _QUIET["depth"] == 0:
            _QUIET["saved"] = sys.stdout
            sys.stdout = io.StringIO()
        _QUIET["depth"] += 1
    try:
        yield
    finally:
        with _QUIET_LOCK:
            _QUIET["depth"] -= 1
            if _QUIET["depth"] == 0:
                sys.stdout = _QUIET["saved"]
                _QUIET["saved"] = None

COMPILE_SECONDS = 50
"""Rough time numba takes to compile all of PyMatting's kernels (measured: 47 s on 2 cores)."""


def _marker_path():
    """``$XDG_CACHE_HOME/treeform/`` (default ``~/.cache/treeform/``) marker of a finished warm-up."""
    from importlib.metadata import version
    from pathlib import Path

    home = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    tag = f"pymatting-{version('pymatting')}-numba-{version('numba')}-py{sys.version_info[0]}{sys.version_info[1]}"
    return Path(home) / "treeform" / f"matting-kernels-{tag}.ok"


def kernels_to_compile() -> tuple[int, int]:
    """How many of PyMatting's numba kernels importing it will compile now: ``(to compile, all)``.

    ``(0, n)`` once numba's on-disk cache holds them all (or PyMatting is already imported).
    Should numba's cache layout be unreadable to this check, it falls back to a marker file
    that :func:`alpha_matting` writes after the first import (``(1, 1)`` until then).
    """
    if "pymatting" in sys.modules:
        return 0, 0
    try:
        from importlib.util import find_spec

        return cold_kernels(os.path.dirname(find_spec("pymatting").origin))
    except Exception:  # numba or PyMatting internals changed: fall back to our own marker
        try:
            return (0, 1) if _marker_path().exists() else (1, 1)
        except Exception:
            return 0, 0


_IMPORT_LOCK = threading.Lock()


def _import_pymatting():
    """Import PyMatting, first logging a notice when numba is about to compile its kernels.

    One thread at a time: views are matted on threads, and a second thread that found the
    module in ``sys.modules`` while the first was still importing it (or both importing numba
    at once) failed ("module 'numba' has no attribute 'core'", seen once in the multi-view route).
    """
    with _IMPORT_LOCK:
        return _import_pymatting_locked()


def _import_pymatting_locked():
    if "pymatting" in sys.modules:
        return sys.modules["pymatting"]
    cold, total = kernels_to_compile()
    if cold:
        est = max(5, 5 * round(COMPILE_SECONDS * cold / total / 5))
        what = "the matting kernels" if cold == total else f"{cold} of {total} matting kernels"
        log.info("first run: compiling %s with numba, once (~%d s); later runs load them from the cache", what, est)
    import pymatting

    try:  # the fallback marker of kernels_to_compile; an unwritable cache folder is no error
        marker = _marker_path()
        if not marker.exists():
            marker.parent.mkdir(parents=True, exist_ok=True)
            marker.touch()
    except Exception:
        pass
    return pymatting


def _disc(r: int) -> np.ndarray:
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))


def _check_image(image) -> np.ndarray:
    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
        raise InputError(f"image: expected an (H, W, 3) uint8 RGB array, got {img.shape} {img.dtype}")
    if min(img.shape[:2]) < 8:
        raise InputError(f"image: expected at least 8 x 8 pixels, got {img.shape[1]} x {img.shape[0]}")
    return img


def _check_seg(segmentation, shape) -> Segmentation:
    if not isinstance(segmentation, Segmentation):
        raise InputError(f"segmentation: expected a Segmentation, got {type(segmentation).__name__}")
    if segmentation.shape != tuple(shape):
        raise InputError(f"segmentation: size {segmentation.shape[::-1]} does not match the image's {tuple(shape)[::-1]}")
    if not segmentation.tree_mask.any():
        raise InputError("segmentation: the tree mask is empty")
    return segmentation


def blue_sky(image: np.ndarray, *, min_share: float = 0.1) -> np.ndarray:
    """(H, W) bool: clearly blue, bright pixels, when the photo has a blue sky at all.

    A pixel is sky-blue when its Lab b* is below -15 (OpenCV's 8-bit scale, 128 = neutral)
    and its lightness above 50 / 255 (a deep blue sky is dark): bluer than any foliage, bark or blue-green conifer
    needles. The photo has a blue sky when such pixels make up ``min_share`` of its top
    fifth; otherwise nothing is returned (a blue car or house front alone is not sky).

    >>> img = np.zeros((20, 20, 3), np.uint8); img[:] = (40, 110, 40); img[:5] = (90, 150, 230)
    >>> int(blue_sky(img).sum())
    100
    """
    lab = cv2.cvtColor(np.asarray(image), cv2.COLOR_RGB2Lab)
    blue = (lab[..., 2].astype(np.int16) - 128 < -15) & (lab[..., 0] > 50)
    top = blue[: max(1, blue.shape[0] // 5)]
    return blue if top.mean() >= min_share else np.zeros_like(blue)


def _colour_ratio(lab: np.ndarray, background: np.ndarray, tree: np.ndarray) -> np.ndarray:
    """(H, W) how much more often each pixel's colour occurs in ``background`` than in ``tree``.

    Colours are Lab bins (8 x 16 x 16 of OpenCV's 8-bit Lab), each histogram normalised with
    half a count added to every bin, so a colour neither region holds has ratio 1.
    """
    q = ((lab[..., 0].astype(np.int32) >> 5) * 16 + (lab[..., 1].astype(np.int32) >> 4)) * 16 \
        + (lab[..., 2].astype(np.int32) >> 4)
    nb = 8 * 16 * 16
    hb = (np.bincount(q[background], minlength=nb) + 0.5) / (background.sum() + 0.5 * nb)
    hf = (np.bincount(q[tree], minlength=nb) + 0.5) / (tree.sum() + 0.5 * nb)
    return (hb / hf)[q]


def background_gaps(image, tree, *, wood=None, ground=None, ratio: float = 6.0, ring: float = 0.08,
                    crown: float = 0.8) -> np.ndarray:
    """Pixels of a tree mask coloured like the background around the tree: gaps it filled in.

    A segmenter that sees the photo at a few hundred pixels fills the small gaps of a crown,
    whatever shows through them: blue or overcast sky, a wall, a blurred hedge. What shows
    through a gap is what lies around the tree, so the colours that are frequent in a ring
    round the tree and rare inside it mark the gaps, with no assumption on their hue. A gap
    pixel lies inside ``tree`` (not on ``wood``), in the upper ``crown`` share of the tree's
    rows (a pale trunk below the crown can match an overcast sky), and its colour bin (Lab, 8
    x 16 x 16) is ``ratio`` times more frequent in the ring than in the tree. The ring runs
    from 1 % to ``ring`` of the photo's long side outside the tree, above the ground line
    when ``ground`` is given (lawn and road are not seen through a crown); the tree's colours
    are counted at least 1 % inside its edge.

    Parameters
    ----------
    image : ndarray, shape (H, W, 3), uint8
    tree : ndarray, shape (H, W), bool
    wood : ndarray, shape (H, W), bool, optional
        Pixels never taken as gaps.
    ground : ndarray, shape (W,), int, optional
        First ground row of each column (:func:`~treeform.segment.classical.ground_line`).
    ratio, ring, crown : float

    Returns
    -------
    ndarray, shape (H, W), bool

    Examples
    --------
    A green crown over a grey wall; through two holes the network filled, the wall shows:

    >>> img = np.full((100, 100, 3), 128, np.uint8); img[20:80, 20:80] = (40, 120, 40)
    >>> img[40:46, 40:46] = 128; img[60:64, 30:34] = 128
    >>> tree = np.zeros((100, 100), bool); tree[20:80, 20:80] = True
    >>> int(background_gaps(img, tree).sum())
    52
    """
    img = _check_image(image)
    tree = np.asarray(tree, bool)
    if tree.shape != img.shape[:2]:
        raise InputError(f"tree: expected shape {img.shape[:2]}, got {tree.shape}")
    for name, v in (("ratio", ratio), ("ring", ring), ("crown", crown)):
        if not np.isfinite(v) or v <= 0:
            raise InputError(f"{name}: expected a positive number, got {v!r}")
    h, w = tree.shape
    if not tree.any():
        return np.zeros_like(tree)
    r1 = max(1.0, 0.01 * max(h, w))
    r2 = max(r1 + 2.0, ring * max(h, w))
    t8 = tree.astype(np.uint8)
    outside = cv2.distanceTransform(1 - t8, cv2.DIST_L2, 3)
    inside = cv2.distanceTransform(t8, cv2.DIST_L2, 3)
    around = (outside > r1) & (outside <= r2)
    if ground is not None:
        g = np.asarray(ground).reshape(-1)
        if g.shape != (w,):
            raise InputError(f"ground: expected {w} rows (one per column), got shape {g.shape}")
        around &= np.arange(h)[:, None] < g[None, :]
    keep = tree if wood is None else tree & ~np.asarray(wood, bool)
    inner = (inside > r1) & keep
    if around.sum() < 50 or inner.sum() < 50:
        return np.zeros_like(tree)
    rows = np.flatnonzero(tree.any(1))
    upper = np.arange(h)[:, None] < rows[0] + crown * (rows[-1] - rows[0] + 1)
    lab = cv2.cvtColor(img, cv2.COLOR_RGB2Lab)
    return (_colour_ratio(lab, around, inner) > ratio) & keep & upper


def sky_gaps(image, segmentation, *, ratio: float = 10.0) -> np.ndarray:
    """Tree pixels that show the sky through gaps in the foliage.

    A gap pixel is inside the segmented tree, not wood, and either clearly blue and
    bright (when the sky around the crown is blue), or coloured like the background
    above the tree: its colour bin (Lab, 8 x 16 x 16) is ``ratio`` times more frequent
    in that background than in the tree, and it is bright.

    Parameters
    ----------
    image : ndarray, shape (H, W, 3), uint8
    segmentation : Segmentation
    ratio : float

    Returns
    -------
    ndarray, shape (H, W), bool
    """
    img = _check_image(image)
    seg = _check_seg(segmentation, img.shape[:2])
    tree = seg.tree_mask
    h, w = tree.shape
    lab = cv2.cvtColor(img, cv2.COLOR_RGB2Lab)
    L = lab[..., 0].astype(np.int32)
    b = lab[..., 2].astype(np.int32) - 128
    r = max(1, int(round(0.01 * max(h, w))))
    inner = cv2.erode(tree.astype(np.uint8), _disc(r)).astype(bool) & ~seg.wood_mask
    bg = cv2.erode((~tree).astype(np.uint8), _disc(r)).astype(bool)
    rows = np.nonzero(tree.any(1))[0]
    bg &= np.arange(h)[:, None] < (rows.min() + 0.6 * (rows.max() - rows.min() + 1))  # sky, not ground
    if bg.sum() < 50 or inner.sum() < 50:
        return np.zeros_like(tree)
    gap = (_colour_ratio(lab, bg, inner) > ratio) & (L > 120)
    if np.median(b[bg]) < -4:  # a blue sky: its gaps are blue
        gap |= (b < -6) & (L > 90)
    return gap & tree & ~seg.wood_mask


def make_trimap(image, segmentation, *, band: int | None = None, erode: int | None = None,
                point_spacing: float = 1.0, gaps: bool = True, seed=None) -> np.ndarray:
    """A trimap from an automatic segmentation (seed 000 §4.3, Fig. 4).

    * unknown (0.5): the segmentation dilated by ``band`` pixels (the tree and a band
      around it);
    * foreground (1): the trunk (wood) eroded by ``erode`` pixels, plus random points
      sampled inside the crown eroded by ``band`` pixels where the segmentation is
      confident (soft alpha >= 0.9) and away from sky gaps, about one per
      ``point_spacing``^2 pixels. The paper samples sparse points; on our photos sparse
      points left a faint haze of partial alpha over the background around the crown,
      so the default (1) takes every such pixel;
    * background (0): the rest, plus (``gaps``) the sky seen through gaps in the crown
      (:func:`sky_gaps`), eroded by one pixel, so that the matte can be see-through there.

    Parameters
    ----------
    image : ndarray, shape (H, W, 3), uint8
    segmentation : Segmentation
    band : int, optional
        Half width of the unknown band (default 1.5 % of the long side, at least 2 px).
    erode : int, optional
        Erosion of the trunk (default a third of ``band``, at least 1 px).
    point_spacing : float
        Mean spacing in pixels of the crown's foreground points (1 = all of them).
    gaps : bool
        Mark sky-coloured gaps inside the crown as background.
    seed : int or Generator, optional

    Returns
    -------
    ndarray, shape (H, W), float64
        0 background, 0.5 unknown, 1 foreground.
    """
    img = _check_image(image)
    seg = _check_seg(segmentation, img.shape[:2])
    if not point_spacing >= 1:
        raise InputError(f"point_spacing: expected a number >= 1, got {point_spacing!r}")
    rng = as_rng(seed)
    tree = seg.tree_mask
    h, w = tree.shape
    band = max(2, int(round(0.015 * max(h, w)))) if band is None else int(band)
    erode = max(1, band // 3) if erode is None else int(erode)
    if band < 1 or erode < 0:
        raise InputError(f"band, erode: expected band >= 1 and erode >= 0, got {band}, {erode}")
    tri = np.zeros((h, w), np.float64)
    tri[cv2.dilate(tree.astype(np.uint8), _disc(band)).astype(bool)] = UNKNOWN
    wood = seg.wood_mask
    crown = tree & ~wood
    fg = cv2.erode(wood.astype(np.uint8), _disc(erode)).astype(bool) if erode else wood.copy()
    inner = cv2.erode(crown.astype(np.uint8), _disc(band)).astype(bool) & (seg.alpha >= 0.9)
    if gaps:
        gap = sky_gaps(img, seg)
        inner &= ~cv2.dilate(gap.astype(np.uint8), _disc(1)).astype(bool)
        cross = cv2.getStructuringElement(cv2.MORPH_CROSS, (3, 3))
        tri[cv2.erode(gap.astype(np.uint8), cross).astype(bool)] = 0.0
    if point_spacing <= 1:
        fg |= inner
    else:
        ys, xs = np.nonzero(inner)
        n = min(len(ys), int(round(len(ys) / point_spacing ** 2)))
        if n:
            pick = rng.choice(len(ys), size=n, replace=False)
            fg[ys[pick], xs[pick]] = True
    tri[fg] = 1.0
    return tri


def alpha_matting(image, trimap, *, max_side: int = 800) -> np.ndarray:
    """Closed-form alpha matting (PyMatting's ``estimate_alpha_cf``).

    Images larger than ``max_side`` are matted at a reduced size; the alpha is then
    upsampled bilinearly and the trimap's known pixels restored.

    Parameters
    ----------
    image : ndarray, shape (H, W, 3), uint8
    trimap : ndarray, shape (H, W), float
        0 background, 1 foreground, anything between unknown.
    max_side : int

    Returns
    -------
    ndarray, shape (H, W), float32 in [0, 1]
    """
    img = _check_image(image)
    tri = np.asarray(trimap, np.float64)
    if tri.shape != img.shape[:2]:
        raise InputError(f"trimap: shape {tri.shape} does not match the image's {img.shape[:2]}")
    if not np.all(np.isfinite(tri)) or tri.min() < 0 or tri.max() > 1:
        raise InputError("trimap: values must lie in [0, 1]")
    if not (tri == 1).any() or not (tri == 0).any():
        raise InputError("trimap: needs both foreground (1) and background (0) pixels")
    if isinstance(max_side, bool) or not isinstance(max_side, (int, np.integer)) or max_side < 16:
        raise InputError(f"max_side: expected an integer >= 16, got {max_side!r}")
    estimate_alpha_cf = _import_pymatting().estimate_alpha_cf

    h, w = tri.shape
    s = min(1.0, max_side / max(h, w))
    if s < 1.0:
        size = (max(8, round(w * s)), max(8, round(h * s)))
        im_s = cv2.resize(img, size, interpolation=cv2.INTER_AREA)
        tr_s = cv2.resize(tri, size, interpolation=cv2.INTER_NEAREST)
    else:
        im_s, tr_s = img, tri
    # PyMatting prints a "PERFORMANCE WARNING" paragraph to stdout whenever its preconditioner
    # needs a diagonal shift (it then retries): not for our users' terminals (the views of a
    # multi-view capture are matted on threads side by side: one sink for all of them)
    with _quiet_stdout():
        alpha = estimate_alpha_cf(im_s.astype(np.float64) / 255.0, tr_s,
                                  cg_kwargs={"maxiter": 2000})
    # solver noise: a faint haze of alpha ~ 0.01 over the background, or holes of 0.99
    alpha = np.clip(alpha, 0.0, 1.0)
    alpha[alpha < 0.02] = 0.0
    alpha[alpha > 0.98] = 1.0
    if s < 1.0:
        alpha = cv2.resize(alpha, (w, h), interpolation=cv2.INTER_LINEAR)
        alpha[tri == 0] = 0.0
        alpha[tri == 1] = 1.0
    return alpha.astype(np.float32)


def estimate_foreground(image, alpha) -> np.ndarray:
    """Foreground colours F of a matte (PyMatting's multilevel ``estimate_foreground_ml``).

    Returns
    -------
    ndarray, shape (H, W, 3), float32 in [0, 1]
    """
    img = _check_image(image)
    a = np.asarray(alpha, np.float64)
    if a.shape != img.shape[:2]:
        raise InputError(f"alpha: shape {a.shape} does not match the image's {img.shape[:2]}")
    estimate_foreground_ml = _import_pymatting().estimate_foreground_ml

    fg = estimate_foreground_ml(img.astype(np.float64) / 255.0, np.clip(a, 0.0, 1.0))
    return np.clip(fg, 0.0, 1.0).astype(np.float32)


def matte_tree(image, segmentation, *, max_side: int = 800, gaps: bool = True, seed=None) -> tuple:
    """Photo + segmentation -> RGBA billboard (seed 000 §4.3, Fig. 4).

    Parameters
    ----------
    image : ndarray, shape (H, W, 3), uint8
    segmentation : Segmentation
        E.g. from :func:`treeform.segment.segment_tree`.
    max_side : int
        Long side at which the matting runs (the alpha is upsampled).
    gaps : bool
        See :func:`make_trimap`.
    seed : int or Generator, optional

    Returns
    -------
    rgba : ndarray, shape (H, W, 4), uint8
        Foreground colour and alpha; (0, 0, 0, 0) where alpha is 0.
    trimap : ndarray, shape (H, W), float64
    """
    img = _check_image(image)
    tri = make_trimap(img, segmentation, gaps=gaps, seed=seed)
    alpha = alpha_matting(img, tri, max_side=max_side)
    fg = estimate_foreground(img, alpha)
    rgba = np.empty(img.shape[:2] + (4,), np.uint8)
    rgba[..., :3] = np.clip(np.rint(fg * 255), 0, 255)
    rgba[..., 3] = np.clip(np.rint(alpha * 255), 0, 255)
    rgba[rgba[..., 3] == 0] = 0
    return rgba, tri
