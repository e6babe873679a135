"""Stage 2 of the billboard cloud: straight superpixel edges replaced by curves of the crown's silhouette (seed 000 §6, Fig. 10)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
import scipy.ndimage as ndi

from treeform._shared.checks import check_array, check_positive
from treeform._shared.errors import InputError, NoTreeFoundError
from treeform._shared.rng import as_rng


@dataclass
class Regions:
    """Superpixel regions after straight-edge replacement (seed 000 §6, Fig. 10).

    Attributes
    ----------
    boxes : ndarray, shape (n, 4), int64
        ``(x0, y0, w, h)`` of each region's footprint in image pixels.
    masks : list of ndarray, each shape (h_i, w_i), bool
        Footprint within its box: the region grown by its silhouette curves and the
        overlap, holes filled, restricted to the allowed pixels (the crown by default).
    contours : list of list of ndarray, each shape (k, 2), int32
        Outer contour(s) ``(x, y)`` of each grown region (border pixels, corners of straight
        runs only); filling them and keeping the allowed pixels gives ``masks`` exactly.
    edges : ndarray, shape (e, 5), float64
        Straight edges that were replaced: region index, P = (x, y), Q = (x, y) (pixel
        centres).
    curves : list of ndarray, each shape (m, 2), float64
        The silhouette curve put on each edge, from P to Q.
    straight : int
        Straight edges found (replaced or not, when no silhouette piece fitted).
    side : float
        Superpixel side ``sqrt(crown pixels / n)``, the length unit of the tolerances.
    """

    boxes: np.ndarray
    masks: list
    contours: list
    edges: np.ndarray
    curves: list
    straight: int = 0
    side: float = 1.0

    def __len__(self) -> int:
        return len(self.masks)

    def coverage(self, shape) -> np.ndarray:
        """(H, W) int: how many region footprints cover each pixel."""
        count = np.zeros(shape, np.int32)
        for (x0, y0, w, h), m in zip(self.boxes, self.masks):
            count[y0:y0 + h, x0:x0 + w] += m
        return count


def _dp_indices(c: np.ndarray, eps: float) -> np.ndarray:
    """Indices into the closed contour ``c`` (K, 2) of its Douglas–Peucker vertices, in order."""
    approx = cv2.approxPolyDP(c.reshape(-1, 1, 2).astype(np.int32), eps, True).reshape(-1, 2)
    first = np.flatnonzero((c[:, 0] == approx[0, 0]) & (c[:, 1] == approx[0, 1]))[0]
    rolled = np.roll(c, -first, axis=0)
    idx, start = [], 0
    for p in approx:
        hit = np.flatnonzero((rolled[start:, 0] == p[0]) & (rolled[start:, 1] == p[1]))
        if hit.size == 0:  # pragma: no cover - approxPolyDP keeps the contour's order
            break
        start += int(hit[0])
        idx.append(start)
        start += 1
    return (np.array(idx, np.int64) + first) % len(c)


class _Silhouette:
    """The crown silhouette as a closed curve, with a k-d tree to find pieces by their chord."""

    def __init__(self, points: np.ndarray):
        from scipy.spatial import cKDTree

        self.points = np.asarray(points, np.float64)
        self.z = self.points[:, 0] + 1j * self.points[:, 1]
        steps = np.abs(np.diff(np.append(self.z, self.z[0])))
        self.cum = np.concatenate([[0.0], np.cumsum(steps)])  # arc length up to each point (K + 1)
        self.tree = cKDTree(self.points)

    def fit(self, p: complex, q: complex, outward: complex, *, tol: float, max_arc: float, max_bulge: float,
            rng, starts: int = 96) -> np.ndarray | None:
        """A silhouette piece whose chord matches q - p within ``tol``, placed on p → q.

        The piece is mapped onto the edge by the similarity taking its endpoints to p and
        q (a rotation and scale within ``tol`` of the identity), and accepted only if it
        stays on the ``outward`` side of the edge (never more than half a pixel inward),
        within the edge's span, bulges by 1 .. ``max_bulge`` pixels and is between 1.2 and
        ``max_arc`` times as long as the edge. Candidates are tried in random order.

        Returns
        -------
        ndarray, shape (m, 2), or None
        """
        k = len(self.z)
        v = q - p
        length = abs(v)
        a = rng.choice(k, size=min(k, starts), replace=False)
        d, b = self.tree.query(self.points[a] + [v.real, v.imag], distance_upper_bound=tol)
        ok = np.isfinite(d)
        a, b = a[ok], b[ok]
        if a.size == 0:
            return None
        total = self.cum[-1]
        fwd = (self.cum[b] - self.cum[a]) % total
        bwd = total - fwd
        lo, hi = 1.2 * length, max_arc * length
        use_fwd = (fwd >= lo) & (fwd <= hi) & ((fwd <= bwd) | (bwd < lo) | (bwd > hi))
        use_bwd = ~use_fwd & (bwd >= lo) & (bwd <= hi)
        keep = use_fwd | use_bwd
        if not keep.any():
            return None
        a, b, step = a[keep], b[keep], np.where(use_fwd[keep], 1, -1)
        count = np.where(step > 0, (b - a) % k, (a - b) % k) + 1
        m = int(count.max())
        j = np.arange(m)
        idx = (a[:, None] + step[:, None] * j[None, :]) % k
        valid = j[None, :] < count[:, None]
        chord = self.z[b] - self.z[a]
        w = (self.z[idx] - self.z[a][:, None]) * (v / chord)[:, None] + p
        rel = w - p
        t = (rel * np.conj(v)).real / length
        n = (rel * np.conj(outward)).real
        n_min = np.where(valid, n, np.inf).min(1)
        n_max = np.where(valid, n, -np.inf).max(1)
        t_ok = np.where(valid, (t >= -tol) & (t <= length + tol), True).all(1)
        good = np.flatnonzero((n_min >= -0.5) & (n_max >= 1.0) & (n_max <= max_bulge) & t_ok)
        if good.size == 0:
            return None
        i = good[0]
        piece = w[i, :count[i]]
        return np.stack([piece.real, piece.imag], axis=1)


def _between_superpixels(labels: np.ndarray) -> np.ndarray:
    """(H, W) bool: superpixel pixels with a 4-neighbour in another superpixel."""
    pad = np.pad(labels, 1)
    inner = np.zeros(labels.shape, bool)
    h, w = labels.shape
    for dy, dx in ((0, 1), (0, -1), (1, 0), (-1, 0)):
        nb = pad[1 + dy:1 + dy + h, 1 + dx:1 + dx + w]
        inner |= (nb != labels) & (nb > 0)
    return inner & (labels > 0)


def replace_straight_edges(labels, crown, *, within=None, overlap: int = 2, silhouette=None,
                           straightness: float = 0.05, min_edge: float = 0.3, endpoint_tolerance: float = 0.1,
                           max_bulge: float = 0.5, max_arc: float = 4.0, seed=0) -> Regions:
    """Replace straight superpixel edges by curves from the crown silhouette (seed 000 §6, Fig. 10).

    Each region's outer contour is simplified (Douglas–Peucker, tolerance
    ``straightness`` superpixel sides, at least one pixel); a simplified segment at least
    ``min_edge`` sides long whose pixels lie between two superpixels (not on the crown
    silhouette) is a straight edge P → Q. It is replaced by a piece of the silhouette
    whose endpoints have the same relative position as P and Q up to
    ``endpoint_tolerance`` times the edge length (the paper's first constraint), mapped
    exactly onto P and Q and lying wholly on the outer side of the edge (the second: the
    curve never crosses the straight line, so the region only grows and every crown pixel
    stays in at least one region). The area between edge and curve joins the region.
    Finally each region grows by ``overlap`` pixels (beyond the paper), so that
    neighbouring billboards overlap and minified views show no cracks between them.

    Parameters
    ----------
    labels : ndarray, shape (H, W), int
        Superpixels 1 .. n, 0 outside the crown (:func:`superpixels`).
    crown : ndarray, shape (H, W), bool
    within : ndarray, shape (H, W), bool, optional
        Pixels a region's footprint may cover (default ``crown``; e.g. crown and trunk).
    overlap : int
        Dilation (3 x 3, pixels) of every grown region.
    silhouette : ndarray, shape (K, 2), optional
        Closed curve ``(x, y)`` the pieces come from (default: the longest exterior
        contour of ``crown``).
    straightness, min_edge, max_bulge : float
        In superpixel sides ``sqrt(crown pixels / n)``: DP tolerance, shortest straight
        edge, largest distance of a curve from its edge.
    endpoint_tolerance : float
        Endpoint mismatch allowed, as a fraction of the edge length (at least 1.5 px).
    max_arc : float
        Longest silhouette piece, in edge lengths.
    seed : int or Generator
        Which of the fitting silhouette pieces is used.

    Returns
    -------
    Regions
        Region ``i`` is superpixel ``i + 1``.

    Examples
    --------
    >>> m = np.zeros((40, 40), bool); m[4:36, 4:36] = True
    >>> lab = np.where(m, 1 + (np.arange(40)[None, :] >= 20), 0)
    >>> reg = replace_straight_edges(lab, m)
    >>> len(reg), bool((reg.coverage(m.shape)[m] >= 1).all())
    (2, True)
    """
    from treeform.contour import longest_exterior_contour, signed_area

    labels = check_array(labels, "labels", ndim=2, dtype_kind="iu").astype(np.int32)
    crown = check_array(crown, "crown", ndim=2).astype(bool)
    if crown.shape != labels.shape:
        raise InputError(f"crown: expected shape {labels.shape} to match labels, got {crown.shape}")
    if ((labels > 0) != crown).any():
        raise InputError("labels: must be > 0 exactly on the crown pixels")
    within = crown if within is None else check_array(within, "within", shape=crown.shape).astype(bool)
    if isinstance(overlap, bool) or not isinstance(overlap, (int, np.integer)) or overlap < 0:
        raise InputError(f"overlap: expected a non-negative integer, got {overlap!r}")
    for name, val in (("straightness", straightness), ("min_edge", min_edge),
                      ("endpoint_tolerance", endpoint_tolerance), ("max_bulge", max_bulge)):
        check_positive(val, name)
    if check_positive(max_arc, "max_arc") <= 1.2:
        raise InputError(f"max_arc: expected a number > 1.2, got {max_arc!r}")
    n = int(labels.max())
    if n == 0:
        raise NoTreeFoundError("labels: no superpixels")
    rng = as_rng(seed)
    sil = _Silhouette(longest_exterior_contour(crown) if silhouette is None
                      else check_array(silhouette, "silhouette", shape=(None, 2), dtype_kind="iuf"))
    side = math.sqrt(crown.sum() / n)
    eps = max(1.0, straightness * side)
    min_len = max(3.0, min_edge * side)
    bulge = max(2.0, max_bulge * side)
    pad = int(math.ceil(bulge)) + 2 + int(overlap)
    inner = _between_superpixels(labels)
    hh, ww = labels.shape
    boxes, masks, contours, edges, curves = [], [], [], [], []
    straight = 0
    objects = ndi.find_objects(labels)
    if any(sl is None for sl in objects):
        raise InputError("labels: expected consecutive superpixel labels 1 .. n")
    for r, sl in enumerate(objects):
        ya, yb = max(0, sl[0].start - pad), min(hh, sl[0].stop + pad)
        xa, xb = max(0, sl[1].start - pad), min(ww, sl[1].stop + pad)
        canvas = (labels[ya:yb, xa:xb] == r + 1).astype(np.uint8)
        found, _ = cv2.findContours(canvas, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
        bulges = []
        for c in found:
            c = c.reshape(-1, 2)
            if len(c) < 8:
                continue
            orient = 1.0 if signed_area(c) > 0 else -1.0
            idx = _dp_indices(c, eps)
            for i, j in zip(idx, np.roll(idx, -1)):
                span = c[np.arange(i, i + (j - i) % len(c) + 1) % len(c)]
                p = complex(span[0, 0] + xa, span[0, 1] + ya)
                q = complex(span[-1, 0] + xa, span[-1, 1] + ya)
                length = abs(q - p)
                if length < min_len or inner[span[:, 1] + ya, span[:, 0] + xa].mean() < 0.8:
                    continue
                straight += 1
                d = (q - p) / length
                outward = orient * complex(d.imag, -d.real)  # positive area: interior toward (-dy, dx)
                curve = sil.fit(p, q, outward, tol=max(1.5, endpoint_tolerance * length), max_arc=max_arc,
                                max_bulge=bulge, rng=rng)
                if curve is None:
                    continue
                edges.append((r, p.real, p.imag, q.real, q.imag))
                curves.append(curve)
                bulges.append(curve - [xa, ya])
        if bulges:
            polys = [np.rint(b * 16).astype(np.int32).reshape(-1, 1, 2) for b in bulges]
            cv2.fillPoly(canvas, polys, 1, lineType=cv2.LINE_8, shift=4)
        if overlap:
            canvas = cv2.dilate(canvas, np.ones((3, 3), np.uint8), iterations=int(overlap))
        outline, _ = cv2.findContours(canvas, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_SIMPLE)
        filled = np.zeros_like(canvas)
        cv2.drawContours(filled, outline, -1, 1, thickness=cv2.FILLED)
        foot = filled.astype(bool) & within[ya:yb, xa:xb]
        ys, xs = np.nonzero(foot)
        y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
        boxes.append((xa + x0, ya + y0, x1 - x0, y1 - y0))
        masks.append(foot[y0:y1, x0:x1])
        contours.append([o.reshape(-1, 2) + np.array([xa, ya], np.int32) for o in outline])
    return Regions(np.array(boxes, np.int64).reshape(-1, 4), masks, contours,
                   np.array(edges, np.float64).reshape(-1, 5), curves, straight, side)
