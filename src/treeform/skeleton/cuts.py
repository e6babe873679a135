"""Cuts that partition a shape into one area per branch (seed 004 §3.3, §3.5).

A cut is a segment from a starting point ``c`` on the (DCE-simplified) boundary to an ending
point ``e``: on the bottom of the shape for vines (§3.3), on the parent axis (the trunk, or a
first-order branch for the next order) for trees (§3.5). Starting points are drawn one by one
with probability ``rho_k`` (proximity to inward DCE vertices, distance along the boundary to
the starting points already chosen) and accepted by an area-balance test (vines) or an angle
test (trees). Everything here works in working-size pixels ``(x, y)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np
from scipy import ndimage as ndi

from treeform.skeleton.dce import dce, inward_vertices, outer_contour, resample_closed

__all__ = ["Boundary", "boundary_candidates", "start_probability", "select_cuts", "rasterise", "label_areas",
           "point_at_arc", "polyline_arc"]

SIGMA = 0.4
"""Standard deviation of the Gaussians that mix rho1 and rho2 (seed 004 §3.3)."""

CROSS_PENALTY = 10.0
"""Score added to a candidate cut that crosses an earlier cut or the axis (never accepted)."""


@dataclass
class Boundary:
    """A shape's DCE polygon and the candidate starting points on it (working pixels)."""

    polygon: np.ndarray          # (N, 2) DCE vertices
    candidates: np.ndarray       # (K, 2) points along the polygon, snapped onto the true contour
    arc: np.ndarray              # (K,) arc position of each candidate along the polygon
    perimeter: float
    inward: np.ndarray           # (M, 2) inward DCE vertices
    alpha: np.ndarray            # (M,) their opening angles (outside the shape)
    extra: dict = field(default_factory=dict)


def boundary_candidates(mask: np.ndarray, n_dce: int, n_candidates: int) -> Boundary | None:
    """DCE polygon of ``mask``'s outer contour with ``n_dce`` vertices and ``n_candidates`` points on it.

    The points ``c_k`` discretise the polygon uniformly (seed 004 §3.3); each is then moved to
    the nearest pixel of the true contour, so a cut ending there reaches the boundary.
    Returns None when the contour is too short.
    """
    full = outer_contour(mask)
    if len(full) < 8:
        return None
    simple = outer_contour(mask, simple=True)
    if len(simple) < 3:
        simple = full
    poly = simple[dce(simple, max(3, n_dce))]
    pts, arc, per = resample_closed(poly, n_candidates)
    d2 = ((pts[:, None, :] - full[None, :, :]) ** 2).sum(-1)
    snapped = full[np.argmin(d2, axis=1)]
    idx, alpha = inward_vertices(poly)
    return Boundary(poly, snapped, arc, per, poly[idx], alpha)


def _gauss(x: np.ndarray, sigma: float = SIGMA) -> np.ndarray:
    return np.exp(-0.5 * ((x - 1.0) / sigma) ** 2) / (sigma * np.sqrt(2.0 * np.pi))


def start_probability(b: Boundary, chosen: list[int]) -> np.ndarray:
    """Probability ``rho_k`` of each candidate to be the next starting point (seed 004 §3.3).

    ``rho1_k = sum_l (1 / d(c_k, s_l)) (1 - alpha_l / 2 pi)`` over the inward DCE vertices
    ``s_l`` (``d`` clamped below at the candidates' spacing), divided by its maximum so it
    spans [0, 1] with 1 at the strongest notch; ``rho2_k`` = the distance along the polygon to
    the nearest chosen starting point, divided by its maximum (1 = the farthest candidate),
    left out while none is chosen. ``rho_k ∝ phi(rho1_k; 1, sigma) + phi(rho2_k; 1, sigma)``,
    ``sigma = 0.4``; chosen candidates get 0.
    """
    k = len(b.candidates)
    spacing = b.perimeter / max(k, 1)
    rho = np.zeros(k)
    if len(b.inward):
        d = np.sqrt(((b.candidates[:, None, :] - b.inward[None, :, :]) ** 2).sum(-1))
        r1 = ((1.0 / np.maximum(d, spacing)) * (1.0 - b.alpha / (2.0 * np.pi))[None, :]).sum(1)
        r1 = r1 / r1.max()
    else:
        r1 = np.zeros(k)
    rho += _gauss(r1)
    if chosen:
        da = np.abs(b.arc[:, None] - b.arc[np.asarray(chosen)][None, :])
        r2 = np.minimum(da, b.perimeter - da).min(1)
        if r2.max() > 0:
            rho += _gauss(r2 / r2.max())
    rho[np.asarray(chosen, dtype=int)] = 0.0
    s = rho.sum()
    return rho / s if s > 0 else np.full(k, 1.0 / k)


