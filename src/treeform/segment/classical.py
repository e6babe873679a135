"""Classical (non-learned) segmentation of one ordinary outdoor photo of a tree.

The automatic path, :func:`segment_tree`, needs no user input. Steps 1-3 run on a copy
of the photo reduced to :data:`WORK_SIDE` pixels on its long side, step 4 at full size.

1. **Cues** per pixel: CIE Lab, chromatic excess green ``(2g - r - b) / (r + g + b)``
   and texture, the local standard deviation of log brightness (foliage is textured;
   sky, lawn and distant tree lines are smoother).
2. **Sky, ground and bark.** Sky is smooth and blue (negative b*), or coloured like
   smooth bright seeds at the top of the photo (white or grey sky) and connected to
   them. Ground is everything below a *ground line*, one row per column, found exactly
   by dynamic programming: ground is smooth, coloured like the bottom band of the
   photo, low in the frame, and never a vertical run of bark colour (a trunk). Bark is
   brown, grey or reddish, neither green, yellow nor blue (:func:`wood_colour_mask`).
3. **Graph cut** (``cv2.grabCut`` on a texture / a* / b* image, sky painted one flat
   colour). The main tree stands on the column where the skyline of what is neither
   sky nor ground rises highest near the centre; its trunk is the tallest vertical
   run of bark colour standing on the ground line near that column. Sure foreground:
   the textured crown interior and the trunk. Sure background: sky, ground, regions
   of another colour than the top of the crown away from it (a neighbouring tree),
   pixels under a gap of side sky and the band just above the ground line reaching a
   side of the photo (bushes, hedges, tree lines). Probable background: the rest of
   that band and tree lines beside the crown (the skyline drops to a flat level
   toward a border). The cut settles the probable pixels; the main tree is the
   connected component holding the trunk and crown seeds.
4. **Full resolution.** The mask is upsampled and its edge snapped to the photo by a
   per-pixel Bayes rule (colour histograms of tree and background as likelihoods,
   the blurred upsampled mask as prior), so twigs and sky gaps follow the photo. The
   trunk is searched again at full size (a thin trunk is a pixel wide when reduced);
   nothing of the tree lies below the ground line or below the trunk's foot, and the
   foot is wood. Wood is the bark colour, judged against the tree's own median
   colour so that grey-green needles and leaf shadows stay foliage. Where the tree's
   own colour is bark-like (leafless, or a red / orange / brown autumn crown), shape
   decides: a trunk run stops where it widens into the crown, and bark-coloured masses
   too broad for branches are foliage.

:func:`mask_to_segmentation` labels a user-supplied tree mask with the same wood
colour model and trunk search.
"""

from __future__ import annotations

import cv2
import numpy as np

from treeform._shared.errors import InputError, NoTreeFoundError
from treeform.structures.segmentation import BACKGROUND, FOLIAGE, WOOD, Segmentation

__all__ = ["segment_tree", "mask_to_segmentation", "wood_colour_mask", "ground_line", "trunk_in_mask", "WORK_SIDE"]

WORK_SIDE = 256
"""Long side, in pixels, of the reduced copy on which the graph cut runs."""
LEAF_MASS = 0.01
"""Leafless-looking trees: bark-coloured masses broader than a disc of this share of the tree's
height are leaf masses (a red, orange or brown autumn crown), not branches."""

_MIN_TREE_FRACTION = 0.01
MIN_TRUNK = 0.12
"""A trunk found by :func:`trunk_in_mask` stands for at least this share of the tree's height."""
_GRABCUT_ITERS = 4
_NBINS = 8 * 16 * 16


# --------------------------------------------------------------------------- checks


def _check_image(image, *, min_side: int = 8) -> np.ndarray:
    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] != 3:
        raise InputError(f"image: expected an (H, W, 3) RGB array, got shape {img.shape}")
    if img.dtype != np.uint8:
        raise InputError(f"image: expected dtype uint8, got {img.dtype}")
    if min(img.shape[:2]) < min_side:
        raise InputError(f"image: expected at least {min_side} x {min_side} pixels, got {img.shape[1]} x {img.shape[0]}")
    return np.ascontiguousarray(img)


# --------------------------------------------------------------------------- features


def _features(rgb: np.ndarray, *, texture: bool = True) -> dict:
    """Per-pixel cues of an (H, W, 3) uint8 RGB image.

    Returns a dict of (H, W) float32 arrays: ``L`` (0..255), ``a`` and ``b`` (centred
    on 0), ``chroma``, ``exg`` (chromatic excess green) and, when ``texture``, ``tex``
    (5 x 5 standard deviation of log brightness).
    """
    f = rgb.astype(np.float32)
    s = f.sum(2) + 1.0
    exg = (2.0 * f[..., 1] - f[..., 0] - f[..., 2]) / s
    lab = cv2.cvtColor(rgb, cv2.COLOR_RGB2Lab).astype(np.float32)
    L = lab[..., 0]
    a = lab[..., 1] - 128.0
    b = lab[..., 2] - 128.0
    out = dict(exg=exg, L=L, a=a, b=b, chroma=np.hypot(a, b))
    if texture:
        ll = np.log(L * (100.0 / 255.0) + 3.0)
        m = cv2.blur(ll, (5, 5))
        m2 = cv2.blur(ll * ll, (5, 5))
        out["tex"] = np.sqrt(np.maximum(m2 - m * m, 0.0))
    return out


def _quantize(F: dict) -> np.ndarray:
    """(H, W) int32 colour bin in an 8 (L) x 16 (a) x 16 (b) Lab grid."""
    Lq = np.clip(F["L"] * (8 / 256.0), 0, 7).astype(np.int32)
    aq = np.clip((F["a"] + 48.0) * (16 / 96.0), 0, 15).astype(np.int32)
    bq = np.clip((F["b"] + 48.0) * (16 / 96.0), 0, 15).astype(np.int32)
    return (Lq * 16 + aq) * 16 + bq


