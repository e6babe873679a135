"""Tree synthesis: contour combination, RGBA colour transfer, histogram transfer (seed 000 §5).

* §5.1 a new contour ``u' = sum_j w_j u_j`` (weights >= 0, summing to 1) and its region
  fill (:func:`treeform.contour.fill_contour`), the preliminary alpha mask;
* §5.2 RGBA colour transfer: each target pixel's mean value coordinates with respect to
  the simplified target contour Cs', applied to each exemplar's Cs, give a source
  position, sampled bilinearly; alpha is the maximum over the exemplars and colour a
  convex combination of the exemplars' colours where they are not transparent;
* §5.3 histogram transfer of each RGB channel to a reference image, transparent pixels
  ignored (:func:`match_histograms`; from the tree of a photo, crown and trunk apart:
  :mod:`treeform.methods.variations.season`).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from treeform._shared.errors import InputError
from treeform.contour import fill_contour, mvc_map, simplify_contour
from treeform.methods.variations.exemplar import TRUNK

__all__ = ["Synthesis", "combine_contours", "check_weights", "warp_coordinates", "transfer_rgba",
           "match_histograms", "synthesize"]


@dataclass
class Synthesis:
    """One synthesised tree.

    Attributes
    ----------
    rgba : ndarray, shape (S, S, 4), uint8
        The tree, straight alpha; (0, 0, 0, 0) outside ``mask``.
    mask : ndarray, shape (S, S), bool
        Region fill of ``contour`` (the preliminary alpha of §5.1).
    contour : ndarray, shape (N, 2)
        Cr' = sum_j w_j Cr_j.
    simplified : ndarray, shape (M, 2)
        Cs' used for the mean value coordinates.
    weights, colour_weights : ndarray, shape (J,)
    labels : ndarray, shape (S, S), uint8, or None
        0 background, 1 crown, 2 trunk: a pixel is trunk where its colour comes mostly
        from the exemplars' trunks (for :func:`~.season.season_transfer`).
    """

    rgba: np.ndarray
    mask: np.ndarray
    contour: np.ndarray
    simplified: np.ndarray
    weights: np.ndarray
    colour_weights: np.ndarray
    labels: np.ndarray | None = None


def check_weights(weights, n: int, name: str = "weights") -> np.ndarray:
    """Convex weights: ``n`` finite values >= 0 with a positive sum, returned normalised to sum 1."""
    w = np.asarray(weights, np.float64).reshape(-1)
    if w.shape != (n,):
        raise InputError(f"{name}: expected {n} weights, got {w.size}")
    if not np.all(np.isfinite(w)) or (w < 0).any() or w.sum() <= 0:
        raise InputError(f"{name}: expected non-negative weights with a positive sum (a convex combination; "
                         f"negative weights would reflect contours), got {w.tolist()}")
    return w / w.sum()


def combine_contours(contours, weights) -> np.ndarray:
    """Convex combination of fixed-length contours (seed 000 §5.1).

    Combining the absolute pixel coordinates is the paper's combination of
    mean-subtracted vectors u_j with the means combined by the same weights.

    Parameters
    ----------
    contours : ndarray, shape (J, N, 2)
        Resampled contours Cr_j (all with the same pin layout).
    weights : array-like, shape (J,)
        w_j >= 0 (normalised to sum 1).

    Returns
    -------
    ndarray, shape (N, 2)

    Examples
    --------
    >>> a = np.zeros((3, 2)); b = np.ones((3, 2))
    >>> combine_contours([a, b], [0.25, 0.75])[0].tolist()
    [0.75, 0.75]
    """
    c = np.asarray(contours, np.float64)
    if c.ndim != 3 or c.shape[2] != 2 or len(c) < 1:
        raise InputError(f"contours: expected shape (J, N, 2), got {c.shape}")
    w = check_weights(weights, len(c))
    return np.tensordot(w, c, axes=1)


def warp_coordinates(mask, target_polygon, source_polygons, *, step: int = 4):
    """Source positions of the pixels of ``mask`` under the mean value coordinate warp.

    The coordinates are evaluated exactly (:func:`treeform.contour.mvc_map`) on a grid
    of nodes every ``step`` pixels that covers the mask, and interpolated bilinearly in
    between: mean value coordinates are smooth (C-infinity away from the vertices), so
    with Cs vertices hundreds of pixels apart the interpolation error is far below a
    pixel, at 1/step^2 of the cost. ``step=1`` evaluates every pixel exactly.

    Parameters
    ----------
    mask : ndarray, shape (H, W), bool
    target_polygon : ndarray, shape (M, 2)
    source_polygons : ndarray, shape (J, M, 2)
    step : int

    Returns
    -------
    coords : ndarray, shape (J, P, 2), float32
        Source ``(x, y)`` of each mask pixel, per source polygon.
    ys, xs : ndarray, shape (P,), int
        The mask pixels, in ``np.nonzero`` order.
    """
    m = np.asarray(mask, bool)
    if isinstance(step, bool) or not isinstance(step, (int, np.integer)) or step < 1:
        raise InputError(f"step: expected an integer >= 1, got {step!r}")
    src = np.asarray(source_polygons, np.float64)
    ys, xs = np.nonzero(m)
    if ys.size == 0:
        return np.zeros((len(src), 0, 2), np.float32), ys, xs
    if step == 1:
        pts = np.column_stack([xs, ys]).astype(np.float64)
        return mvc_map(pts, target_polygon, src).astype(np.float32), ys, xs
    x0, y0 = int(xs.min()), int(ys.min())
    gx = (xs - x0) / step
    gy = (ys - y0) / step
    ix = np.floor(gx).astype(np.int64)
    iy = np.floor(gy).astype(np.int64)
    nx, ny = int(ix.max()) + 2, int(iy.max()) + 2
    need = np.zeros((ny, nx), bool)
    for dy in (0, 1):
        for dx in (0, 1):
            need[iy + dy, ix + dx] = True
    ny_, nx_ = np.nonzero(need)
    nodes = np.column_stack([x0 + nx_ * step, y0 + ny_ * step]).astype(np.float64)
    vals = mvc_map(nodes, target_polygon, src)  # (J, K, 2)
    grid = np.zeros((len(src), ny, nx, 2), np.float64)
    grid[:, ny_, nx_] = vals
    fx = (gx - ix)[None, :, None]
    fy = (gy - iy)[None, :, None]
    out = (grid[:, iy, ix] * (1 - fx) * (1 - fy) + grid[:, iy, ix + 1] * fx * (1 - fy)
           + grid[:, iy + 1, ix] * (1 - fx) * fy + grid[:, iy + 1, ix + 1] * fx * fy)
    return out.astype(np.float32), ys, xs


def _premultiplied(image) -> np.ndarray:
    if hasattr(image, "premultiplied"):
        return image.premultiplied
    a = np.asarray(image)
    if a.ndim != 3 or a.shape[2] != 4 or a.dtype != np.uint8:
        raise InputError(f"images: expected (S, S, 4) uint8 RGBA arrays, got {a.shape} {a.dtype}")
    f = a.astype(np.float32) / 255.0
    f[..., :3] *= f[..., 3:4]
    return f


def _sample(src: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Bilinear samples (P, C) of a float32 image at points ``xy`` (P, 2), zero outside.

    The points are laid out as a (rows, 1024) map because ``cv2.remap`` needs images
    under 32767 pixels on a side.
    """
    p = len(xy)
    if p == 0:
        return np.zeros((0, src.shape[2]), np.float32)
    cols = 1024
    rows = -(-p // cols)
    mx = np.full(rows * cols, -10.0, np.float32)
    my = np.full(rows * cols, -10.0, np.float32)
    mx[:p] = xy[:, 0]
    my[:p] = xy[:, 1]
    s = cv2.remap(src, mx.reshape(rows, cols), my.reshape(rows, cols), interpolation=cv2.INTER_LINEAR,
                  borderMode=cv2.BORDER_CONSTANT, borderValue=(0, 0, 0, 0))
    return s.reshape(rows * cols, -1)[:p]


def transfer_rgba(mask, target_polygon, images, source_polygons, colour_weights, *, step: int = 4) -> np.ndarray:
    """RGBA colour transfer by mean value coordinates (seed 000 §5.2).

    For every pixel p' of ``mask`` the source position in exemplar j is
    ``p_j = sum_i lambda'_i(p') v_ij`` (lambda' the mean value coordinates of p' with
    respect to Cs', v_ij the vertices of exemplar j's Cs), sampled bilinearly
    (premultiplied, so transparent black never darkens a colour). The output alpha is
    ``max_j a_j``; the colour is the convex combination ``sum_j b_j a_j c_j / sum_j b_j
    a_j`` of the exemplars' colours c_j with the colour weights b_j, so that only
    non-transparent samples contribute (weighted by their opacity, which makes the
    result continuous where a sample's alpha falls to 0).

    Parameters
    ----------
    mask : ndarray, shape (S, S), bool
        Target region (region fill of the synthesised contour).
    target_polygon : ndarray, shape (M, 2)
        Cs'.
    images : sequence of J Exemplar or (S, S, 4) uint8 arrays
    source_polygons : ndarray, shape (J, M, 2)
        Cs of each exemplar.
    colour_weights : array-like, shape (J,)
    step : int
        Grid step of :func:`warp_coordinates`.

    Returns
    -------
    ndarray, shape (S, S, 4), uint8
        Straight alpha; (0, 0, 0, 0) outside ``mask`` and where every sample is transparent.
    """
    return _transfer(mask, target_polygon, images, source_polygons, colour_weights, step=step)[0]


def _transfer(mask, target_polygon, images, source_polygons, colour_weights, *, step: int = 4, trunks=None):
    """:func:`transfer_rgba`, and with ``trunks`` (J (S, S) bool maps) the labels of the
    result: a pixel is trunk where its colour comes mostly from trunk samples (the
    opacity- and colour-weighted share of trunk, bilinear, >= 0.5), else crown."""
    m = np.asarray(mask, bool)
    b = check_weights(colour_weights, len(images), "colour_weights")
    coords, ys, xs = warp_coordinates(m, target_polygon, source_polygons, step=step)
    prem_sum = np.zeros((len(ys), 3), np.float32)
    wsum = np.zeros(len(ys), np.float32)
    alpha = np.zeros(len(ys), np.float32)
    trunk_sum = np.zeros(len(ys), np.float32)
    for j, img in enumerate(images):
        prem = _premultiplied(img)
        s = _sample(prem, coords[j])
        a = np.clip(s[:, 3], 0.0, 1.0)
        alpha = np.maximum(alpha, a)
        if b[j] > 0:
            prem_sum += np.float32(b[j]) * s[:, :3]
            wsum += np.float32(b[j]) * a
            if trunks is not None:  # the trunk indicator, premultiplied like the colours
                t = (np.asarray(trunks[j], bool) * prem[..., 3]).astype(np.float32)[..., None]
                trunk_sum += np.float32(b[j]) * _sample(t, coords[j]).reshape(-1)
    # pixels where every weighted exemplar is transparent take the unweighted mean colour
    out = np.zeros(m.shape + (4,), np.uint8)
    ok = wsum > 1e-6
    colour = np.zeros((len(ys), 3), np.float32)
    colour[ok] = prem_sum[ok] / wsum[ok, None]
    if (~ok & (alpha > 0)).any():
        rest = ~ok & (alpha > 0)
        acc = np.zeros((int(rest.sum()), 3), np.float32)
        acc_w = np.zeros(int(rest.sum()), np.float32)
        for j, img in enumerate(images):
            s = _sample(_premultiplied(img), coords[j, rest])
            acc += s[:, :3]
            acc_w += s[:, 3]
        colour[rest] = acc / np.maximum(acc_w, 1e-6)[:, None]
    a8 = np.clip(np.rint(alpha * 255.0), 0, 255).astype(np.uint8)
    rgb8 = np.clip(np.rint(colour * 255.0), 0, 255).astype(np.uint8)
    rgb8[a8 == 0] = 0
    out[ys, xs, :3] = rgb8
    out[ys, xs, 3] = a8
    if trunks is None:
        return out, None
    labels = np.zeros(m.shape, np.uint8)
    trunk = ok & (trunk_sum >= 0.5 * wsum)
    labels[ys, xs] = np.where(a8 > 0, np.where(trunk, 2, 1), 0)
    return out, labels


def _reference_pixels(reference, threshold: float) -> np.ndarray:
    r = np.asarray(reference)
    if r.ndim != 3 or r.shape[2] not in (3, 4) or r.dtype != np.uint8:
        raise InputError(f"reference: expected an (H, W, 3) or (H, W, 4) uint8 image, got {r.shape} {r.dtype}")
    if r.shape[2] == 4:
        px = r[r[..., 3] >= threshold * 255.0, :3]
    else:
        px = r.reshape(-1, 3)
    if len(px) == 0:
        raise InputError("reference: no opaque pixel to take a histogram from")
    return px


def match_histograms(image, reference, *, threshold: float = 0.5) -> np.ndarray:
    """Histogram transfer of each RGB channel to a reference image (seed 000 §5.3).

    For each channel the cumulative histograms of the image's and the reference's
    opaque pixels (alpha >= ``threshold``; an RGB reference counts as all opaque) are
    computed, and each of the image's values is mapped to the reference value of the
    same quantile, by linear interpolation (as in scikit-image's ``match_histograms``,
    [GW07]). Transparent pixels are ignored when the histograms are taken; the mapping
    is applied to every pixel with alpha > 0, and alpha is unchanged.

    Parameters
    ----------
    image : ndarray, shape (H, W, 4), uint8
    reference : ndarray, shape (H', W', 3 or 4), uint8
    threshold : float
        Alpha threshold of "opaque" in [0, 1].

    Returns
    -------
    ndarray, shape (H, W, 4), uint8
    """
    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] != 4 or img.dtype != np.uint8:
        raise InputError(f"image: expected an (H, W, 4) uint8 RGBA image, got {img.shape} {img.dtype}")
    if not 0 <= threshold <= 1:
        raise InputError(f"threshold: expected a value in [0, 1], got {threshold!r}")
    ref = _reference_pixels(reference, threshold)
    opaque = img[..., 3] >= max(threshold * 255.0, 1)
    out = img.copy()
    if not opaque.any():
        return out
    visible = img[..., 3] > 0
    levels = np.arange(256, dtype=np.float64)
    for c in range(3):
        src_counts = np.bincount(img[..., c][opaque], minlength=256).astype(np.float64)
        ref_counts = np.bincount(ref[:, c], minlength=256).astype(np.float64)
        src_values = np.nonzero(src_counts)[0]
        ref_values = np.nonzero(ref_counts)[0]
        src_q = np.cumsum(src_counts[src_values]) / src_counts.sum()
        ref_q = np.cumsum(ref_counts[ref_values]) / ref_counts.sum()
        mapped = np.interp(src_q, ref_q, ref_values.astype(np.float64))
        # a lookup table for every level (levels absent from the image interpolate)
        lut = np.interp(levels, src_values.astype(np.float64), mapped)
        lut8 = np.clip(np.rint(lut), 0, 255).astype(np.uint8)
        out[..., c] = np.where(visible, lut8[img[..., c]], img[..., c])
    return out


