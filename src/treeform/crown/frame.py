"""The crown past the photo's edges: a tree too large for the frame is not cut flat (issue 11).

A crown that the photo's top or side edge cuts has a straight edge there in its silhouette, and
an envelope inflated from that silhouette (:func:`~treeform.crown.envelope.inflate_envelope`)
has a flat face: from the side and from above the tree becomes a box. The crown goes on past
the frame, where the photo says nothing of it. :func:`beyond_frame` continues it with the
least-committal round shape: over each run of the edge the crown covers, a half ellipse as
wide as the run and standing out a fixed share of that width (a round crown cut through its
middle loses a half disc; one cut near its rim a shallow cap), at most ``reach`` of the crown's
size, and the frame's corners bridged where the crown covers both edges there. The bottom
edge is the ground and is never continued, nor is a run of a side that starts below the
crown's middle height: a crown the side cuts is cut across its upper half, while what reaches
a side only lower down is mostly a hedge, planters or a neighbouring tree the mask took in.

Functions over arrays (masks in, masks out); the envelope route uses the result for the
crown's shape, its branches and the leaves it cannot see in the photo.
"""

from __future__ import annotations

import numpy as np

from treeform._shared.checks import check_array
from treeform._shared.errors import InputError

__all__ = ["beyond_frame", "CAP_RATIO", "REACH", "MIN_RUN"]

CAP_RATIO = 0.35
"""How far a cap stands out past the edge, as a share of the run of the edge it covers."""

REACH = 0.3
"""At most this share of the crown's height (top edge) or width (side edges) past the frame."""

MIN_RUN = 0.03
"""Runs of the edge shorter than this share of the edge are the crown's ragged outline touching it: left as they are."""


def _runs(edge: np.ndarray, gap: int) -> list[tuple[int, int]]:
    """[a, b) runs of True in a 1-D array, runs closer than ``gap`` joined."""
    idx = np.flatnonzero(np.diff(np.r_[0, edge.astype(np.int8), 0]))
    runs = [(int(a), int(b)) for a, b in zip(idx[::2], idx[1::2])]
    out: list[tuple[int, int]] = []
    for a, b in runs:
        if out and a - out[-1][1] <= gap:
            out[-1] = (out[-1][0], b)
        else:
            out.append((a, b))
    return out


def _half_ellipse(a: int, b: int, h: float) -> list[tuple[int, int]]:
    """(position, extent) along the run [a, b) of a half ellipse as wide as the run and ``h`` deep (extents >= 1)."""
    c, r = 0.5 * (a + b - 1), max(0.5 * (b - a), 0.5)
    k = np.arange(a, b)
    n = np.rint(h * np.sqrt(np.clip(1.0 - ((k - c) / r) ** 2, 0.0, 1.0))).astype(int)
    return [(int(kk), int(nn)) for kk, nn in zip(k, n) if nn > 0]


def beyond_frame(mask: np.ndarray, *, cap: float = CAP_RATIO, reach: float = REACH,
                 min_run: float = MIN_RUN) -> tuple[np.ndarray, tuple[int, int]]:
    """The crown silhouette continued past the top, left and right edges of the frame it touches.

    Parameters
    ----------
    mask : ndarray, shape (H, W), bool
        The crown's silhouette in the photo.
    cap : float
        A run of ``L`` edge pixels gets a half-ellipse cap standing ``cap * L`` past the edge ...
    reach : float
        ... but no more than ``reach`` times the crown's height (top) or width (sides).
    min_run : float
        Runs shorter than this share of the edge's length are not continued.

    Returns
    -------
    padded : ndarray, shape (H + top, W + left + right), bool
        ``mask`` at rows ``top:``, columns ``left:left + W``, with the crown's continuation
        around it (no margin is added where nothing is continued: ``padded`` is ``mask`` then).
    offset : (int, int)
        ``(top, left)``: pixel (u, v) of the photo is ``padded[v + top, u + left]``.

    Examples
    --------
    A disc whose top the frame cuts gets its top back, rounded; the bottom edge (the ground) is
    never continued, and a crown inside the frame is left as it is:

    >>> yy, xx = np.mgrid[:60, :80]
    >>> disc = (yy - 20) ** 2 + (xx - 40) ** 2 < 30 ** 2
    >>> padded, (top, left) = beyond_frame(disc)
    >>> top > 0, left, padded.shape[1] == 80, bool(padded[top:].sum() == disc.sum())
    (True, 0, True, True)
    >>> bool(padded[0].sum() < padded[top].sum())                       # rounded, not a box
    True
    >>> beyond_frame(((yy - 30) ** 2 + (xx - 40) ** 2 < 20 ** 2))[1]
    (0, 0)
    """
    import cv2

    m = check_array(mask, "mask", ndim=2).astype(bool)
    for name, v in (("cap", cap), ("reach", reach)):
        if not 0.0 <= float(v) <= 2.0:
            raise InputError(f"{name}: expected a number in [0, 2], got {v!r}")
    H, W = m.shape
    if not m.any():
        return m.copy(), (0, 0)
    ys, xs = np.nonzero(m)
    crown_h, crown_w = float(ys.max() - ys.min() + 1), float(xs.max() - xs.min() + 1)
    middle = 0.5 * (ys.min() + ys.max())
    # the runs of each edge the crown covers, and how far each one's cap stands out
    caps = {}
    for side, edge, length, size in (("top", m[0], W, crown_h), ("left", m[:, 0], H, crown_w),
                                     ("right", m[:, -1], H, crown_w)):
        runs = [(a, b) for a, b in _runs(edge, max(1, int(0.02 * length))) if b - a >= max(2, min_run * length)]
        if side != "top":  # a crown the side cuts is cut across its upper half; what touches the side only
            runs = [(a, b) for a, b in runs if a < middle]  # lower down is a hedge, a neighbour or clutter
        caps[side] = [(a, b, min(cap * (b - a), reach * size)) for a, b in runs]
    depth = {s: int(np.ceil(max([h for *_, h in c], default=0.0))) for s, c in caps.items()}
    top, left, right = depth["top"], depth["left"], depth["right"]
    if top == left == right == 0:
        return m.copy(), (0, 0)
    out = np.zeros((H + top, W + left + right), bool)
    out[top:, left:left + W] = m
    grown = np.zeros_like(out)
    for side, caps_ in caps.items():  # half ellipses standing on each run, outward
        for a, b, h in caps_:
            for k, n in _half_ellipse(a, b, h):
                if side == "top":
                    grown[top - n:top, left + k] = True
                elif side == "left":
                    grown[top + k, left - n:left] = True
                else:
                    grown[top + k, left + W:left + W + n] = True
    # a corner the crown covers on both edges: the convex hull of the two caps and the crown near the
    # corner fills the notch between them (the caps alone meet at the frame's corner in a point)
    for side, col0, col1 in (("left", 0, left), ("right", left + W, left + W + right)):
        if top == 0 or col1 == col0 or not (m[0, 0] if side == "left" else m[0, -1]):
            continue
        c0, c1 = (0, col1 + 2 * top) if side == "left" else (col0 - 2 * top, out.shape[1])
        near = np.zeros_like(out)
        near[:2 * top, max(0, c0):c1] = True
        pts = np.argwhere((grown | out) & near)[:, ::-1].astype(np.int32)
        if len(pts) >= 3:
            hull = np.zeros(out.shape, np.uint8)
            cv2.fillConvexPoly(hull, cv2.convexHull(pts), 1)
            corner = np.zeros_like(out)
            corner[:top, col0:col1] = True
            grown |= hull.astype(bool) & corner
    return out | grown, (top, left)
