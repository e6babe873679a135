"""Trunk feet as a heatmap, CenterNet-style (issue 16 item 2): targets, the scene stream, peak picking.

The foot detector (:class:`~treeform.learn.nets.feetnet.FeetNet`) predicts, at stride
:data:`STRIDE` of its input, the logit that a tree's trunk meets the ground in each cell plus
the foot's sub-cell offset (Zhou et al. 2019, "Objects as points": Gaussian targets, a
penalty-reduced focal loss, peaks kept by a 3 x 3 max filter). This module is numpy only: the
trainer builds its targets with :func:`feet_targets`, the runtime
(:class:`~treeform.learn.infer.FeetDetector`) decodes with :func:`heatmap_peaks`.
"""

from __future__ import annotations

import numpy as np

from treeform._shared.errors import InputError

__all__ = ["STRIDE", "SIGMA", "feet_targets", "heatmap_peaks", "FeetStream", "feet_test_scenes", "score_feet"]

STRIDE = 4
"""Input pixels per heatmap cell."""

SIGMA = 1.5
"""Standard deviation of a foot's Gaussian target, in heatmap cells."""


def feet_targets(feet, visible, shape: tuple, *, sigma: float = SIGMA, ignore_radius: float = 3.0) -> tuple:
    """Heatmap, offset and weight targets of one scene's feet.

    Parameters
    ----------
    feet : array_like, shape (N, 2)
        (u, v) input pixels of the feet.
    visible : array_like, shape (N,), bool
        False: the foot is hidden (its cells within ``ignore_radius`` weigh nothing).
    shape : (h, w)
        Heatmap size (the input's divided by :data:`STRIDE`).

    Returns
    -------
    heat : ndarray, shape (h, w), float32
        max over the visible feet of exp(-d^2 / 2 sigma^2), exactly 1 at each foot's cell.
    offset : ndarray, shape (2, h, w), float32
        At each foot's cell, the foot's position in cells minus the cell's index (0..1).
    weight : ndarray, shape (h, w), float32
        1, or 0 near a hidden foot.

    Examples
    --------
    >>> heat, off, wt = feet_targets([[10.0, 22.0]], [True], (8, 8))
    >>> int(heat.argmax()), float(heat.max()), off[:, 5, 2].tolist()
    (42, 1.0, [0.5, 0.5])
    """
    h, w = (int(x) for x in shape)
    feet = np.asarray(feet, np.float64).reshape(-1, 2)
    visible = np.asarray(visible, bool).reshape(-1)
    heat = np.zeros((h, w), np.float32)
    offset = np.zeros((2, h, w), np.float32)
    weight = np.ones((h, w), np.float32)
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
    for (u, v), vis in zip(feet, visible):
        cx, cy = u / STRIDE, v / STRIDE  # cell (i, j) covers input pixels [4i, 4i + 4): its centre is i + 0.5 - 0.5/4 ...
        ix, iy = int(np.floor(cx)), int(np.floor(cy))
        if not (0 <= ix < w and 0 <= iy < h):
            continue
        if not vis:
            weight[(xx - cx) ** 2 + (yy - cy) ** 2 <= ignore_radius ** 2] = 0.0
            continue
        g = np.exp(-((xx - ix) ** 2 + (yy - iy) ** 2) / (2 * sigma ** 2))
        np.maximum(heat, g, out=heat)
        heat[iy, ix] = 1.0
        offset[:, iy, ix] = (cx - ix, cy - iy)
    return heat, offset, weight


def heatmap_peaks(prob: np.ndarray, offset: np.ndarray | None = None, *, threshold: float = 0.3,
                  min_distance: float = 2.0) -> np.ndarray:
    """Feet from a heatmap: local maxima (3 x 3) above ``threshold``, then non-maximum suppression.

    Parameters
    ----------
    prob : ndarray, shape (h, w)
        Foot probabilities per cell.
    offset : ndarray, shape (2, h, w), optional
        Sub-cell offsets (x, y) of the foot in its cell (default 0.5, the cell's middle).
    threshold : float
    min_distance : float
        Of two peaks closer than this (cells), the weaker goes.

    Returns
    -------
    ndarray, shape (N, 3)
        (u, v, score) in input pixels (cell * :data:`STRIDE`), strongest first.

    Examples
    --------
    >>> p = np.zeros((10, 12)); p[3, 4] = 0.9; p[3, 5] = 0.5; p[7, 10] = 0.6
    >>> heatmap_peaks(p).round(2).tolist()
    [[18.0, 14.0, 0.9], [42.0, 30.0, 0.6]]
    """
    import scipy.ndimage as ndi

    prob = np.asarray(prob, np.float32)
    if prob.ndim != 2:
        raise InputError(f"prob: expected an (h, w) heatmap, got shape {prob.shape}")
    local = ndi.maximum_filter(prob, size=3, mode="constant", cval=-1.0)
    ys, xs = np.nonzero((prob >= local) & (prob >= threshold))
    score = prob[ys, xs]
    order = np.lexsort((xs, ys, -score))  # strongest first; ties by position (deterministic)
    kept: list = []
    for i in order:
        if all((xs[i] - xs[j]) ** 2 + (ys[i] - ys[j]) ** 2 >= min_distance ** 2 for j in kept):
            kept.append(i)
    kept = np.asarray(kept, np.int64)
    if kept.size == 0:
        return np.zeros((0, 3))
    ky, kx = ys[kept], xs[kept]
    if offset is None:
        ox = oy = np.full(len(kept), 0.5)
    else:
        ox, oy = np.clip(offset[0, ky, kx], 0, 1), np.clip(offset[1, ky, kx], 0, 1)
    return np.c_[(kx + ox) * STRIDE, (ky + oy) * STRIDE, score[kept]].astype(np.float64)