def synthesize(exemplars, weights, *, colour_weights=None, m: int = 20, mvc_step: int = 4) -> Synthesis:
    """A new tree from exemplars (seed 000 §5.1–5.2).

    Parameters
    ----------
    exemplars : sequence of J :class:`~treeform.methods.variations.exemplar.Exemplar`
        Processed at the same size, with the same pin layout (counts).
    weights : array-like, shape (J,)
        Contour weights w_j >= 0 (normalised to sum 1).
    colour_weights : array-like, shape (J,), optional
        Colour weights b_j (default: ``weights``).
    m : int
        Points M of the simplified contours (paper: 20).
    mvc_step : int
        Grid step of the mean value coordinate evaluation (1 = every pixel).

    Returns
    -------
    Synthesis
    """
    ex = list(exemplars)
    if not ex:
        raise InputError("exemplars: expected at least one exemplar")
    sizes = {e.rgba.shape for e in ex}
    counts = {tuple(e.counts) for e in ex}
    if len(sizes) != 1 or len(counts) != 1:
        raise InputError("exemplars: all must be processed at the same size and with the same contour counts")
    w = check_weights(weights, len(ex))
    b = w if colour_weights is None else check_weights(colour_weights, len(ex), "colour_weights")
    shape = ex[0].rgba.shape[:2]
    contour = combine_contours([e.resampled for e in ex], w)
    mask = fill_contour(contour, shape)
    cs_t = simplify_contour(contour, shape, m=m, dilate=ex[0].dilate, counts=ex[0].counts)
    # an exemplar with zero contour and colour weight takes no part (so that a morph at
    # t = 0 or 1 is exactly one of its ends)
    active = [j for j in range(len(ex)) if w[j] > 0 or b[j] > 0]
    cs_src = np.stack([ex[j].simplified_contour(m) for j in active])
    rgba, labels = _transfer(mask, cs_t, [ex[j] for j in active], cs_src, b[active], step=mvc_step,
                             trunks=[ex[j].labels == TRUNK for j in active])
    return Synthesis(rgba, mask, contour, cs_t, w, b, labels)
