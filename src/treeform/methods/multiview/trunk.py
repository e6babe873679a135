"""The trunk's width read from the photos at their own resolution (seed 002 §4.3: radii from the images).

The views' mattes are made at ``mask_size`` by a network that sees each whole photo at once
(``matte_side``): a trunk a few pixels wide comes out wider than it is (2.5-3x with 512-px mattes
seen at 320 px), and the lower trunk is often lost in front of a busy park. Here the trunk's
axis (the visible skeleton's, down to the ground) is projected into every registered photo, the
photo is cut around its lower part at full resolution and the segmentation network run on that
crop alone, so the trunk fills several of the network's pixels; in each image row the tree run
that crosses the axis is the trunk's width there, turned into metres by the axis' depth in that
camera.
"""

from __future__ import annotations

import numpy as np

__all__ = ["TRUNK_BAND", "trunk_axis", "trunk_chain", "trunk_diameter"]

TRUNK_BAND = (0.02, 0.15)
"""Heights, as shares of the tree's height, between which the trunk is measured: above the
ground's clutter and the root flare, below most crowns."""
MIN_ROWS = 3
"""Image rows a view must measure to count."""
MIN_VIEWS = 3
"""Views that must measure the trunk for a width to be returned."""
ROW_QUANTILE = 25.0
"""Percentile of a view's row widths taken as its trunk width: where a hedge, a neighbour's crown or
the tree's own low limbs join the trunk's run in a row, that row reads wider, never narrower."""


def trunk_chain(skeleton) -> np.ndarray:
    """(M,) the trunk's node indices: from the root, always into the child carrying the most nodes.

    >>> from treeform.structures import TreeSkeleton
    >>> sk = TreeSkeleton(np.array([[0, 0, 0], [0, 1, 0], [1, 2, 0], [0, 2, 0], [0, 3, 0.0]]),
    ...                   np.array([-1, 0, 1, 1, 3]), np.ones(5))
    >>> trunk_chain(sk).tolist()
    [0, 1, 3, 4]
    """
    parent = np.asarray(skeleton.parent, np.int64)
    size = skeleton.subtree_sizes()
    children: dict = {}
    for i in range(1, len(parent)):
        children.setdefault(int(parent[i]), []).append(i)
    chain = [0]
    while chain[-1] in children:
        chain.append(max(children[chain[-1]], key=lambda c: size[c]))
    return np.asarray(chain, np.int64)


def trunk_axis(skeleton) -> np.ndarray:
    """(M, 3) the trunk's polyline: the positions of :func:`trunk_chain`."""
    return np.asarray(skeleton.positions, np.float64)[trunk_chain(skeleton)]


def _along(axis: np.ndarray, heights: np.ndarray) -> np.ndarray:
    """Points of the polyline ``axis`` at the given heights (y), along its first rise to each."""
    y = np.maximum.accumulate(axis[:, 1])  # a trunk that dips is read as rising monotonically
    keep = np.r_[True, np.diff(y) > 1e-9]
    y, pts = y[keep], axis[keep]
    if len(y) < 2:
        return np.zeros((0, 3))
    heights = heights[(heights >= y[0]) & (heights <= y[-1])]
    return np.column_stack([np.interp(heights, y, pts[:, d]) for d in range(3)])


def trunk_diameter(sfm, images, axis: np.ndarray, height: float, *, segmenter=None,
                   band: tuple = TRUNK_BAND) -> float | None:
    """The trunk's diameter (metres, the world of ``sfm``), or None where too few photos show it.

    Parameters
    ----------
    sfm : SfmResult
        Registered cameras in the tree's frame (metres, Y up, the foot at the origin).
    images : sequence of ndarray, shape (H, W, 3), uint8
        Each registered photo (``sfm.names`` order), at any size proportional to ``sfm.sizes``.
    axis : ndarray, shape (M, 3)
        The trunk's polyline from the foot up (:func:`trunk_axis`).
    height : float
        The tree's height (metres).
    segmenter : Segmenter, optional
        The learned segmenter (default: the shipped weights).
    band : (float, float)
        Heights measured, as shares of ``height`` (:data:`TRUNK_BAND`).

    Returns
    -------
    float or None
        The median over the photos of each photo's :data:`ROW_QUANTILE` row width, or None
        where fewer than :data:`MIN_VIEWS` photos measure :data:`MIN_ROWS` rows.
    """
    from treeform.learn.infer import Segmenter
    from treeform.segment.instances import run_at

    pts = _along(np.asarray(axis, np.float64).reshape(-1, 3), np.linspace(band[0], band[1], 48) * float(height))
    if len(pts) < 2:
        return None
    seg = segmenter or Segmenter()
    per_view = []
    for k, img in enumerate(images):
        img = np.asarray(img)
        h, w = img.shape[:2]
        s = w / float(sfm.sizes[k, 0])
        uvz = sfm.project(pts, k)
        ok = (uvz[:, 2] > 0) & np.all(np.isfinite(uvz), axis=1)
        uv, z = s * uvz[ok, :2], uvz[ok, 2]
        inside = (uv[:, 0] >= 0) & (uv[:, 0] < w) & (uv[:, 1] >= 0) & (uv[:, 1] < h)
        if inside.sum() < 2:
            continue
        uv, z = uv[inside], z[inside]
        extent = float(np.ptp(uv, axis=0).max())
        side = int(min(max(256.0, 1.5 * extent), h, w))
        x0 = int(np.clip(round(uv[:, 0].mean() - side / 2), 0, w - side))
        y0 = int(np.clip(round(uv[:, 1].mean() - side / 2), 0, h - side))
        tree = seg.probabilities(img[y0:y0 + side, x0:x0 + side])[..., 0] < 0.5
        order = np.argsort(uv[:, 1])
        v_s, u_s, z_s = uv[order, 1], uv[order, 0], z[order]
        tol = max(6, int(round(0.012 * max(h, w))))
        fx = s * float(sfm.K[k, 0, 0])
        widths = []
        for r in range(max(int(np.ceil(v_s[0])), y0), min(int(np.floor(v_s[-1])), y0 + side - 1) + 1):
            c = int(round(np.interp(r, v_s, u_s))) - x0
            run = run_at(tree[r - y0], c - tol, c + tol)
            if run is not None:
                widths.append((run[1] - run[0] + 1) * float(np.interp(r, v_s, z_s)) / fx)
        if len(widths) >= MIN_ROWS:
            per_view.append(float(np.percentile(widths, ROW_QUANTILE)))
    if len(per_view) < MIN_VIEWS:
        return None
    return float(np.median(per_view))
