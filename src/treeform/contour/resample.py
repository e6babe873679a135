"""Fixed-length contours: chord-length resampling between pin points (seed 000 §4.5).

A resampled contour Cr has exactly ``N = n_right + n_crown + n_left`` points (paper:
200 + 1600 + 200 = 2000): the right trunk segment B -> R, the crown segment R -> L and
the left trunk segment L -> B, each sampled uniformly by arc length along the contour
(chord-length parameterisation). Point 0 is the bottom pin B, point ``n_right`` is R and
point ``n_right + n_crown`` is L, in every exemplar, so the flattened ``(2N,)`` vectors
of different trees correspond component by component.
"""

from __future__ import annotations

import numpy as np

from treeform._shared.checks import check_array
from treeform._shared.errors import InputError
from treeform.contour.pins import PinPoints

__all__ = ["resample_polyline", "resample_contour", "DEFAULT_COUNTS", "segment_counts"]

DEFAULT_COUNTS = (200, 1600, 200)
"""Points on the right trunk, crown and left trunk segments of Cr (seed 000 §4.5)."""


def segment_counts(n: int) -> tuple[int, int, int]:
    """Split ``n`` points as the paper does (10 % per trunk side, 80 % crown), e.g.
    ``segment_counts(20) == (2, 16, 2)``."""
    if n < 3:
        raise InputError(f"n: expected at least 3 points, got {n}")
    t = max(1, int(round(0.1 * n)))
    return t, n - 2 * t, t


def resample_polyline(points, n: int, *, endpoint: bool = False) -> np.ndarray:
    """``n`` points uniformly spaced by arc length along an open polyline.

    Parameters
    ----------
    points : ndarray, shape (K, D)
        An image contour (D = 2) or a path in space (D = 3); a flat sequence is read as (K, 2).
    n : int
        Number of output points (>= 0).
    endpoint : bool
        Whether the last output point is the polyline's end. With ``False`` (default)
        the samples sit at arc lengths ``k * L / n``, k = 0 .. n - 1, so consecutive
        segments can be concatenated without duplicating their shared end points.

    Returns
    -------
    ndarray, shape (n, D), float64
        The first point is ``points[0]``. A zero-length polyline gives ``n`` copies of it.

    Examples
    --------
    >>> resample_polyline([[0, 0], [4, 0]], 4).tolist()
    [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0]]
    >>> resample_polyline([[0, 0, 0], [0, 2, 0], [2, 2, 0]], 3, endpoint=True).tolist()  # in space
    [[0.0, 0.0, 0.0], [0.0, 2.0, 0.0], [2.0, 2.0, 0.0]]
    """
    p = np.asarray(points, np.float64)
    p = p.reshape(-1, 2) if p.ndim != 2 else p
    if len(p) == 0:
        raise InputError("points: empty polyline")
    if n <= 0:
        return np.zeros((0, p.shape[1]))
    d = np.diff(p, axis=0)
    seg = np.hypot(*d.T) if p.shape[1] == 2 else np.linalg.norm(d, axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    total = s[-1]
    if total <= 0:
        return np.repeat(p[:1], n, axis=0)
    t = np.linspace(0.0, total, n) if endpoint and n > 1 else np.arange(n) * (total / n)
    return np.column_stack([np.interp(t, s, p[:, k]) for k in range(p.shape[1])])


def _arc(c: np.ndarray, start: int, steps: int) -> np.ndarray:
    """Contour points from index ``start`` forward ``steps`` steps (inclusive, wrapping)."""
    return c[(start + np.arange(steps + 1)) % len(c)]


def resample_contour(contour, pins: PinPoints, *, counts=DEFAULT_COUNTS) -> np.ndarray:
    """Resample an overall contour C to the fixed-length contour Cr (seed 000 §4.5).

    Parameters
    ----------
    contour : ndarray, shape (K, 2)
        Closed contour ``(x, y)``, oriented as by :func:`orient_contour
        <treeform.contour.borders.orient_contour>`.
    pins : PinPoints
        B, L, R on ``contour`` (:func:`pin_points <treeform.contour.pins.pin_points>`).
    counts : tuple of 3 int
        Points on B -> R, R -> L and L -> B (default 200, 1600, 200).

    Returns
    -------
    ndarray, shape (sum(counts), 2), float64
        Cr; ``Cr[0]`` is B, ``Cr[counts[0]]`` is R, ``Cr[counts[0] + counts[1]]`` is L.
        Without a trunk (L = R = B) both trunk segments collapse onto B.
    """
    c = check_array(contour, "contour", ndim=2, dtype_kind="iuf", min_size=2).astype(np.float64)
    if c.shape[1] != 2 or len(c) != pins.n:
        raise InputError(f"contour: expected shape ({pins.n}, 2) to match the pins, got {c.shape}")
    n_r, n_c, n_l = (int(k) for k in counts)
    if min(n_r, n_c, n_l) < 1:
        raise InputError(f"counts: expected three counts >= 1, got {counts!r}")
    br, rl, lb = pins.segments()
    if not pins.has_trunk:
        return np.vstack([np.repeat(c[[pins.b]], n_r, axis=0), resample_polyline(_arc(c, pins.b, pins.n), n_c),
                          np.repeat(c[[pins.b]], n_l, axis=0)])
    return np.vstack([resample_polyline(_arc(c, pins.b, br), n_r),
                      resample_polyline(_arc(c, pins.r, rl), n_c),
                      resample_polyline(_arc(c, pins.l, lb), n_l)])
