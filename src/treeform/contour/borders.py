"""Border following on binary masks: all contours, and the overall (longest exterior) one.

Seed 000 §4.2. OpenCV's ``findContours`` implements the border following algorithm of
Suzuki & Abe (1985), the one the paper cites as [SA85].

Coordinates are pixel positions ``(x, y)`` = (column, row), pixel centres at integers,
``y`` growing downwards (image convention).
"""

from __future__ import annotations

import cv2
import numpy as np

from treeform._shared.checks import check_array
from treeform._shared.errors import InputError, NoTreeFoundError

__all__ = ["find_contours", "longest_exterior_contour", "signed_area", "orient_contour", "contour_length"]


def _as_mask(mask, name: str = "mask") -> np.ndarray:
    m = check_array(mask, name, ndim=2)
    if m.dtype == bool:
        return m.astype(np.uint8)
    if m.dtype.kind not in "uif":
        raise InputError(f"{name}: expected a bool or numeric (H, W) array, got {m.dtype}")
    return (m > (0.5 if m.dtype.kind == "f" else 0)).astype(np.uint8)


def find_contours(mask) -> tuple[list[np.ndarray], np.ndarray]:
    """All borders between opaque and transparent pixels of a binary mask (seed 000 §4.2).

    Parameters
    ----------
    mask : ndarray, shape (H, W), bool or numeric
        Non-zero (floats: > 0.5) = opaque.

    Returns
    -------
    contours : list of ndarray, each shape (K, 2), float64
        Border pixels ``(x, y)`` in order along the border (every 8-connected border pixel).
    exterior : ndarray, shape (n_contours,), bool
        True for exterior contours (not inside any other contour), False for the
        borders of holes (interior contours).

    Examples
    --------
    >>> m = np.zeros((7, 7), bool); m[1:6, 1:6] = True; m[3, 3] = False
    >>> cs, ext = find_contours(m)
    >>> ext.tolist(), [len(c) for c in cs]
    ([True, False], [16, 4])
    """
    m = _as_mask(mask)
    found, hierarchy = cv2.findContours(m, cv2.RETR_CCOMP, cv2.CHAIN_APPROX_NONE)
    if not found:
        return [], np.zeros(0, bool)
    contours = [c.reshape(-1, 2).astype(np.float64) for c in found]
    # RETR_CCOMP: two levels; a contour with no parent is an exterior border
    exterior = hierarchy.reshape(-1, 4)[:, 3] < 0
    return contours, exterior


def contour_length(points, *, closed: bool = True) -> float:
    """Length of the polyline through ``points`` (N, 2), closed by default."""
    p = np.asarray(points, np.float64)
    if len(p) < 2:
        return 0.0
    d = np.diff(np.vstack([p, p[:1]]) if closed else p, axis=0)
    return float(np.hypot(d[:, 0], d[:, 1]).sum())


def signed_area(points) -> float:
    """Shoelace area of the closed polygon ``points`` (N, 2) in image coordinates.

    Negative when the polygon runs counter-clockwise on screen (y down), i.e. from the
    bottom towards the right.
    """
    p = np.asarray(points, np.float64)
    if len(p) < 3:
        return 0.0
    x, y = p[:, 0], p[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def orient_contour(points) -> np.ndarray:
    """``points`` reordered, if needed, to run counter-clockwise on screen.

    Starting from the bottom of a tree, the contour then first goes right (up the right
    side of the trunk), across the top from right to left, and down the left side.
    """
    p = np.asarray(points, np.float64)
    return p[::-1].copy() if signed_area(p) > 0 else p.copy()


def longest_exterior_contour(mask) -> np.ndarray:
    """The overall contour C of a tree: its longest exterior contour (seed 000 §4.2).

    Parameters
    ----------
    mask : ndarray, shape (H, W)
        Binary alpha mask A_t (alpha thresholded at 0.5).

    Returns
    -------
    ndarray, shape (K, 2), float64
        Border pixels ``(x, y)`` of the exterior contour with the largest length,
        oriented counter-clockwise on screen (see :func:`orient_contour`).

    Raises
    ------
    NoTreeFoundError
        The mask is empty.
    """
    contours, exterior = find_contours(mask)
    ext = [c for c, e in zip(contours, exterior) if e]
    if not ext:
        raise NoTreeFoundError("mask: no opaque pixels, so no contour")
    lengths = [contour_length(c) if len(c) > 1 else 0.0 for c in ext]
    return orient_contour(ext[int(np.argmax(lengths))])
