"""Billboard clouds from one tree picture (seed 000 §6, Figs. 9–11).

The stages are functions over arrays in image pixels — ``x`` = column, ``y`` = row (down),
pixel ``(j, i)`` covering ``[j, j + 1) x [i, i + 1)`` — and depth ``z`` in pixels toward
the viewer:

1. :func:`superpixels` — SLIC superpixels of the crown (n = 256, compactness 0.35);
2. :func:`replace_straight_edges` — every straight superpixel edge is replaced by a curve
   taken from the crown silhouette, whose endpoints match the edge's within a tolerance and
   which never crosses the edge inward, so regions only grow (Fig. 10);
3. :func:`build_atlas` — the RGBA crops of all regions (and of the trunk) in one texture;
4. :func:`place_billboards` — a front layer at the regions' own image positions with
   depths from the envelope's biharmonic height field, darker-than-average regions pushed
   deeper; a rear layer with horizontally mirrored positions (textures not mirrored);
   extra billboards at blue-noise positions inside the crown volume, darkened with depth;
   the trunk as one billboard;
5. :func:`cloud_mesh` — one alpha-tested (MASK), double-sided quad per billboard.

Every vertex lies on the ray of the reference camera (:class:`CloudFrame`) through its
image point, so the front view reproduces the picture's pixel grid exactly whatever the
billboards' depths and yaw angles; rear and interior billboards are kept behind the front
layer at each of their pixels and inside the tree's alpha (up to ``max_leak``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import cv2
import numpy as np
import scipy.ndimage as ndi

from treeform._shared.checks import check_array, check_positive
from treeform._shared.errors import InputError, NoTreeFoundError
from treeform._shared.rng import as_rng
from treeform.structures.camera import Camera
from treeform.structures.mesh import Material, Mesh, MeshPart

__all__ = ["FRONT", "REAR", "INTERIOR", "TRUNK", "Regions", "Placement", "CloudFrame", "superpixels",
           "replace_straight_edges", "build_atlas", "place_billboards", "cloud_mesh", "luminance"]

FRONT, REAR, INTERIOR, TRUNK = 0, 1, 2, 3
"""Billboard layers of :attr:`Placement.layer`."""

_FOUR = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], bool)


# --------------------------------------------------------------------------- superpixels


def superpixels(rgb, mask, *, n_segments: int = 256, compactness: float = 0.35, max_side: int = 512) -> np.ndarray:
    """SLIC superpixels of the crown (seed 000 §6, [ASS*12], Fig. 9).

    SLIC runs on the colours in [0, 1] (no Lab conversion: the paper's compactness 0.35
    is on that scale) of the crown's bounding box, reduced so that its longer side is at
    most ``max_side``; the labels are scaled back (nearest) and every crown pixel the
    reduced mask missed takes the label of its nearest labelled pixel. Superpixels are
    then split into 8-connected pieces (a superpixel's box never spans a gap of the
    crown); pieces under a tenth of the mean superpixel area join the nearest large piece
    within half a superpixel side, farther crumbs stay on their own.

    Parameters
    ----------
    rgb : ndarray, shape (H, W, 3), uint8
    mask : ndarray, shape (H, W), bool
        Crown pixels (the superpixels partition exactly these).
    n_segments : int
        Approximate number of superpixels (paper: 256).
    compactness : float
        SLIC compactness (paper: 0.35; lower gives more fractal, less even regions).
    max_side : int
        Longest side SLIC runs at (speed; 512 keeps a 1024² tree well under a second).

    Returns
    -------
    ndarray, shape (H, W), int32
        0 outside ``mask``; 8-connected superpixels labelled 1 .. n consecutively.

    Examples
    --------
    >>> m = np.zeros((64, 64), bool); m[8:56, 8:56] = True
    >>> rgb = np.zeros((64, 64, 3), np.uint8); rgb[:, 32:] = 200
    >>> lab = superpixels(rgb, m, n_segments=8)
    >>> bool((lab[m] > 0).all() and (lab[~m] == 0).all()), int(lab.max()) >= 4
    (True, True)
    """
    from skimage.segmentation import slic

    rgb = check_array(rgb, "rgb", ndim=3, dtype_kind="u")
    mask = check_array(mask, "mask", ndim=2).astype(bool)
    if rgb.shape[:2] != mask.shape or rgb.shape[2] != 3:
        raise InputError(f"rgb: expected shape {mask.shape + (3,)} to match the mask, got {rgb.shape}")
    if isinstance(n_segments, bool) or not isinstance(n_segments, (int, np.integer)) or n_segments < 1:
        raise InputError(f"n_segments: expected a positive integer, got {n_segments!r}")
    compactness = check_positive(compactness, "compactness")
    if isinstance(max_side, bool) or not isinstance(max_side, (int, np.integer)) or max_side < 16:
        raise InputError(f"max_side: expected an integer >= 16, got {max_side!r}")
    if not mask.any():
        raise NoTreeFoundError("mask: no crown pixels to segment into superpixels")
    ys, xs = np.nonzero(mask)
    y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
    crop_rgb, crop_mask = rgb[y0:y1, x0:x1], mask[y0:y1, x0:x1]
    h, w = crop_mask.shape
    scale = min(1.0, max_side / max(h, w))
    if scale < 1.0:
        size = (max(1, round(w * scale)), max(1, round(h * scale)))
        small_rgb = cv2.resize(crop_rgb, size, interpolation=cv2.INTER_AREA)
        small_mask = cv2.resize(crop_mask.astype(np.float32), size, interpolation=cv2.INTER_AREA) >= 0.5
        if not small_mask.any():
            small_mask = cv2.resize(crop_mask.astype(np.uint8), size, interpolation=cv2.INTER_NEAREST) > 0
    else:
        small_rgb, small_mask = crop_rgb, crop_mask
    if small_mask.any():
        lab = slic(small_rgb.astype(np.float32) / 255.0, n_segments=int(n_segments), compactness=compactness,
                   mask=small_mask, start_label=1, convert2lab=False, channel_axis=-1)
    else:  # a crown thinner than one reduced pixel everywhere: one region
        lab = np.ones(small_mask.shape, np.int64)
    if scale < 1.0:
        lab = cv2.resize(lab.astype(np.int32), (w, h), interpolation=cv2.INTER_NEAREST)
    lab = np.where(crop_mask, lab, 0)
    missing = crop_mask & (lab == 0)
    if missing.any():
        _, (ni, nj) = ndi.distance_transform_edt(lab == 0, return_indices=True)
        lab[missing] = lab[ni[missing], nj[missing]]
    lab = _connected(lab, crop_mask.sum() / max(int(lab.max()), 1))
    used = np.unique(lab[crop_mask])
    lut = np.zeros(int(used.max()) + 1, np.int32)
    lut[used] = np.arange(1, used.size + 1)  # consecutive 1 .. n
    out = np.zeros(mask.shape, np.int32)
    out[y0:y1, x0:x1] = lut[lab]
    return out


def _connected(lab: np.ndarray, mean_area: float) -> np.ndarray:
    """Split labels into 8-connected pieces; small pieces join a near large one.

    A piece smaller than a tenth of ``mean_area`` takes, pixel by pixel, the label of the
    nearest pixel of a large piece when that is at most half a superpixel side away;
    farther crumbs (a detached twig) stay superpixels of their own, so that no superpixel's
    box spans a gap of the crown.
    """
    from skimage.measure import label

    pieces = label(lab, background=0, connectivity=2)
    sizes = np.bincount(pieces.ravel())
    small = sizes < 0.1 * mean_area
    small[0] = False
    crumbs = small[pieces]
    large = (pieces > 0) & ~crumbs
    if crumbs.any() and large.any():
        dist, (ni, nj) = ndi.distance_transform_edt(~large, return_indices=True)
        near = crumbs & (dist <= 0.5 * math.sqrt(mean_area))
        pieces[near] = pieces[ni[near], nj[near]]
    return pieces


# --------------------------------------------------------------------------- edge replacement


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


# --------------------------------------------------------------------------- atlas


def build_atlas(rgba, boxes, masks, *, gutter: int = 2) -> tuple[np.ndarray, np.ndarray]:
    """Pack the RGBA crops of all billboards into one texture atlas (shelf packing).

    Crops are placed tallest first, left to right in shelves, ``gutter`` transparent
    texels apart. A crop's alpha is 255 on its mask and 0 elsewhere (binary, for alpha
    testing: a bilinear sample less than half a texel off still lands on the right side
    of the 0.5 cutoff); its colour is the picture's (transparent pixels take their
    nearest tree pixel's colour, so filtering and mipmaps bring no dark fringes).

    Parameters
    ----------
    rgba : ndarray, shape (H, W, 4), uint8
        The tree picture (straight alpha).
    boxes : ndarray, shape (n, 4), int
        ``(x0, y0, w, h)`` crops.
    masks : sequence of ndarray, each shape (h_i, w_i), bool
    gutter : int

    Returns
    -------
    atlas : ndarray, shape (Ha, Wa, 4), uint8
        Sides are multiples of 4.
    rects : ndarray, shape (n, 4), int64
        ``(u0, v0, w, h)`` texel rectangle of each crop.

    Examples
    --------
    >>> img = np.full((8, 8, 4), 255, np.uint8)
    >>> boxes = np.array([[0, 0, 4, 4], [4, 4, 2, 3]])
    >>> atlas, rects = build_atlas(img, boxes, [np.ones((4, 4), bool), np.ones((3, 2), bool)])
    >>> atlas.shape, rects.tolist()
    ((16, 8, 4), [[2, 2, 4, 4], [2, 8, 2, 3]])
    """
    rgba = check_array(rgba, "rgba", ndim=3, dtype_kind="u")
    if rgba.shape[2] != 4:
        raise InputError(f"rgba: expected an (H, W, 4) image, got shape {rgba.shape}")
    boxes = check_array(boxes, "boxes", shape=(None, 4), dtype_kind="iu").astype(np.int64)
    if len(masks) != len(boxes) or len(boxes) == 0:
        raise InputError(f"masks: expected one mask per box ({len(boxes)}, at least one), got {len(masks)}")
    g = int(gutter)
    opaque = rgba[..., 3] > 0
    rgb = rgba[..., :3]
    if opaque.any() and not opaque.all():
        _, (ni, nj) = ndi.distance_transform_edt(~opaque, return_indices=True)
        rgb = rgb[ni, nj]
    widths, heights = boxes[:, 2] + g, boxes[:, 3] + g
    atlas_w = int(max(widths.max() + g, math.ceil(math.sqrt(1.1 * float((widths * heights).sum())))))
    atlas_w += -atlas_w % 4
    order = np.lexsort((np.arange(len(boxes)), -heights))
    rects = np.zeros((len(boxes), 4), np.int64)
    u, v, shelf = g, g, 0
    for i in order:
        if u + widths[i] > atlas_w:
            u, v, shelf = g, v + shelf, 0
        rects[i] = (u, v, boxes[i, 2], boxes[i, 3])
        u += widths[i]
        shelf = max(shelf, heights[i])
    atlas_h = v + shelf
    atlas_h += -atlas_h % 4
    atlas = np.zeros((atlas_h, atlas_w, 4), np.uint8)
    for (x0, y0, w, h), (u0, v0, _, _), m in zip(boxes, rects, masks):
        m = np.asarray(m, bool)
        if m.shape != (h, w):
            raise InputError(f"masks: expected a ({h}, {w}) mask for box {(x0, y0, w, h)}, got {m.shape}")
        tile = atlas[v0:v0 + h, u0:u0 + w]
        tile[..., :3] = rgb[y0:y0 + h, x0:x0 + w]
        tile[..., 3] = np.where(m, 255, 0)
    return atlas, rects


def luminance(rgba, boxes, masks) -> np.ndarray:
    """Mean luma (Rec. 709 weights on the sRGB values, in [0, 1]) of each crop's mask pixels.

    Returns
    -------
    ndarray, shape (n,)
    """
    luma = np.asarray(rgba)[..., :3].astype(np.float32) @ np.array([0.2126, 0.7152, 0.0722], np.float32) / 255.0
    return np.array([luma[y0:y0 + h, x0:x0 + w][m].mean() if m.any() else 0.0
                     for (x0, y0, w, h), m in zip(boxes, masks)])


# --------------------------------------------------------------------------- placement


@dataclass
class Placement:
    """Where each billboard goes, in image pixels (seed 000 §6).

    Attributes
    ----------
    sprite : ndarray, shape (m,), int64
        Index of the billboard's crop (row of the atlas ``rects`` / ``boxes``).
    layer : ndarray, shape (m,), int8
        :data:`FRONT`, :data:`REAR`, :data:`INTERIOR` or :data:`TRUNK`.
    x, y : ndarray, shape (m,), float64
        Image-plane centre of the billboard (pixels; a front billboard's own box centre).
    z : ndarray, shape (m,), float64
        Depth of the centre toward the viewer (pixels; 0 = the picture plane).
    yaw : ndarray, shape (m,), float64
        Rotation about the vertical axis (radians); the depth across the billboard is
        ``z + (x' - x) tan(yaw)`` at image column ``x'``.
    shade : ndarray, shape (m,), float64
        Colour factor (1 = the picture's colour; interior billboards are darker).
    """

    sprite: np.ndarray
    layer: np.ndarray
    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    yaw: np.ndarray
    shade: np.ndarray

    def __len__(self) -> int:
        return len(self.sprite)

    def counts(self) -> dict:
        """Billboards per layer, e.g. ``{"front": 240, "rear": 231, ...}``."""
        names = ("front", "rear", "interior", "trunk")
        return {name: int((self.layer == k).sum()) for k, name in enumerate(names)}


@dataclass
class _Footprints:
    """Opaque pixels of each crop and the tree's coverage, for leak and depth tests."""

    boxes: np.ndarray
    masks: list
    tree: np.ndarray
    zbuf: np.ndarray = field(init=False)

    def __post_init__(self):
        self.zbuf = np.full(self.tree.shape, -np.inf)

    def window(self, s: int, ox: int, oy: int):
        """(mask part inside the image, image slices) of crop ``s`` with its top-left at (ox, oy)."""
        w, h = self.boxes[s, 2], self.boxes[s, 3]
        hh, ww = self.tree.shape
        xa, ya, xb, yb = max(ox, 0), max(oy, 0), min(ox + w, ww), min(oy + h, hh)
        if xa >= xb or ya >= yb:
            return None, None
        return self.masks[s][ya - oy:yb - oy, xa - ox:xb - ox], (slice(ya, yb), slice(xa, xb))

    def leak(self, s: int, ox: int, oy: int) -> float:
        """Fraction of crop ``s``'s opaque pixels falling outside the tree (or the image)."""
        m, win = self.window(s, ox, oy)
        total = self.masks[s].sum()
        inside = 0 if m is None else int((m & self.tree[win]).sum())
        return 1.0 - inside / max(total, 1)

    def paint(self, s: int, ox: int, oy: int, xc: float, z: float, yaw: float) -> None:
        """Record crop ``s`` (a front billboard) in the front depth buffer."""
        m, win = self.window(s, ox, oy)
        if m is None:
            return
        depth = z + _tilt(win, xc, yaw)[None, :]
        self.zbuf[win] = np.where(m, np.maximum(self.zbuf[win], depth), self.zbuf[win])

    def deepest(self, s: int, ox: int, oy: int, xc: float, yaw: float, gap: float) -> float:
        """Largest centre depth that keeps crop ``s`` ``gap`` behind the front layer at all its pixels."""
        m, win = self.window(s, ox, oy)
        if m is None:
            return np.inf
        front = self.zbuf[win]
        sel = m & np.isfinite(front)
        if not sel.any():
            return np.inf
        offs = np.broadcast_to(_tilt(win, xc, yaw)[None, :], m.shape)
        return float((front[sel] - offs[sel]).min() - gap)


def _tilt(win, xc: float, yaw: float) -> np.ndarray:
    """Depth offset, relative to the centre, of a billboard turned by ``yaw`` at the window's columns."""
    cols = np.arange(win[1].start, win[1].stop) + 0.5
    return (cols - xc) * math.tan(yaw)


def place_billboards(boxes, masks, luminance, height, tree, *, crown=None, trunk: int | None = None,
                     push: float = 0.5, interior: float = 0.5, darken: float = 0.5, yaw=(20.0, 50.0),
                     max_leak: float = 0.02, seed=0) -> Placement:
    """Populate the crown with billboards (seed 000 §6).

    * **Front layer** — every region at its own image position; depth = the envelope's
      height ``height`` at the region's centroid, minus ``push`` times the largest height
      scaled by how much darker than the mean luminance the region is (dark regions are
      read as occluded and sent into the crown, leaving cavities to see deeper layers).
    * **Rear layer** — every region again, its position mirrored within its row's crown
      span (textures are not mirrored), at the mirrored depth; moved toward the row's
      centre in quarter-widths until at most ``max_leak`` of its pixels fall outside the
      tree (else dropped).
    * **Interior** — ``interior`` × n extra billboards at blue-noise positions inside the
      crown volume ``|z| < height(x, y)``, each a random region that fits inside the tree
      (4 tries), darkened by ``1 - darken·(1 - |z| / height)``.
    * **Trunk** — crop ``trunk`` at its image position, depth 0, turned 45°.

    Every billboard gets a random yaw of ``±U(yaw)`` degrees; rear and interior ones are
    kept at least a pixel behind the front layer (and the trunk) at each of their pixels,
    so the front view is the picture.

    Parameters
    ----------
    boxes : ndarray, shape (n, 4), int
        ``(x0, y0, w, h)`` crop boxes (regions, then the trunk crop if any).
    masks : sequence of ndarray, each shape (h_i, w_i), bool
        Opaque pixels of each crop.
    luminance : ndarray, shape (n,)
        Mean luminance of each crop (:func:`luminance`).
    height : ndarray, shape (H, W), float
        Front height of the crown envelope in pixels (0 outside;
        :func:`treeform.crown.inflate_envelope`'s ``front_z``).
    tree : ndarray, shape (H, W), bool
        The picture's opaque pixels (crown and trunk).
    crown : ndarray, shape (H, W), bool, optional
        Crown pixels, whose filled row spans mirror the rear layer (default ``height > 0``).
    trunk : int, optional
        Index of the trunk crop in ``boxes``.
    push, interior, darken : float
        Depth push of the darkest region (fraction of the largest height), extra
        billboards per region, darkening at the crown's centre plane.
    yaw : (float, float)
        Range of the absolute yaw angle in degrees (0 ≤ low ≤ high < 80).
    max_leak : float
        Largest fraction of a rear or interior billboard's pixels allowed outside the tree.
    seed : int or Generator

    Returns
    -------
    Placement
        Front billboards first (in region order), then trunk, rear and interior ones.
    """
    from treeform.growth.sampling import blue_noise_points

    boxes = check_array(boxes, "boxes", shape=(None, 4), dtype_kind="iu").astype(np.int64)
    n = len(boxes)
    lum = check_array(luminance, "luminance", shape=(n,), dtype_kind="iuf").astype(np.float64)
    height = check_array(height, "height", ndim=2, dtype_kind="iuf").astype(np.float64)
    tree = check_array(tree, "tree", shape=height.shape).astype(bool)
    if len(masks) != n or n == 0:
        raise InputError(f"masks: expected one mask per box ({n}, at least one), got {len(masks)}")
    lo, hi = (float(a) for a in yaw)
    if not 0 <= lo <= hi < 80:
        raise InputError(f"yaw: expected (low, high) degrees with 0 <= low <= high < 80, got {yaw!r}")
    for name, val in (("push", push), ("interior", interior), ("darken", darken), ("max_leak", max_leak)):
        check_positive(val, name, allow_zero=True)
    if trunk is not None and not 0 <= trunk < n:
        raise InputError(f"trunk: expected an index in [0, {n}), got {trunk!r}")
    rng = as_rng(seed)
    crown = height > 0 if crown is None else check_array(crown, "crown", shape=height.shape).astype(bool)
    filled = ndi.binary_fill_holes(crown)
    hh, ww = height.shape
    fp = _Footprints(boxes, [np.asarray(m, bool) for m in masks], tree)
    regions = [i for i in range(n) if i != trunk]
    h_max = float(height.max())
    gap = 1.0

    def random_yaw(k):
        return np.radians(rng.uniform(lo, hi, k) * rng.choice([-1.0, 1.0], k))

    out = []  # (sprite, layer, x, y, z, yaw, shade) per billboard
    # front layer: own position, envelope depth, darker than average -> deeper
    reg = np.array(regions, np.int64)
    cx = boxes[reg, 0] + boxes[reg, 2] / 2.0
    cy = boxes[reg, 1] + boxes[reg, 3] / 2.0
    cent = np.array([_centroid(boxes[i], fp.masks[i]) for i in reg]).reshape(-1, 2)
    base = height[cent[:, 1], cent[:, 0]]
    mean = lum[reg].mean() if reg.size else 0.0
    dark = np.clip(mean - lum[reg], 0.0, None)
    dark = dark / dark.max() if dark.size and dark.max() > 0 else dark
    z_front = np.maximum(base - push * h_max * dark, 0.0)
    a_front = random_yaw(len(reg))
    for k, i in enumerate(reg):
        out.append((i, FRONT, cx[k], cy[k], z_front[k], a_front[k], 1.0))
        fp.paint(i, boxes[i, 0], boxes[i, 1], cx[k], z_front[k], a_front[k])
    if trunk is not None:
        tx, ty = boxes[trunk, 0] + boxes[trunk, 2] / 2.0, boxes[trunk, 1] + boxes[trunk, 3] / 2.0
        out.append((trunk, TRUNK, tx, ty, 0.0, math.radians(45.0), 1.0))
        fp.paint(trunk, boxes[trunk, 0], boxes[trunk, 1], tx, 0.0, math.radians(45.0))

    # rear layer: positions mirrored within the crown's row span, textures as they are
    rows = np.nonzero(filled.any(1))[0]
    left = np.where(filled.any(1), filled.argmax(1), 0)
    right = np.where(filled.any(1), ww - filled[:, ::-1].argmax(1), ww)
    a_rear = random_yaw(len(reg))
    for k, i in enumerate(reg):
        r = int(np.clip(round(cy[k] - 0.5), rows.min(), rows.max())) if rows.size else 0
        mid = (left[r] + right[r]) / 2.0
        w, h = boxes[i, 2], boxes[i, 3]
        oy = boxes[i, 1]
        x_mir = left[r] + right[r] - cx[k]
        towards = 1.0 if mid >= x_mir else -1.0
        for step in range(5):
            x = x_mir + towards * step * w / 4.0
            if step and (x - mid) * (x_mir - mid) < 0:  # moved past the centre: give up
                break
            ox = int(round(x - w / 2.0))
            if fp.leak(i, ox, oy) <= max_leak:
                xc = ox + w / 2.0
                col = int(np.clip(math.floor(xc), 0, ww - 1))
                want = -max(height[cent[k, 1], col] - push * h_max * dark[k], 0.0) - gap
                z = min(want, fp.deepest(i, ox, oy, xc, a_rear[k], gap))
                out.append((i, REAR, xc, oy + h / 2.0, z, a_rear[k], 1.0))
                break

    # interior: blue-noise points in |z| < height, random regions that fit, darker inside
    m_extra = int(round(interior * len(reg)))
    if m_extra and h_max > 0 and reg.size:
        py, px = np.nonzero(height > 0)
        lo3 = np.array([px.min(), py.min(), -h_max], np.float64)
        hi3 = np.array([px.max() + 1.0, py.max() + 1.0, h_max])

        def inside(p):
            j = np.clip(np.floor(p[:, 0]).astype(np.int64), 0, ww - 1)
            i = np.clip(np.floor(p[:, 1]).astype(np.int64), 0, hh - 1)
            return np.abs(p[:, 2]) < height[i, j]

        pts = blue_noise_points(inside, (lo3, hi3), m_extra, seed=rng)
        picks = rng.choice(reg, size=(len(pts), 4))
        a_int = random_yaw(len(pts))
        for p, cand, a in zip(pts, picks, a_int):
            for i in cand:
                w, h = boxes[i, 2], boxes[i, 3]
                ox, oy = int(round(p[0] - w / 2.0)), int(round(p[1] - h / 2.0))
                if fp.leak(i, ox, oy) > max_leak:
                    continue
                xc, yc = ox + w / 2.0, oy + h / 2.0
                z = min(float(p[2]), fp.deepest(i, ox, oy, xc, a, gap))
                hz = height[int(np.clip(math.floor(p[1]), 0, hh - 1)), int(np.clip(math.floor(p[0]), 0, ww - 1))]
                inner = 1.0 - min(abs(z) / hz, 1.0) if hz > 0 else 0.0
                out.append((int(i), INTERIOR, xc, yc, z, a, 1.0 - darken * inner))
                break
    cols = list(zip(*out))
    return Placement(np.array(cols[0], np.int64), np.array(cols[1], np.int8),
                     *(np.array(c, np.float64) for c in cols[2:]))


def _centroid(box, mask) -> tuple[int, int]:
    """Pixel (column, row) nearest the centroid of a crop's mask, in image coordinates."""
    ys, xs = np.nonzero(mask)
    if ys.size == 0:
        return int(box[0]), int(box[1])
    k = int(np.argmin((xs - xs.mean()) ** 2 + (ys - ys.mean()) ** 2))  # a mask pixel, even for a crescent
    return int(box[0] + xs[k]), int(box[1] + ys[k])


# --------------------------------------------------------------------------- frame and mesh


@dataclass(frozen=True)
class CloudFrame:
    """Image pixels → world metres, and the reference (photo) camera of a billboard cloud.

    World: metres, Y up, the tree's base at the origin, the picture plane at z = 0 and the
    camera on +Z at distance ``distance`` looking toward -Z through the picture's centre,
    with the vertical field of view ``fov_y``. A point at image position (x, y) and depth
    z (pixels) is put on that camera's ray through (x, y), so the camera sees it at (x, y).

    Parameters
    ----------
    width, height : int
        Picture size (pixels).
    metres_per_pixel : float
        Size of a pixel on the picture plane.
    origin : (float, float)
        Image position of the tree's base (world origin).
    fov_y : float
        Vertical field of view of the reference camera (degrees).
    """

    width: int
    height: int
    metres_per_pixel: float
    origin: tuple
    fov_y: float = 10.0

    @classmethod
    def for_tree(cls, tree, *, tree_height: float = 10.0, fov_y: float = 10.0) -> "CloudFrame":
        """The frame of a picture whose opaque pixels ``tree`` (H, W) are ``tree_height`` metres tall.

        The origin is the middle of the tree's lowest row of pixels, at its bottom edge.
        """
        tree = check_array(tree, "tree", ndim=2).astype(bool)
        check_positive(tree_height, "tree_height")
        if not 0 < float(fov_y) < 120:
            raise InputError(f"fov_y: expected degrees in (0, 120), got {fov_y!r}")
        rows = np.nonzero(tree.any(1))[0]
        if rows.size == 0:
            raise NoTreeFoundError("tree: no opaque pixels")
        bottom = int(rows.max())
        cols = np.nonzero(tree[bottom])[0]
        s = float(tree_height) / (bottom + 1 - rows.min())
        return cls(tree.shape[1], tree.shape[0], s, ((cols.min() + cols.max() + 1) / 2.0, bottom + 1.0),
                   float(fov_y))

    @property
    def distance(self) -> float:
        """Camera distance to the picture plane (metres)."""
        return self.height * self.metres_per_pixel / (2.0 * math.tan(math.radians(self.fov_y) / 2.0))

    @property
    def centre(self) -> np.ndarray:
        """(3,) world position of the picture's centre (the camera's target)."""
        s = self.metres_per_pixel
        return np.array([(self.width / 2.0 - self.origin[0]) * s, (self.origin[1] - self.height / 2.0) * s, 0.0])

    def to_world(self, x, y, z) -> np.ndarray:
        """Image positions and depths (pixels, arrays of one shape) → (..., 3) world points.

        Examples
        --------
        >>> f = CloudFrame(100, 100, 0.1, (50.0, 100.0))
        >>> cam = f.camera()
        >>> p = f.to_world(np.array([20.5, 70.5]), np.array([10.5, 90.5]), np.array([30.0, -25.0]))
        >>> np.allclose(cam.project(p)[:, :2], [[20.5, 10.5], [70.5, 90.5]])
        True
        """
        s = self.metres_per_pixel
        x, y, z = np.broadcast_arrays(*(np.asarray(a, np.float64) for a in (x, y, z)))
        plane = np.stack([(x - self.origin[0]) * s, (self.origin[1] - y) * s, np.zeros_like(x)], axis=-1)
        eye = self.centre + [0.0, 0.0, self.distance]
        t = (self.distance - z * s) / self.distance
        return eye + (plane - eye) * t[..., None]

    def camera(self, width: int | None = None, height: int | None = None) -> Camera:
        """The reference camera, optionally rendering at another size (same field of view)."""
        w = self.width if width is None else int(width)
        h = self.height if height is None else int(height)
        d = self.distance
        reach = 1.5 * max(self.width, self.height) * self.metres_per_pixel
        centre = self.centre
        return Camera(w, h, self.fov_y, tuple(centre + [0.0, 0.0, d]), tuple(centre),
                      near=max(d - reach, 1e-3 * d), far=d + reach)


def cloud_mesh(placement: Placement, boxes, rects, atlas, frame: CloudFrame, *, name: str = "billboard_cloud",
               tolerance: float = 0.1) -> Mesh:
    """Textured quads, one per billboard, in one part with one MASK material (seed 000 §6).

    Each quad is its crop box centred at the billboard's image position, turned by its
    yaw about the vertical line through its centre, every vertex put on the reference
    camera's ray through its image point (:meth:`CloudFrame.to_world`); UVs are the crop's
    atlas rectangle; vertex colours carry the shade. The material is double-sided,
    alpha-tested at 0.5.

    A turned quad on those rays is a trapezoid, whose triangles map the texture affinely
    where the front view needs a projective map; the texture slips by about
    ``(w/K) max(w/K, h) |tan yaw| s / (4 d)`` pixels in a w x h quad cut into K vertical
    strips (s metres per pixel, d the camera distance). K is the smallest count that
    keeps this within ``tolerance``: 1 or 2 for superpixels, dozens for a wide trunk.

    Parameters
    ----------
    placement : Placement
    boxes : ndarray, shape (n, 4), int
        Crop boxes ``(x0, y0, w, h)`` (their sizes are used).
    rects : ndarray, shape (n, 4), int
        Atlas rectangles ``(u0, v0, w, h)`` (:func:`build_atlas`).
    atlas : ndarray, shape (Ha, Wa, 4), uint8
    frame : CloudFrame
    tolerance : float
        Largest texture slip of the front view, pixels.

    Returns
    -------
    Mesh
        One part: 2 (K + 1) vertices and 2 K triangles per billboard.
    """
    boxes = np.asarray(boxes, np.int64)
    rects = np.asarray(rects, np.int64)
    check_positive(tolerance, "tolerance")
    m = len(placement)
    if m == 0:
        raise InputError("placement: no billboards")
    spr = placement.sprite
    w, h = boxes[spr, 2].astype(np.float64), boxes[spr, 3].astype(np.float64)
    tan = np.tan(placement.yaw)
    c = np.abs(tan) * frame.metres_per_pixel / (4.0 * frame.distance * tolerance)
    k = np.maximum(1, np.ceil(np.maximum(w * np.sqrt(c), w * h * c))).astype(np.int64)
    # vertex columns: billboard b has k[b] + 1 of them, each a top and a bottom vertex
    col_start = np.concatenate([[0], np.cumsum(k + 1)])
    b = np.repeat(np.arange(m), k + 1)
    f = (np.arange(col_start[-1]) - col_start[b]) / k[b]  # 0 .. 1 across the billboard
    dx = (f - 0.5) * w[b]
    x = placement.x[b] + dx
    z = placement.z[b] + dx * tan[b]
    top = frame.to_world(x, placement.y[b] - h[b] / 2.0, z)
    bottom = frame.to_world(x, placement.y[b] + h[b] / 2.0, z)
    pos = np.stack([top, bottom], 1).reshape(-1, 3)  # vertex 2c: top of column c, 2c + 1: its bottom
    ah, aw = atlas.shape[:2]
    u = (rects[spr[b], 0] + f * rects[spr[b], 2]) / aw
    v0 = rects[spr[b], 1] / ah
    v1 = (rects[spr[b], 1] + rects[spr[b], 3]) / ah
    uv = np.stack([np.stack([u, v0], 1), np.stack([u, v1], 1)], 1).reshape(-1, 2)
    first = col_start[:-1]  # the normal of a billboard from its first strip (all strips are coplanar)
    nrm = np.cross(bottom[first] - top[first], top[first + 1] - top[first])
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    col = np.ones((len(b), 4))
    col[:, :3] = placement.shade[b, None]
    c = np.flatnonzero(np.arange(col_start[-1]) + 1 < col_start[b + 1])  # columns with a strip to their right
    tl, bl, tr, br = 2 * c, 2 * c + 1, 2 * c + 2, 2 * c + 3
    idx = np.stack([np.stack([tl, bl, br], 1), np.stack([tl, br, tr], 1)], 1).reshape(-1, 3)
    mat = Material(name=name, texture=atlas, alpha_mode="MASK", alpha_cutoff=0.5, double_sided=True,
                   roughness=1.0, metallic=0.0)
    part = MeshPart(pos, np.repeat(nrm[b], 2, axis=0), uv, np.repeat(col, 2, axis=0), idx, mat, name)
    return Mesh([part])
