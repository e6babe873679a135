"""The learned trunk feet of a photo on its tree mask (issue 16 item 2).

The foot detector (:class:`~treeform.learn.infer.FeetDetector`) sees the photo at 384 pixels
and places a foot within a few of them; :func:`snap_feet` moves each of its peaks to the
lowest point of the tree mask it stands on (the row the ground placement needs to a pixel),
drops peaks on a trunk above its foot, and gives each foot a marker (its trunk's lowest part)
for :func:`~treeform.segment.instances.split_at_trunks`. :func:`union_feet` joins them to the
feet of the rules (:func:`~treeform.segment.instances.trunk_feet`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["snap_feet", "union_feet"]


def snap_feet(tree: np.ndarray, peaks, *, band: float = 0.012, reach: float = 0.03,
              max_drop: float = 0.1, keep: float = 0.5, above: float = 0.35) -> list[tuple]:
    """The learned detector's feet, each moved to the lowest point of the tree mask it stands on.

    The heatmap places a foot within a few pixels (it sees the photo at 384 pixels); the
    placement on the ground needs its row to a pixel. Each peak (u, v) takes, in the band of
    columns ``u +- band`` x W, the piece of ``tree`` (connected in the band) nearest to it
    within ``reach`` x H; the foot is that piece's lowest row, in the middle of its pixels
    there. A peak on a trunk above its foot (the piece goes on down more than ``max_drop`` x H)
    is dropped. A peak with no tree near it is dropped too, unless it is at least ``keep``
    strong and tree pixels stand above it in its band (within ``above`` x H): a thin trunk
    the segmenter missed, under a crown it found; it stays where the detector put it, as it
    does when the piece ends more than 1 % of H above it (the trunk's lowest part missing). Two
    peaks that reach the same foot are one (the stronger one's marker and score stay).

    Parameters
    ----------
    tree : ndarray, shape (H, W), bool
        Every tree's pixels.
    peaks : array_like, shape (N, 3)
        (u, v, score) of :meth:`~treeform.learn.infer.FeetDetector.detect`, strongest first.
    band, reach, max_drop, keep, above : float

    Returns
    -------
    list of (ndarray (H, W) bool, (float, float), float)
        (marker: the trunk's piece from the foot up to ``max_drop`` x H above it, (u, v) foot,
        score), left to right.

    Examples
    --------
    A trunk standing at (30, 49) and a peak a little off it; a peak on the sky goes:

    >>> m = np.zeros((60, 80), bool); m[5:30, 10:50] = True; m[30:50, 29:32] = True
    >>> [(f, sc) for _, f, sc in snap_feet(m, [[31.0, 46.0, 0.9], [70.0, 10.0, 0.5]])]
    [((30.0, 49.0), 0.9)]
    """
    import scipy.ndimage as ndi

    tree = np.asarray(tree, bool)
    H, W = tree.shape
    r = max(2, int(round(band * W)))
    ry = max(3, int(round(reach * H)))
    drop = max(ry, int(round(max_drop * H)))
    lift = max(2, int(round(0.01 * H)))
    out: list = []
    for u, v, score in np.asarray(peaks, np.float64).reshape(-1, 3):
        x0, x1 = max(0, int(round(u)) - r), min(W, int(round(u)) + r + 1)
        if x1 <= x0:
            continue
        lab, n = ndi.label(tree[:, x0:x1], structure=np.ones((3, 3)))
        if n == 0:
            continue
        y0, y1 = max(0, int(round(v)) - ry), min(H, int(round(v)) + ry + 1)
        ys, xs = np.nonzero(lab[y0:y1])
        if ys.size:
            near = np.argmin((ys + y0 - v) ** 2 + (xs + x0 - u) ** 2)
            piece = lab == lab[ys[near] + y0, xs[near]]
            bottom = int(np.flatnonzero(piece.any(1))[-1])
            if bottom - v > drop:
                continue
            if bottom >= v - lift:
                foot_u, foot_v = float(np.flatnonzero(piece[bottom]).mean()) + x0, bottom
            else:  # the mask ends above the foot (a thin trunk's lowest part missing): the detector's foot
                foot_u, foot_v = float(u), int(round(min(v, H - 1)))
        else:  # nothing near: a trunk the mask lacks, under a crown above it?
            ya = max(0, int(round(v - above * H)))
            rows = np.flatnonzero(lab[ya:y0].any(1))
            if score < keep or rows.size == 0:
                continue
            low = ya + int(rows[-1])
            piece = np.zeros(lab.shape, bool)
            piece[:low + 1] = lab[:low + 1] == lab[low, np.flatnonzero(lab[low])[0]]
            foot_u, foot_v, bottom = float(u), int(round(min(v, H - 1))), low
        if any(abs(foot_u - f[0]) <= r and abs(foot_v - f[1]) <= 2 for _, f, _ in out):
            continue  # the foot of a stronger peak
        marker = np.zeros_like(tree)
        top = max(0, bottom - drop)
        marker[top:bottom + 1, x0:x1] = piece[top:bottom + 1]
        out.append((marker, (foot_u, float(foot_v)), float(score)))
    out.sort(key=lambda t: t[1][0])
    return out


def union_feet(rule_feet: list, learned: list, tol_u: float, tol_v: float) -> list:
    """Feet of the rules and of the detector together: a learned foot within ``tol_u`` columns and
    ``tol_v`` rows of a rule foot is that foot (the rule's stays); the others join, after the
    rules' feet (:func:`~treeform.segment.instances.merge_joined_feet` then makes one foot of
    those on one trunk, keeping the rule's).

    Both are lowest points of the mask, so one trunk's two feet coincide within a few pixels,
    while a tree standing nearly behind another has its foot a little aside and higher.
    """
    out = list(rule_feet)
    for marker, foot, _ in learned:
        if not any(abs(foot[0] - f[0]) <= tol_u and abs(foot[1] - f[1]) <= tol_v for _, f in rule_feet):
            out.append((marker, foot))
    return out