def _hist_prob(q: np.ndarray, sel: np.ndarray, nbins: int = _NBINS) -> np.ndarray:
    """(nbins,) colour histogram of ``q[sel]`` with add-one smoothing, summing to 1."""
    h = np.bincount(q[sel], minlength=nbins).astype(np.float32)
    return (h + 1.0) / (h.sum() + nbins)


# --------------------------------------------------------------------------- masks


def _components_touching(mask: np.ndarray, seeds: np.ndarray) -> np.ndarray:
    """Pixels of ``mask`` in 8-connected components that contain a ``seeds`` pixel."""
    n, lab = cv2.connectedComponents(mask.astype(np.uint8), connectivity=8)
    hit = np.zeros(n, bool)
    hit[np.unique(lab[seeds & mask])] = True
    hit[0] = False
    return hit[lab]


def _largest_cc(mask: np.ndarray, prefer: np.ndarray | None = None) -> np.ndarray:
    """The largest 8-connected component; pixels in ``prefer`` count 5 times."""
    n, lab, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    if n <= 1:
        return np.zeros(mask.shape, bool)
    score = stats[1:, cv2.CC_STAT_AREA].astype(np.float64)
    if prefer is not None:
        score += 4.0 * np.bincount(lab[prefer & mask], minlength=n)[1:]
    return lab == 1 + int(np.argmax(score))


def _fill_holes(mask: np.ndarray, max_area: float) -> np.ndarray:
    """Fill background holes of at most ``max_area`` pixels that do not touch the border."""
    n, lab, stats, _ = cv2.connectedComponentsWithStats((~mask).astype(np.uint8), connectivity=4)
    h, w = mask.shape
    x, y, ww, hh, area = (stats[:, i] for i in range(5))
    small = (area <= max_area) & (x > 0) & (y > 0) & (x + ww < w) & (y + hh < h)
    small[0] = False
    return mask | small[lab]


def _median(values: np.ndarray, mask: np.ndarray) -> float:
    """Median of ``values[mask]`` (on a regular subsample when there are many pixels)."""
    step = max(1, int(np.sqrt(mask.size / 40000)))
    v = values[::step, ::step][mask[::step, ::step]]
    if v.size == 0:
        v = values[mask]
    return float(np.median(v)) if v.size else 0.0


def _border(shape) -> np.ndarray:
    b = np.zeros(shape, bool)
    b[0, :] = b[-1, :] = b[:, 0] = b[:, -1] = True
    return b


def _disc(r: int) -> np.ndarray:
    return cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))


def _erode(m, k):
    return cv2.erode(m.astype(np.uint8), k).astype(bool)


def _dilate(m, k):
    return cv2.dilate(m.astype(np.uint8), k).astype(bool)


def _open(m, k):
    return cv2.morphologyEx(m.astype(np.uint8), cv2.MORPH_OPEN, k).astype(bool)


# --------------------------------------------------------------------------- colour models


def _sky_mask(F: dict) -> np.ndarray:
    """(H, W) bool sky: blue, or coloured like smooth bright seeds at the top, and smooth."""
    h, w = F["L"].shape
    L, b, tex, ch = F["L"], F["b"], F["tex"], F["chroma"]
    rows = np.arange(h)[:, None]
    weak_blue = (b < -4) & (L > 50) & (tex < 0.22)
    strong_blue = (b < -12) & (tex < 0.12)
    sky = _components_touching(weak_blue, strong_blue)
    # white, grey or hazy sky: a colour model learnt from smooth bright pixels at the top
    seeds = (rows < 0.3 * h) & (tex < 0.07) & (L > 110) & ((b < -3) | (ch < 18))
    seeds = _components_touching(seeds, seeds & (rows < 0.05 * h + 2))
    if seeds.sum() > 0.002 * h * w:
        q = _quantize(F)
        hist = np.bincount(q[seeds], minlength=_NBINS).reshape(8, 16, 16)
        keep = hist >= max(2.0, 0.002 * seeds.sum())
        grown = keep.copy()
        for axis in range(3):
            for d in (-1, 1):
                grown |= np.roll(keep, d, axis=axis)
        colour = grown.reshape(-1)[q]
        sky |= _components_touching(colour & (tex < 0.15), seeds)
        # sky seen through gaps (under a crown, beside a trunk): very smooth, sky-coloured
        very = colour & (tex < 0.06) & ~sky
        n, lab, st, _ = cv2.connectedComponentsWithStats(very.astype(np.uint8), connectivity=8)
        big = st[:, cv2.CC_STAT_AREA] >= max(6, 0.001 * h * w)
        big[0] = False
        if big.any():
            sky |= _components_touching(colour & (tex < 0.15), big[lab])
    return sky


def sky_mask(image: np.ndarray) -> np.ndarray:
    """The sky of an (H, W, 3) uint8 RGB photo: (H, W) bool (blue or bright, smooth; see the module notes)."""
    return _sky_mask(_features(_check_image(image)))


def wood_colour_mask(image: np.ndarray) -> np.ndarray:
    """Pixels coloured like bark: brown, grey or reddish, neither green, yellow nor blue.

    This is the one wood colour model of this module, shared by :func:`segment_tree`
    and :func:`mask_to_segmentation`.

    Parameters
    ----------
    image : ndarray, shape (H, W, 3), uint8
        RGB photo.

    Returns
    -------
    ndarray, shape (H, W), bool

    Examples
    --------
    >>> px = np.array([[[110, 80, 55], [60, 140, 40]]], np.uint8)  # brown bark, green leaf
    >>> wood_colour_mask(px).tolist()
    [[True, False]]
    """
    return _bark_colour(_features(_check_image(image, min_side=1), texture=False))


def _bark_colour(F: dict) -> np.ndarray:
    a, b, L, exg = F["a"], F["b"], F["L"], F["exg"]
    return (a > -7) & (b > -4) & (b < 45) & (exg < 0.16) & (L > 25) & ~((L > 215) & (F["chroma"] < 10))


