"""Pin points B (tree bottom), L (trunk top-left) and R (trunk top-right) on a contour.

Seed 000 §4.4. Image coordinates (``y`` down): the tree bottom is the point with the
*largest* row, and the crown baseline is the largest row of a crown pixel.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from treeform._shared.checks import check_array
from treeform._shared.errors import InputError

__all__ = ["PinPoints", "pin_points", "crown_baseline"]


@dataclass(frozen=True)
class PinPoints:
    """Indices of the pin points into a contour of length ``n``.

    ``b`` is the tree bottom, ``r`` is reached from ``b`` going forward along the
    contour (the right side of the trunk, for a contour from :func:`orient_contour
    <treeform.contour.borders.orient_contour>`), ``l`` going backward. Without a trunk
    ``l == r == b``.
    """

    b: int
    l: int  # noqa: E741 - the paper's name
    r: int
    n: int

    @property
    def has_trunk(self) -> bool:
        return not (self.l == self.b and self.r == self.b)

    def segments(self) -> tuple[int, int, int]:
        """Forward lengths (in contour steps) of B->R, R->L and L->B; they sum to ``n``."""
        br = (self.r - self.b) % self.n
        rl = (self.l - self.r) % self.n
        lb = (self.b - self.l) % self.n
        if not self.has_trunk:
            return 0, self.n, 0
        return br, rl, lb


def crown_baseline(crown_mask, *, ignore: float = 0.0) -> float | None:
    """The crown baseline: the lowest row (largest ``y``) of the crown, or None.

    Parameters
    ----------
    crown_mask : ndarray, shape (H, W), bool
    ignore : float
        Fraction of the crown's pixels, the lowest ones, to ignore (0 = the paper's
        lowest crown pixel; a small value such as 0.002 makes the baseline robust to
        stray crown specks beside the trunk's foot).

    Examples
    --------
    >>> m = np.zeros((6, 4), bool); m[1:3] = True
    >>> crown_baseline(m)
    2.0
    """
    m = np.asarray(check_array(crown_mask, "crown_mask", ndim=2), bool)
    if not 0 <= ignore < 1:
        raise InputError(f"ignore: expected a fraction in [0, 1), got {ignore!r}")
    per_row = m.sum(1)
    total = int(per_row.sum())
    if total == 0:
        return None
    below = np.cumsum(per_row[::-1])[::-1]  # crown pixels on this row and below
    rows = np.nonzero((below > ignore * total) & (per_row > 0))[0]
    return float(rows.max())


def pin_points(contour, *, baseline: float | None) -> PinPoints:
    """Select the pin points B, L, R on an overall tree contour (seed 000 §4.4).

    B is the contour point with the lowest position (largest row); when several share it,
    the one at their median column. From B the contour is traversed forward and backward;
    each traversal stops at the first point at or above the crown baseline (the contour
    segment reaching it crosses the baseline), giving R (forward) and L (backward). Without
    a trunk (``baseline`` None, or not above B) ``L = R = B``, as in the paper; also when
    the two traversals meet (the contour never rises above the baseline on one side).

    Parameters
    ----------
    contour : ndarray, shape (K, 2)
        Closed contour ``(x, y)``, e.g. from :func:`longest_exterior_contour
        <treeform.contour.borders.longest_exterior_contour>`.
    baseline : float or None
        Row of the crown baseline (:func:`crown_baseline`); None when the tree has no
        trunk pixels.

    Returns
    -------
    PinPoints

    Examples
    --------
    >>> c = np.array([[1, 4], [2, 4], [2, 2], [3, 2], [3, 0], [0, 0], [0, 2], [1, 2]], float)
    >>> pin_points(c, baseline=2.0)
    PinPoints(b=0, l=7, r=2, n=8)
    """
    c = check_array(contour, "contour", ndim=2, dtype_kind="iuf", min_size=2)
    if c.shape[1] != 2:
        raise InputError(f"contour: expected shape (K, 2), got {c.shape}")
    n = len(c)
    y = c[:, 1]
    low = np.nonzero(y >= y.max() - 1e-9)[0]
    mx = np.median(c[low, 0])
    b = int(low[np.argmin(np.abs(c[low, 0] - mx) + 1e-9 * np.arange(len(low)))])
    if baseline is None or not baseline < y[b] or n < 3:
        return PinPoints(b, b, b, n)
    order_f = (b + np.arange(1, n)) % n
    order_b = (b - np.arange(1, n)) % n
    hit_f = np.nonzero(y[order_f] <= baseline)[0]
    hit_b = np.nonzero(y[order_b] <= baseline)[0]
    if hit_f.size == 0 or hit_b.size == 0 or hit_f[0] + hit_b[0] + 2 >= n:
        return PinPoints(b, b, b, n)
    return PinPoints(b, int(order_b[hit_b[0]]), int(order_f[hit_f[0]]), n)