def _crosses(p0: np.ndarray, p1: np.ndarray, segs: np.ndarray) -> bool:
    """Whether segment p0->p1 meets any of ``segs`` (M, 2, 2) away from p0 itself."""
    if len(segs) == 0:
        return False
    d = p1 - p0
    a, e = segs[:, 0], segs[:, 1] - segs[:, 0]
    den = d[0] * e[:, 1] - d[1] * e[:, 0]
    w = a - p0
    ok = np.abs(den) > 1e-12
    den = np.where(ok, den, 1.0)
    t = (w[:, 0] * e[:, 1] - w[:, 1] * e[:, 0]) / den
    u = (w[:, 0] * d[1] - w[:, 1] * d[0]) / den
    return bool(np.any(ok & (t > 1e-3) & (t <= 1.0) & (u >= 0.0) & (u <= 1.0)))


def select_cuts(b: Boundary, ends: np.ndarray, score, *, tol: float, rng: np.random.Generator,
                max_tries: int = 48, blockers: np.ndarray | None = None) -> dict:
    """Choose one starting point per ending point (seed 004 §3.3 algorithm, bounded retries).

    Parameters
    ----------
    b : Boundary
    ends : ndarray, shape (E, 2)
        Ending points ``e_i`` in order (i = 1..E).
    score : callable ``(c (2,), i) -> float``
        Acceptance error of the cut from candidate point ``c`` to ending point ``i`` (0-based):
        the area imbalance of eq. (2) for vines, the angle error for trees.
    tol : float
        A cut is accepted when its score is ``<= tol`` and it crosses no earlier cut or blocker.
    rng : numpy.random.Generator
        Draws the starting points by ``rho`` (:func:`start_probability`).
    max_tries : int
        Draws per cut; after that the best-scoring draw is taken (deterministic given ``rng``).
    blockers : ndarray, shape (M, 2, 2), optional
        Segments a cut must not cross (the axis).

    Returns
    -------
    dict
        ``cuts`` list of (start (2,), end (2,), i) accepted in order, ``chosen`` candidate indices,
        ``tries`` draws per cut, ``accepted`` whether each met the test (else best kept).
    """
    segs = np.zeros((0, 2, 2)) if blockers is None else np.asarray(blockers, float).reshape(-1, 2, 2)
    free = list(range(len(ends)))
    chosen: list[int] = []
    out = {"cuts": [], "chosen": chosen, "tries": [], "accepted": [], "scores": []}
    for _ in range(len(ends)):
        rho = start_probability(b, chosen)
        best = (np.inf, -1, -1)
        tries, ok = 0, False
        for tries in range(1, max_tries + 1):
            k = int(rng.choice(len(rho), p=rho))
            c = b.candidates[k]
            for i in free:
                s = float(score(c, i))
                if _crosses(ends[i], c, segs):
                    s += CROSS_PENALTY
                if s < best[0]:
                    best = (s, k, i)
            if best[0] <= tol:
                ok = True
                break
        s, k, i = best
        if k < 0:
            break
        c, e = b.candidates[k], ends[i]
        chosen.append(k)
        free.remove(i)
        segs = np.concatenate([segs, np.array([[e, c]])], axis=0)
        out["cuts"].append((c.copy(), e.copy(), i))
        out["tries"].append(tries)
        out["accepted"].append(ok)
        out["scores"].append(s)
    return out