def _vertical_bark(bark: np.ndarray) -> np.ndarray:
    """Bark pixels in tall, narrow vertical runs (trunks)."""
    h, w = bark.shape
    kv = cv2.getStructuringElement(cv2.MORPH_RECT, (1, max(3, int(0.08 * h))))
    kh = cv2.getStructuringElement(cv2.MORPH_RECT, (max(3, int(0.4 * w)), 1))
    return _open(bark, kv) & ~_open(bark, kh)


# --------------------------------------------------------------------------- ground


def _ground_evidence(F: dict, sky: np.ndarray, vbark: np.ndarray) -> np.ndarray:
    """(H, W) float32: > 0 where a pixel looks like ground (lawn, path, meadow)."""
    h, w = sky.shape
    texb = cv2.blur(F["tex"], (7, 7))
    rows = np.arange(h)[:, None]
    upper = (rows >= int(0.05 * h)) & (rows < int(0.45 * h)) & ~sky
    ref = np.median(texb[upper]) if upper.sum() > 50 else np.median(texb[~sky]) if (~sky).any() else 0.0
    tex_rel = texb / max(float(ref), 0.03)
    smooth_ev = np.clip((0.65 - tex_rel) / 0.3, -1.0, 1.0)
    q = _quantize(F)
    bottom = (rows >= int(0.92 * h)) & ~sky
    col_ev = np.zeros_like(smooth_ev)
    if bottom.sum() > 20 and upper.sum() > 20:
        ratio = _hist_prob(q, bottom)[q] / _hist_prob(q, upper)[q]
        col_ev = np.clip(np.log(ratio) / 2.0, -1.5, 1.0)
    e = smooth_ev + col_ev - 0.6 * (1.0 - rows / h) ** 2 - 3.0 * vbark
    e[sky] = -1.0
    return e.astype(np.float32)


def _ground_line(e: np.ndarray, lam: float = 1.0) -> np.ndarray:
    """Per column x the first ground row ``g[x]`` (``H`` = no ground visible).

    Maximises ``sum_x sum_{y >= g[x]} e[y, x] - lam * sum_x |g[x] - g[x-1]|`` exactly by
    dynamic programming (the L1 transition is two running maxima per column).
    """
    h, w = e.shape
    s = np.zeros((h + 1, w), np.float32)
    s[:h] = np.cumsum(e[::-1], axis=0)[::-1]
    ys = np.arange(h + 1, dtype=np.float32)
    dp = np.empty((w, h + 1), np.float32)
    dp[0] = s[:, 0]
    for x in range(1, w):
        p = dp[x - 1]
        fwd = np.maximum.accumulate(p + lam * ys) - lam * ys
        bwd = np.maximum.accumulate((p - lam * ys)[::-1])[::-1] + lam * ys
        dp[x] = np.maximum(fwd, bwd) + s[:, x]
    g = np.empty(w, np.int32)
    g[-1] = int(np.argmax(dp[-1]))
    for x in range(w - 1, 0, -1):
        g[x - 1] = int(np.argmax(dp[x - 1] - lam * np.abs(ys - g[x])))
    return g


def ground_line(image: np.ndarray) -> np.ndarray:
    """Where the ground begins in each column of an outdoor photo.

    The colour rules' ground model (smooth texture, the colours of the photo's bottom
    rows, no vertical bark, never sky) and their dynamic-programming ground line, on a
    copy reduced to :data:`WORK_SIDE` pixels (about 10 ms).

    Parameters
    ----------
    image : ndarray, shape (H, W, 3), uint8
        RGB photo.

    Returns
    -------
    ndarray, shape (W,), int32
        First ground row of each column, at the photo's resolution (``H`` where no ground
        is visible in that column).

    Examples
    --------
    A sky over a lawn, a textured stem in the middle:

    >>> img = np.zeros((120, 80, 3), np.uint8); img[:80] = (90, 150, 230); img[80:] = (70, 120, 40)
    >>> img[:80, 30:50] = np.random.default_rng(0).integers(20, 160, (80, 20, 3))
    >>> g = ground_line(img); g.shape, int(np.median(g))
    ((80,), 80)
    """
    img = _check_image(image)
    h, w = img.shape[:2]
    sc = min(1.0, WORK_SIDE / max(h, w))
    hs, ws = max(8, round(h * sc)), max(8, round(w * sc))
    small = cv2.resize(img, (ws, hs), interpolation=cv2.INTER_AREA) if sc < 1.0 else img
    F = _features(small)
    sky = _sky_mask(F)
    g = _ground_line(_ground_evidence(F, sky, _vertical_bark(_bark_colour(F) & ~sky)))
    return g.astype(np.int32) if (hs, ws) == (h, w) else _ground_to(g, hs, h, w)


def _ground_to(g: np.ndarray, hs: int, h: int, w: int) -> np.ndarray:
    """A ground line found on a copy ``hs`` rows tall, at a photo of ``h`` x ``w`` pixels."""
    gx = cv2.resize(g.astype(np.float32).reshape(1, -1), (w, 1), interpolation=cv2.INTER_LINEAR).ravel()
    return np.minimum(np.round(gx * h / hs), h).astype(np.int32)


# --------------------------------------------------------------------------- main tree


def _skyline(cand: np.ndarray) -> np.ndarray:
    """(W,) float32: first non-sky, non-ground row per column (H where none)."""
    h, w = cand.shape
    t = np.where(cand.any(0), np.argmax(cand, axis=0), h).astype(np.float32)
    return cv2.medianBlur(t.reshape(1, -1), 5).ravel()


def _main_axis(t: np.ndarray, h: int) -> int:
    """Column of the main tree: the skyline rises highest there, near the centre."""
    w = t.size
    xs = (np.arange(w) + 0.5) / w
    score = (h - t) * (1.0 - np.abs(xs - 0.5))
    score = cv2.GaussianBlur(score.reshape(1, -1).astype(np.float32), (0, 0), sigmaX=max(1.0, 0.02 * w)).ravel()
    return int(np.argmax(score))


