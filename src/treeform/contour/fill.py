"""Region fill of (possibly self-intersecting) contours and the simplified contour Cs.

Seed 000 §5.1 (region fill) and §4.6 (simplification).
"""

from __future__ import annotations

import cv2
import numpy as np

from treeform._shared.checks import check_array
from treeform._shared.errors import InputError
from treeform.contour.borders import longest_exterior_contour
from treeform.contour.pins import PinPoints
from treeform.contour.resample import resample_contour, segment_counts

__all__ = ["fill_contour", "simplify_contour"]

_SHIFT = 4  # sub-pixel bits for OpenCV drawing


def _shape(shape) -> tuple[int, int]:
    try:
        h, w = (int(s) for s in shape)
    except (TypeError, ValueError):
        raise InputError(f"shape: expected (H, W), got {shape!r}") from None
    if h < 1 or w < 1:
        raise InputError(f"shape: expected positive (H, W), got {shape!r}")
    return h, w


def fill_contour(points, shape) -> np.ndarray:
    """Pixels inside a closed contour, robust to self-intersections (seed 000 §5.1).

    As in the paper, the contour is drawn onto a blank canvas and a region fill
    (4-connected flood fill) from outside clears everything reachable from the image
    border; what is left — the drawn contour and every region it encloses — is the
    tree. A self-intersecting contour therefore never leaves holes: its result is the
    union of the interiors of all its loops.

    Parameters
    ----------
    points : ndarray, shape (N, 2)
        Closed contour ``(x, y)`` in pixels (float; drawn with sub-pixel precision).
    shape : tuple (H, W)

    Returns
    -------
    ndarray, shape (H, W), bool

    Examples
    --------
    >>> bowtie = np.array([[1, 1], [8, 8], [8, 1], [1, 8]], float)  # self-intersecting
    >>> m = fill_contour(bowtie, (10, 10))
    >>> bool(m[4, 2]), bool(m[4, 7]), bool(m[1, 4]), bool(m[0, 0])
    (True, True, False, False)
    """
    h, w = _shape(shape)
    p = check_array(points, "points", ndim=2, dtype_kind="iuf")
    if p.shape[1] != 2 or len(p) < 1:
        raise InputError(f"points: expected shape (N, 2) with N >= 1, got {p.shape}")
    # a one-pixel frame so that the fill starts outside any contour touching the border
    canvas = np.zeros((h + 2, w + 2), np.uint8)
    q = np.rint((p + 1.0) * (1 << _SHIFT)).astype(np.int32).reshape(-1, 1, 2)
    cv2.polylines(canvas, [q], True, 1, thickness=1, lineType=cv2.LINE_8, shift=_SHIFT)
    flood = np.zeros((h + 4, w + 4), np.uint8)
    cv2.floodFill(canvas, flood, (0, 0), 2, flags=4)
    return canvas[1:-1, 1:-1] != 2


def simplify_contour(resampled, shape, *, m: int = 20, dilate: int = 8, counts=None) -> np.ndarray:
    """The simplified contour Cs of M points used for mean value coordinates (seed 000 §4.6).

    The interior of Cr is filled (:func:`fill_contour`), dilated ``dilate`` times with a
    3 x 3 kernel (mean value coordinates distort most near and outside the contour, so
    Cs lies a little outside Cr), and the exterior contour of that mask is resampled to
    ``m`` points. So that vertex i of every Cs corresponds to vertex i of every other,
    the resampling uses the pins of Cr carried over to the dilated contour (its points
    nearest to B = Cr[0], R = Cr[counts[0]] and L = Cr[counts[0] + counts[1]]), with
    10 % of the points on each trunk side (:func:`segment_counts
    <treeform.contour.resample.segment_counts>`).

    Parameters
    ----------
    resampled : ndarray, shape (N, 2)
        Cr from :func:`resample_contour <treeform.contour.resample.resample_contour>`.
    shape : tuple (H, W)
        Image size.
    m : int
        Number of points M of Cs (paper: 20 .. 100; 20 is as good as 100).
    dilate : int
        Dilation iterations (paper: 8 at 1024 x 1024).
    counts : tuple of 3 int, optional
        The counts Cr was made with (default: 10 % / 80 % / 10 % of N).

    Returns
    -------
    ndarray, shape (m, 2), float64
        Cs; ``Cs[0]`` is the point of the dilated contour nearest to B.
    """
    cr = check_array(resampled, "resampled", ndim=2, dtype_kind="iuf")
    if cr.shape[1] != 2 or len(cr) < 3:
        raise InputError(f"resampled: expected shape (N, 2) with N >= 3, got {cr.shape}")
    if isinstance(m, bool) or not isinstance(m, (int, np.integer)) or m < 3:
        raise InputError(f"m: expected an integer >= 3, got {m!r}")
    if isinstance(dilate, bool) or not isinstance(dilate, (int, np.integer)) or dilate < 0:
        raise InputError(f"dilate: expected an integer >= 0, got {dilate!r}")
    h, w = _shape(shape)
    n = len(cr)
    counts = segment_counts(n) if counts is None else tuple(int(k) for k in counts)
    if len(counts) != 3 or sum(counts) != n:
        raise InputError(f"counts: expected 3 counts summing to {n}, got {counts!r}")
    mask = fill_contour(cr, (h, w)).astype(np.uint8)
    if dilate:
        mask = cv2.dilate(mask, np.ones((3, 3), np.uint8), iterations=int(dilate))
    c = longest_exterior_contour(mask)
    k = len(c)

    def nearest(pt):
        return int(np.argmin(((c - pt) ** 2).sum(1)))

    b, r, l_ = nearest(cr[0]), nearest(cr[counts[0]]), nearest(cr[counts[0] + counts[1]])
    has_trunk = not (np.allclose(cr[counts[0]], cr[0]) and np.allclose(cr[counts[0] + counts[1]], cr[0]))
    br, bl = (r - b) % k, (l_ - b) % k
    if not has_trunk or r == b or l_ == b or br >= bl:
        pins = PinPoints(b, b, b, k)  # the trunk vanished in the dilation, or pins out of order
    else:
        pins = PinPoints(b, l_, r, k)
    return resample_contour(c, pins, counts=segment_counts(m))