def polyline_arc(poly: np.ndarray) -> np.ndarray:
    """Cumulative arc length (K,) of an open (K, 2) polyline."""
    if len(poly) < 2:
        return np.zeros(len(poly))
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(poly, axis=0).T))])


def point_at_arc(poly: np.ndarray, s) -> tuple[np.ndarray, np.ndarray]:
    """Points (…, 2) and unit tangents (…, 2) of an open polyline at arc positions ``s``."""
    cum = polyline_arc(poly)
    s = np.clip(np.asarray(s, float), 0.0, cum[-1])
    x, y = np.interp(s, cum, poly[:, 0]), np.interp(s, cum, poly[:, 1])
    j = np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(poly) - 2)
    t = poly[j + 1] - poly[j]
    t = t / np.maximum(np.linalg.norm(t, axis=-1, keepdims=True), 1e-12)
    return np.stack([x, y], axis=-1), t


def rasterise(shape, cuts, axis: np.ndarray | None = None, *, extend_start: float = 2.0,
              extend_end: float = 0.0) -> np.ndarray:
    """Separator image: the cuts (8-connected, 1 px) and the axis polyline.

    Each cut ``(c, e, i)`` is drawn from ``e`` to ``c``, prolonged ``extend_start`` pixels beyond
    the starting point ``c`` (so it crosses the boundary) and ``extend_end`` beyond ``e``.
    Returns an (h, w) bool image.
    """
    img = np.zeros(shape, np.uint8)
    if axis is not None and len(axis) >= 2:
        pts = np.round(axis * 16).astype(np.int32).reshape(-1, 1, 2)
        cv2.polylines(img, [pts], False, 1, 1, cv2.LINE_8, shift=4)
    for c, e, _ in cuts:
        d = c - e
        n = np.linalg.norm(d)
        if n < 1e-9:
            continue
        u = d / n
        p0, p1 = e - extend_end * u, c + extend_start * u
        cv2.line(img, tuple(np.round(p0 * 16).astype(int).tolist()), tuple(np.round(p1 * 16).astype(int).tolist()),
                 1, 1, cv2.LINE_8, shift=4)
    return img.astype(bool)


def label_areas(mask: np.ndarray, sep: np.ndarray, n_keep: int, *, min_frac: float = 0.01):
    """Areas of ``mask`` minus the separators (4-connected), at most ``n_keep`` of them.

    Components smaller than ``min_frac`` of the mask, or beyond the ``n_keep`` largest, are
    merged into their nearest kept area.

    Returns
    -------
    areas : ndarray, shape (h, w), int32
        Area index of each non-separator pixel of the kept areas, -1 elsewhere.
    filled : ndarray, shape (h, w), int32
        Area index of every mask pixel (separators and merged fragments by nearest area), -1
        outside the mask.
    count : int
    """
    free = (mask & ~sep).astype(np.uint8)
    n, lab = cv2.connectedComponents(free, connectivity=4)
    sizes = np.bincount(lab.ravel(), minlength=n)
    sizes[0] = 0
    order = np.argsort(-sizes, kind="stable")
    minimum = max(3, int(min_frac * mask.sum()))
    keep = [j for j in order[:n_keep] if sizes[j] >= minimum]
    if not keep:
        keep = [int(order[0])] if sizes[order[0]] > 0 else []
    remap = np.full(n, -1, np.int32)
    remap[np.asarray(keep, int)] = np.arange(len(keep), dtype=np.int32)
    areas = remap[lab]
    filled = areas.copy()
    if keep:
        todo = mask & (areas < 0)
        if todo.any():
            _, (iy, ix) = ndi.distance_transform_edt(areas < 0, return_indices=True)
            filled[todo] = areas[iy[todo], ix[todo]]
    filled[~mask] = -1
    return areas, filled, len(keep)