def _side_zones(t: np.ndarray, ax: int, h: int, w: int):
    """Probable / sure background beside the crown where the skyline drops to a tree line.

    On each side, the skyline at the image border gives the level of a side tree line;
    walking out from the axis, the knee is where the skyline reaches that level. Below
    the level and beyond the knee lies the tree line, not the main crown.
    """
    rows = np.arange(h)[:, None]
    cols = np.arange(w)[None, :]
    pr = np.zeros((h, w), bool)
    bg = np.zeros((h, w), bool)
    bw = max(2, int(0.08 * w))
    m = int(0.03 * w)
    for side in (-1, 1):
        level = float(np.median(t[:bw] if side < 0 else t[-bw:]))
        if level - float(t[ax]) < 0.15 * h:
            continue
        xs = np.arange(ax, -1, -1) if side < 0 else np.arange(ax, w)
        hit = np.nonzero(t[xs] >= level - 0.04 * h)[0]
        if hit.size == 0:
            continue
        knee = int(xs[hit[0]])
        rest = t[:knee + 1] if side < 0 else t[knee:]
        if rest.size and float(np.std(rest)) > 0.06 * h:
            continue  # not a flat tree line beyond the knee: maybe the crown's own skirt
        beyond = (cols < knee - m) if side < 0 else (cols > knee + m)
        far = (cols < knee - m - int(0.12 * w)) if side < 0 else (cols > knee + m + int(0.12 * w))
        pr |= beyond & (rows > level - 0.02 * h)
        bg |= far & (rows > level)
    return pr, bg


def _colour_neighbours(F: dict, cand: np.ndarray, crown: np.ndarray, ax: int) -> np.ndarray:
    """Neighbouring trees of another colour than the main crown.

    Chromaticity (a*, b*) histograms of the top of the main crown and of the non-sky
    pixels far from the axis; large regions away from the axis whose colours are far
    more likely under the second model are neighbours (yellow beside green, purple
    beside yellow, a dark conifer beside a light crown). Dark pixels are left alone
    (shadows look alike in every tree).
    """
    h, w = cand.shape
    cols = np.arange(w)[None, :]
    lit = F["L"] >= 20
    far = cand & lit & (np.abs(cols - ax) > 0.25 * w)
    crown = crown & lit
    if crown.sum() < 20 or far.sum() < 0.01 * h * w:
        return np.zeros((h, w), bool)
    aq = np.clip((F["a"] + 48.0) * (12 / 96.0), 0, 11).astype(np.int32)
    bq = np.clip((F["b"] + 48.0) * (12 / 96.0), 0, 11).astype(np.int32)
    q = aq * 12 + bq
    lr = np.log(_hist_prob(q, far, 144)[q] / _hist_prob(q, crown, 144)[q])
    unlike = cand & lit & (lr > np.log(4.0)) & (np.abs(cols - ax) > 0.05 * w)
    unlike = _open(cv2.medianBlur(unlike.astype(np.uint8), 5).astype(bool), np.ones((3, 3), np.uint8))
    # shadows inside a neighbour belong to it
    unlike = cv2.morphologyEx(unlike.astype(np.uint8), cv2.MORPH_CLOSE, _disc(3)).astype(bool) & cand
    unlike &= lit | _erode(unlike, _disc(1))
    unlike = _open(unlike, _disc(2))  # no thin lines (a shadow crack inside the crown)
    n, lab, st, _ = cv2.connectedComponentsWithStats(unlike.astype(np.uint8), connectivity=8)
    big = st[:, cv2.CC_STAT_AREA] >= 0.01 * h * w
    big[0] = False
    return big[lab]


def _find_trunk(F: dict, cand: np.ndarray, g: np.ndarray, ax: int, *, near: np.ndarray | None = None,
                max_offset: float = 0.3):
    """The main trunk(s): vertical runs of bark-coloured pixels that stand on the ground.

    Candidate runs come from :func:`_vertical_bark` (broken runs are first joined
    vertically). A run counts when its bottom reaches the ground line, it lies within
    30 % of the width from the axis and it is, on average, redder and less green than
    the tree's median colour (:func:`_wood_score` > 0.5), so the grey-green needles of
    a conifer that reach the ground do not pass. The tallest run close to the axis wins;
    other standing runs within 15 % of the width (multi-stemmed trees) are kept.

    Returns the (h, w) bool trunk pixels and the trunk column.
    """
    h, w = cand.shape
    # the ground line may cut a thin trunk a little above its true foot
    rows = np.arange(h)[:, None]
    cand = cand | ((rows >= g[None, :]) & (rows < g[None, :] + int(0.06 * h)))
    woodness = _wood_score(F, cand)
    # bark colours, or (a trunk in shade) much darker-redder and less green than the tree
    bark = (_bark_colour(F) | (woodness > 4.0)) & cand
    vb = _vertical_bark(bark) & cand
    vb = cv2.morphologyEx(vb.astype(np.uint8), cv2.MORPH_CLOSE,
                          cv2.getStructuringElement(cv2.MORPH_RECT, (3, max(3, int(0.06 * h))))).astype(bool)
    n, lab, st, cen = cv2.connectedComponentsWithStats(vb.astype(np.uint8), connectivity=8)
    touches = np.ones(n, bool)
    if near is not None:
        touches = np.bincount(lab[_dilate(near, np.ones((3, 3), np.uint8))], minlength=n) > 0
    area = np.maximum(st[:, cv2.CC_STAT_AREA], 1)
    mean_wood = np.bincount(lab.ravel(), weights=woodness.ravel(), minlength=n) / area
    texb = cv2.blur(F["tex"], (5, 5))
    mean_tex = np.bincount(lab.ravel(), weights=texb.ravel(), minlength=n) / area
    tex_ref = _median(texb, cand)
    hazy = np.bincount(lab.ravel(), weights=((F["L"] > 190) & (F["chroma"] < 10)).ravel().astype(np.float64),
                       minlength=n) / area
    standing, score = [], []
    for k in range(1, n):
        y0, hh = st[k, cv2.CC_STAT_TOP], st[k, cv2.CC_STAT_HEIGHT]
        xc = int(np.clip(cen[k][0], 0, w - 1))
        ww = st[k, cv2.CC_STAT_WIDTH]
        if y0 + hh < min(g[xc], h) - 0.1 * h or abs(xc - ax) > max_offset * w or mean_wood[k] < 0.5 or not touches[k]:
            continue
        if hh < 1.5 * ww or mean_tex[k] < 0.3 * tex_ref or hazy[k] > 0.5:
            continue  # a trunk is upright; its bark is not smooth, nor white-grey like haze
        standing.append((k, xc))
        score.append(hh * (1.0 - abs(xc - ax) / w))
    if not standing:
        return np.zeros((h, w), bool), ax
    tx = standing[int(np.argmax(score))][1]
    keep = np.zeros(n, bool)
    for k, xc in standing:
        keep[k] = abs(xc - tx) <= 0.15 * w
    return _below_the_crown(keep[lab] & vb), tx