class FeetStream:
    """An endless, reproducible stream of :func:`~treeform.dataset.feet_scenes.feet_scene` scenes.

    Round ``r`` of ``n`` scenes depends only on (seed, r): worker processes compose the same
    scenes as the main process would (:class:`treeform.learn.train._Rounds`).
    """

    def __init__(self, sprites, *, size: tuple = (384, 288), seed: int = 0, photos=(), empty: float = 0.08,
                 renders=(), render_fraction: float = 0.0, behind: float = 0.35, behind_aside: float = 0.1):
        if not sprites:
            raise InputError("sprites: expected at least one tree sprite")
        self.sprites, self.size, self.seed, self.photos, self.empty = list(sprites), tuple(size), int(seed), list(photos), empty
        self.renders, self.render_fraction = list(renders), float(render_fraction)
        self.behind, self.behind_aside = float(behind), float(behind_aside)

    def chunk(self, r: int, n: int) -> tuple:
        """Round ``r``: images (n, H, W, 3) uint8, and per scene the feet (k, 2) and visibility (k,)."""
        from treeform.dataset.feet_scenes import feet_scene

        W, H = self.size
        images = np.zeros((n, H, W, 3), np.uint8)
        feet, vis = [], []
        for i in range(n):
            rng = np.random.default_rng([self.seed, 31, int(r), i])
            sc = feet_scene(self.sprites, rng, size=self.size, photos=self.photos, empty=self.empty,
                            renders=self.renders, render_fraction=self.render_fraction, behind=self.behind,
                            behind_aside=self.behind_aside)
            images[i] = sc["image"]
            feet.append(sc["feet"])
            vis.append(sc["visible"])
        return images, feet, vis


def feet_test_scenes(sprites, *, n: int = 200, size: tuple = (384, 288), seed: int = 12345, photos=()) -> tuple:
    """The fixed test split of the foot detector: ``n`` scenes of held-out sprites (another seed)."""
    return FeetStream(sprites, size=size, seed=seed, photos=photos).chunk(0, n)


def score_feet(found: list, truth: list, visible: list, *, tolerance: float) -> dict:
    """Recall (of the visible feet), precision and median error of found feet against the truth.

    ``found[i]`` (k, >=2) and ``truth[i]`` (m, 2) are the feet of scene ``i`` in pixels; a found
    foot within ``tolerance`` pixels of a true one matches it (Hungarian assignment). A found
    foot matching a hidden true foot counts neither way.
    """
    from scipy.optimize import linear_sum_assignment

    tp = fp = fn = 0
    errs = []
    for f, t, v in zip(found, truth, visible):
        f = np.asarray(f, np.float64).reshape(-1, np.shape(f)[-1] if np.size(f) else 2)[:, :2]
        t = np.asarray(t, np.float64).reshape(-1, 2)
        v = np.asarray(v, bool).reshape(-1)
        matched_f, matched_t = set(), set()
        if len(f) and len(t):
            cost = np.linalg.norm(f[:, None] - t[None], axis=2)
            fi, ti = linear_sum_assignment(cost)
            for a, b in zip(fi, ti):
                if cost[a, b] <= tolerance:
                    matched_f.add(int(a))
                    matched_t.add(int(b))
                    if v[b]:
                        tp += 1
                        errs.append(cost[a, b])
        fn += int(sum(1 for b in range(len(t)) if v[b] and b not in matched_t))
        fp += len(f) - len(matched_f)
    return {"recall": round(tp / max(1, tp + fn), 4), "precision": round(tp / max(1, tp + fp), 4),
            "true_feet": tp + fn, "false_feet": fp, "median_error_px": round(float(np.median(errs)), 3) if errs else None}