def _below_the_crown(trunk: np.ndarray) -> np.ndarray:
    """A trunk run up from its foot only while it stays trunk-wide.

    A run of bark-coloured pixels can climb on into a crown of the same colour (red, orange,
    brown autumn leaves): where its width passes 2.5 times the width of its lowest fifth
    (plus 2 pixels) for 3 rows in a row, the crown begins and the run is cut there. The
    shape decides, not the hue.
    """
    rows = np.flatnonzero(trunk.any(axis=1))
    if len(rows) < 10:
        return trunk
    width = trunk[rows].sum(axis=1)
    foot = float(np.median(width[-max(3, len(rows) // 5):]))
    wide = width > 2.5 * foot + 2
    # from the foot upwards: the first row where 3 wide rows in a row begin
    run = 0
    for i in range(len(rows) - 1, -1, -1):
        run = run + 1 if wide[i] else 0
        if run >= 3:
            out = trunk.copy()
            out[: rows[i + 2] + 1] = False
            return out
    return trunk


def _grabcut_image(F: dict) -> np.ndarray:
    """(h, w, 3) uint8 feature image for the graph cut: texture, a*, b* (stretched)."""
    t = np.clip(F["tex"] * 600.0, 0, 255)
    a = np.clip(F["a"] * 2.0 + 128.0, 0, 255)
    b = np.clip(F["b"] * 2.0 + 128.0, 0, 255)
    return np.ascontiguousarray(np.dstack([t, a, b]).astype(np.uint8))


def _coarse_mask(small: np.ndarray, seed: int, debug: dict | None = None):
    """Graph cut on the reduced photo.

    Returns a dict: ``mask``, ``trunk``, ``sky`` and ``cand`` (neither sky nor
    ground), all (h, w) bool; ``g`` the (w,) ground line; ``axis`` the trunk's (or
    else the main axis') column; ``F`` the cues of the reduced photo.
    """
    F = _features(small)
    hs, ws = F["L"].shape
    rows = np.arange(hs)[:, None]
    cols = np.arange(ws)[None, :]
    sky = _sky_mask(F)
    bark = _bark_colour(F) & ~sky
    vbark = _vertical_bark(bark)
    g = _ground_line(_ground_evidence(F, sky, vbark))
    ground = rows >= g[None, :]
    cand = _open(~sky & ~ground, np.ones((2, 2), np.uint8))
    if cand.sum() < _MIN_TREE_FRACTION * hs * ws:
        raise NoTreeFoundError("no tree found in the photo (it is sky, ground or uniform)")

    t = _skyline(cand)
    ax = _main_axis(t, hs)
    side_pr, side_bg = _side_zones(t, ax, hs, ws)
    ytop = int(t[ax])
    gmed = float(np.median(g))
    core = cand & (np.abs(cols - ax) < 0.08 * ws) & (rows > ytop + 0.05 * hs)
    core &= rows < ytop + 0.35 * max(gmed - ytop, 1.0)
    core = _erode(core, np.ones((3, 3), np.uint8))
    trunk, tx = _find_trunk(F, cand, g, ax)
    texb = cv2.blur(F["tex"], (5, 5))
    ref = _median(texb, cand)
    sure0 = cand & (rows < g[None, :] - 4) & (texb > 0.6 * ref)
    crown_top = cand & (np.abs(cols - ax) < 0.15 * ws) & (rows < ytop + 0.3 * max(gmed - ytop, 1.0))
    nbr = _colour_neighbours(F, cand, crown_top, ax)
    # band just above the ground line, away from the trunk: bushes, hedges, lawn edges
    low = cand & (rows > g[None, :] - 0.12 * hs) & (np.abs(cols - tx) > 0.06 * ws)
    low_far = low & (np.abs(cols - tx) > 0.3 * ws)
    # below a side-connected gap of sky, away from the trunk: bushes, hedges, tree lines
    border_sky = _components_touching(sky, _border(sky.shape))
    last_sky = np.where(border_sky.any(0), hs - 1 - np.argmax(border_sky[::-1], axis=0), -1)
    below_sky = cand & (rows > last_sky[None, :]) & (last_sky[None, :] > 0.5 * hs)
    below_sky &= np.abs(cols - tx) > 0.06 * ws
    sure = sure0 & ~side_pr & ~low & ~below_sky & ~nbr
    sure = _erode(sure, _disc(2))
    # the low band reaching a side border in its row (a hedge, a line of bushes) is
    # background for sure; elsewhere (a crown skirt?) the graph cut decides
    lowc = cv2.morphologyEx(low.astype(np.uint8), cv2.MORPH_CLOSE, np.ones((1, 5), np.uint8)).astype(bool)
    low_side = np.cumprod(lowc, axis=1).astype(bool) | np.cumprod(lowc[:, ::-1], axis=1)[:, ::-1].astype(bool)
    sure_bg = (low & (low_side | low_far)) | below_sky | (cand & side_bg) | nbr
    sure_bg &= ~_dilate(sure | core | trunk, _disc(3))

    gc = np.full((hs, ws), cv2.GC_PR_BGD, np.uint8)
    gc[cand] = cv2.GC_PR_FGD
    gc[cand & side_pr] = cv2.GC_PR_BGD
    gc[low] = cv2.GC_PR_BGD
    gc[below_sky | nbr] = cv2.GC_PR_BGD
    gc[sure_bg] = cv2.GC_BGD
    gc[sure | core | trunk] = cv2.GC_FGD
    gc[sky] = cv2.GC_BGD
    gc[rows >= g[None, :] + 3] = cv2.GC_BGD
    gc_init = gc.copy() if debug is not None else None
    cv2.setRNGSeed(seed)
    bgd = np.zeros((1, 65), np.float64)
    fgd = np.zeros((1, 65), np.float64)
    feat = _grabcut_image(F)
    # one flat colour for the sky: the background colour model then spends its
    # components on lawn, bushes and tree lines instead of shades of sky
    feat[sky] = (0, 128, 0)
    cv2.grabCut(feat, gc, None, bgd, fgd, _GRABCUT_ITERS, cv2.GC_INIT_WITH_MASK)
    fg = (gc == cv2.GC_FGD) | (gc == cv2.GC_PR_FGD)
    fg = _open(fg, np.ones((2, 2), np.uint8)) | trunk
    # thin twigs and branches in front of the sky that the graph cut smoothed away
    thin = cand & ~_open(cand, np.ones((5, 5), np.uint8)) & _dilate(sky, np.ones((5, 5), np.uint8))
    fg = _components_touching(fg | thin, fg)
    mask = _largest_cc(fg, prefer=core | trunk)
    mask = _fill_holes(mask, 0.002 * hs * ws)
    trunk &= mask
    if debug is not None:  # intermediate maps, for inspecting failures
        debug.update(F=F, small=small, sky=sky, ground=ground, g=g, axis=ax, trunk_x=tx,
                     side=(side_pr & cand) | below_sky, nbr=nbr, low=low, core=core, trunk=trunk, gc_init=gc_init, gc=gc)
    return dict(mask=mask, trunk=trunk, sky=sky, cand=cand, g=g, axis=tx if trunk.any() else ax, F=F)


# --------------------------------------------------------------------------- full resolution


def _refine_full(F: dict, Fs: dict, ms: np.ndarray, sky_s: np.ndarray):
    """Upsample the reduced mask and snap its edge to the photo's colours.

    ``F`` and ``Fs`` are the cues of the photo and of its reduced copy. Colour
    histograms of the tree and of the background on the reduced copy give a
    likelihood ratio per colour; the upsampled, slightly blurred mask is the prior;
    a pixel is tree where the posterior exceeds one half (twigs and sky gaps at the
    silhouette follow the photo).

    Returns the full-resolution (H, W) bool mask and the (H, W) float32 posterior.
    """
    h, w = F["L"].shape
    hs, ws = ms.shape
    qs = _quantize(Fs)
    pf = _hist_prob(qs, _erode(ms, np.ones((3, 3), np.uint8)) & ~sky_s)
    pb = _hist_prob(qs, ~_dilate(ms, np.ones((3, 3), np.uint8)))
    ratio = pf / pb
    prior = cv2.resize(ms.astype(np.float32), (w, h), interpolation=cv2.INTER_LINEAR)
    sig = 0.6 * max(h / hs, w / ws)
    prior = cv2.GaussianBlur(prior, (0, 0), sigmaX=sig)
    prior = np.clip(prior, 0.0, 0.97)
    r = ratio[_quantize(F)]
    post = prior * r / (prior * r + (1.0 - prior) + 1e-6)
    mask = post > 0.5
    return mask, post.astype(np.float32)


def _wood_in_tree(F: dict, mask: np.ndarray, *, threshold: float = 2.0) -> np.ndarray:
    """Wood colour model inside a tree mask: bark colours, clearly redder and less green
    than the tree's own foliage (its median colour), so that grey-green conifer needles
    and leaf shadows stay foliage. A tree that is mostly bark-coloured (leafless) keeps
    the plain bark rule.
    """
    bark = _bark_colour(F) & mask
    if not mask.any():
        return bark
    if _median(F["a"], mask) > -2.0 and _median(F["exg"], mask) < 0.03:
        # the tree's typical colour is bark: a leafless tree -- or a red, orange or brown autumn
        # crown. Told apart by shape, not hue: branches are thin; what survives an opening by a
        # disc of LEAF_MASS of the tree's height is a leaf mass (the trunk is found on its own)
        rows = np.flatnonzero(mask.any(axis=1))
        r = max(2, int(round(LEAF_MASS * (rows[-1] - rows[0] + 1))))
        broad = cv2.morphologyEx(bark.astype(np.uint8), cv2.MORPH_OPEN, _disc(r)).astype(bool)
        return bark & ~broad
    return bark & (_wood_score(F, mask) > threshold)


def _wood_score(F: dict, mask: np.ndarray) -> np.ndarray:
    """(H, W) float32: how much redder (a*) and less green (excess green) than the
    median of ``mask`` a pixel is, in units of 4 a* and 0.06 excess green."""
    a_f = _median(F["a"], mask)
    g_f = _median(F["exg"], mask)
    return ((F["a"] - a_f) / 4.0 + (g_f - F["exg"]) / 0.06).astype(np.float32)


def _label(img: np.ndarray, mask: np.ndarray, trunk: np.ndarray | None = None, *, F: dict | None = None) -> np.ndarray:
    """(H, W) uint8 labels: 0 outside ``mask``, 2 on wood-coloured or trunk pixels, else 1."""
    h, w = mask.shape
    F = _features(img, texture=False) if F is None else F
    wood = _wood_in_tree(F, mask)
    k = max(1, int(round(min(h, w) / 300)))
    wood = cv2.medianBlur(wood.astype(np.uint8), 2 * k + 1).astype(bool) & mask
    # drop isolated specks
    n, lab, st, _ = cv2.connectedComponentsWithStats(wood.astype(np.uint8), connectivity=8)
    keep = st[:, cv2.CC_STAT_AREA] >= max(4, int(2e-5 * h * w))
    keep[0] = False
    wood = keep[lab]
    if trunk is not None:
        wood |= trunk & mask
    labels = np.where(mask, FOLIAGE, BACKGROUND).astype(np.uint8)
    labels[wood] = WOOD
    return labels


def _trunk_full(F: dict, mask: np.ndarray, trunk_s: np.ndarray) -> np.ndarray:
    """The trunk found on the reduced photo, at full resolution: its upsampled pixels,
    widened by about two reduced pixels, where the mask is bark-coloured."""
    h, w = mask.shape
    if not trunk_s.any():
        return np.zeros((h, w), bool)
    t = cv2.resize(trunk_s.astype(np.uint8), (w, h), interpolation=cv2.INTER_NEAREST).astype(bool)
    k = max(3, int(round(2 * max(h, w) / WORK_SIDE)) | 1)
    return _dilate(t, np.ones((k, k), np.uint8)) & mask & _bark_colour(F)


# --------------------------------------------------------------------------- public API


def segment_tree(image: np.ndarray, *, seed: int = 0) -> Segmentation:
    """Segment the one main tree of an ordinary outdoor photo, without user input.

    Parameters
    ----------
    image : ndarray, shape (H, W, 3), uint8
        RGB photo, up to about 1000 pixels on its long side (reduce larger photos first).
    seed : int, optional
        Seed of OpenCV's random generator, set before the graph cut; the same photo and
        seed give the same labels.

    Returns
    -------
    Segmentation
        ``labels`` (H, W) uint8: 0 background, 1 foliage, 2 wood, for the main tree only;
        ``alpha`` (H, W) float32 in [0, 1]: soft tree coverage (the mask, softened at
        its edge by the colour posterior).

    Raises
    ------
    InputError
        ``image`` is not an (H, W, 3) uint8 array.
    NoTreeFoundError
        The photo shows no tree (uniform, all sky or ground, or the tree covers less
        than 1 % of it).

    Notes
    -----
    Colour / texture models of sky, ground, foliage and bark, a ground line by dynamic
    programming, GrabCut (Rother et al. 2004) on a reduced copy, upsampling with a
    colour-posterior edge refinement; see the module docstring.
    """
    img = _check_image(image)
    h, w = img.shape[:2]
    sc = min(1.0, WORK_SIDE / max(h, w))
    size = (max(8, round(w * sc)), max(8, round(h * sc)))
    small = cv2.resize(img, size, interpolation=cv2.INTER_AREA) if sc < 1.0 else img.copy()
    if int(np.ptp(small.reshape(-1, 3), axis=0).max()) < 6:
        raise NoTreeFoundError("no tree found in the photo (the image is uniform)")
    co = _coarse_mask(small, seed)
    ms, trunk_s, cand_s, g_s, ax_s = co["mask"], co["trunk"], co["cand"], co["g"], co["axis"]
    F = _features(img)
    mask, post = _refine_full(F, co["F"], ms, co["sky"])
    # the trunk again at full resolution, where a thin trunk is more than a pixel wide
    hs, ws = ms.shape
    def up(m):
        return cv2.resize(m.astype(np.uint8), (w, h), interpolation=cv2.INTER_NEAREST).astype(bool)

    g = _ground_to(g_s, hs, h, w)
    trunk, _ = _find_trunk(F, up(cand_s), g, int(round((ax_s + 0.5) * w / ws)), near=mask, max_offset=0.1)
    trunk |= _trunk_full(F, mask, trunk_s)
    mask |= trunk
    # nothing of the tree below the ground line but the foot of the trunk
    rows = np.arange(h)[:, None]
    mask &= (rows <= g[None, :] + int(0.01 * h)) | trunk
    ys = np.nonzero(trunk.any(1))[0]
    if ys.size and ys.max() >= np.nonzero(mask.any(1))[0].max() - 0.1 * h:
        # the trunk stands at the bottom of the tree: nothing lies below its foot, and
        # just above the foot, only the trunk
        foot = int(ys.max())
        mask &= rows <= foot
        xs = np.nonzero(trunk[max(0, foot - int(0.02 * h)):].any(0))[0]
        m = int(0.015 * w)
        cols = np.arange(w)[None, :]
        base = (rows >= foot - min(int(0.25 * (foot - ys.min())), int(0.05 * h)))
        base = base & (cols >= xs.min() - m) & (cols <= xs.max() + m)
        near_trunk = _dilate(trunk, np.ones((1, 2 * m + 1), np.uint8))
        mask &= ~base | near_trunk
        trunk |= base & mask  # the foot of the tree is wood
    mask = _largest_cc(mask, prefer=trunk)
    mask = _fill_holes(mask, 0.0005 * h * w)
    if mask.sum() < _MIN_TREE_FRACTION * h * w:
        raise NoTreeFoundError("no tree found in the photo (the tree region covers under 1 % of it)")
    labels = _label(img, mask, trunk & mask, F=F)
    alpha = np.where(mask, np.maximum(post, 0.5), np.minimum(post, 0.5))
    alpha = cv2.GaussianBlur(alpha.astype(np.float32), (3, 3), 0)
    tree = labels != BACKGROUND
    alpha = np.where(tree, np.clip(alpha, 0.5, 1.0), np.clip(alpha, 0.0, 0.49)).astype(np.float32)
    return Segmentation(labels, alpha)


def mask_to_segmentation(mask: np.ndarray, image: np.ndarray) -> Segmentation:
    """Label a user-supplied tree mask: wood where bark-coloured, foliage elsewhere.

    Parameters
    ----------
    mask : ndarray, shape (H, W), bool or uint8
        The tree (True / non-zero, e.g. white = 255) on background (False / 0).
    image : ndarray, shape (H, W, 3), uint8
        The RGB photo the mask belongs to.

    Returns
    -------
    Segmentation
        ``labels`` 0 background, 1 foliage, 2 wood (same wood colour model as
        :func:`segment_tree`); ``alpha`` the mask as 0 / 1.

    Raises
    ------
    InputError
        ``mask`` is not 2-D or its size differs from the image's.
    NoTreeFoundError
        The mask is empty.
    """
    img = _check_image(image)
    m = np.asarray(mask)
    if m.ndim == 3 and m.shape[2] in (1, 3, 4):
        m = m[..., 0]
    if m.ndim != 2:
        raise InputError(f"mask: expected an (H, W) array, got shape {m.shape}")
    if m.shape != img.shape[:2]:
        raise InputError(
            f"mask: size {m.shape[1]} x {m.shape[0]} does not match the image's {img.shape[1]} x {img.shape[0]}"
        )
    m = m > (127 if m.dtype == np.uint8 and m.max() > 1 else 0)
    if not m.any():
        raise NoTreeFoundError("no tree found in the mask (it is empty)")
    F = _features(img)
    labels = _label(img, m, _trunk_in_mask(F, m), F=F)
    return Segmentation(labels, m.astype(np.float32))


def trunk_in_mask(image: np.ndarray, mask: np.ndarray, *, ground: np.ndarray | None = None,
                  focus: np.ndarray | None = None) -> np.ndarray:
    """The trunk of a tree mask: upright bark that stands on the tree's foot.

    Shape first, then colour: vertical runs of bark-coloured pixels (or pixels much
    redder and less green than the tree's median) that reach the mask's lowest rows near
    its foot, at least 1.5 times as tall as wide and textured, cut where they widen into
    the crown (the rules of :func:`segment_tree`'s trunk). A red or orange autumn crown
    is not upright and does not stand on the foot, so it stays out; a "trunk" whose
    median width passes 30 % of the crown's widest row, or that covers 30 % of the mask, is none, and runs shorter than
    :data:`MIN_TRUNK` of the tree's height (fence boards, stakes) are dropped. With ``ground`` (the
    photo's :func:`ground_line`), a trunk that the mask missed below the crown is found
    too: such runs outside the mask that touch it, stand on the ground line, lie within 10 %
    of the width from the mask's foot, below the mask's lowest pixel in their columns, are
    at most 30 % as wide as the crown and, with a ``focus`` map, at least half as sharp as
    the crown (a trunk of a blurred tree behind is not this tree's).

    Parameters
    ----------
    image : ndarray, shape (H, W, 3), uint8
    mask : ndarray, shape (H, W), bool
    ground : ndarray, shape (W,), int, optional
    focus : ndarray, shape (H, W), optional
        Local sharpness and contrast (:func:`treeform.learn.infer.focus_map` with ``relative=False``).

    Returns
    -------
    ndarray, shape (H, W), bool
        Trunk pixels: inside ``mask``, or outside it where ``ground`` is given (none when
        the mask is empty or no trunk stands).
    """
    img = _check_image(image)
    m = np.asarray(mask, bool)
    if m.shape != img.shape[:2]:
        raise InputError(f"mask: expected shape {img.shape[:2]}, got {m.shape}")
    if not m.any():
        return m.copy()
    F = _features(img)
    trunk = _trunk_in_mask(F, m)
    if ground is not None:
        h, w = m.shape
        g = np.asarray(ground, np.int32).reshape(-1)
        if g.shape != (w,):
            raise InputError(f"ground: expected {w} rows (one per column), got shape {g.shape}")
        ys, xs = np.nonzero(m)
        foot = ys >= ys.max() - max(2, int(0.05 * (ys.max() - ys.min() + 1)))
        cand = (~_sky_mask(F) & (np.arange(h)[:, None] < g[None, :])) | m
        standing, _ = _find_trunk(F, cand, g, int(np.median(xs[foot])), near=m, max_offset=0.1)
        # a trunk the mask missed lies below the crown (not in its gaps or beside it), and is far
        # narrower than the crown: a wider piece is ground or rock
        n, lab, st, _ = cv2.connectedComponentsWithStats((standing & ~m).astype(np.uint8), connectivity=8)
        lowest = np.where(m.any(0), h - 1 - np.argmax(m[::-1], axis=0), h)
        under = np.bincount(lab.ravel(), weights=(np.arange(h)[:, None] > lowest[None, :]).ravel(), minlength=n)
        bad = (st[:, cv2.CC_STAT_WIDTH] > 0.3 * m.sum(1).max()) | (under < 0.8 * st[:, cv2.CC_STAT_AREA])
        if focus is not None:
            sharp = 0.5 * float(np.median(focus[m]))
            bad |= np.array([k > 0 and np.median(focus[lab == k]) < sharp for k in range(n)])
        bad[0] = False
        trunk |= standing & ~bad[lab]
    # a run standing for under MIN_TRUNK of the tree's height cannot be told from a fence post, a
    # stake or a hedge's stems
    rows = np.flatnonzero(m.any(1))
    n, lab, st, _ = cv2.connectedComponentsWithStats(trunk.astype(np.uint8), connectivity=8)
    tall = st[:, cv2.CC_STAT_HEIGHT] >= MIN_TRUNK * (rows[-1] - rows[0] + 1)
    tall[0] = False
    trunk = tall[lab]
    widths = trunk.sum(1)
    if trunk.any() and (np.median(widths[widths > 0]) > 0.3 * m.sum(1).max() or trunk.sum() > 0.3 * m.sum()):
        trunk[:] = False  # as wide as the crown, or most of it: bark-coloured leaves (an autumn crown)
    return trunk


def _trunk_in_mask(F: dict, mask: np.ndarray) -> np.ndarray:
    """Trunk of a given tree mask: :func:`_find_trunk` with the ground taken as the
    mask's lowest row in each column and the axis at the mask's foot."""
    h, w = mask.shape
    ys, xs = np.nonzero(mask)
    foot = ys >= ys.max() - max(2, int(0.05 * (ys.max() - ys.min() + 1)))
    ax = int(np.median(xs[foot]))
    has = mask.any(0)
    g = np.where(has, h - np.argmax(mask[::-1], axis=0), h).astype(np.int32)
    trunk, _ = _find_trunk(F, mask, g, ax)
    return trunk & mask
