"""Every tree of a photo, one instance each (issue 16 item 2; seed 003 Fig. 16 crops them by hand).

:func:`find_tree_instances` runs the learned segmenter over the whole photo and over windows
of it (:func:`all_trees_probability`: the network keeps one main tree per view), groups the
pieces of the tree mask into clusters (pieces closer than :data:`~treeform.segment.learned.LINK` of the long side, as a
crown seen through gaps falls apart), and splits each cluster at its trunks:

- a **trunk** rises from a lowest point of the cluster (a foot: nothing of the cluster below
  it nearby, and not above the photo's ground line) as wood or as a long narrow run of the
  mask, or is tall upright wood low in the cluster standing in undergrowth, its foot then on
  the ground line below it (:func:`trunk_feet`); a hanging twig, a crown's lobe or a branch
  has neither, or has more of its tree below it;
- or (``feet='learned'`` / ``'both'``) a trunk's foot is a peak of the learned foot detector's
  heatmap (:class:`~treeform.learn.infer.FeetDetector`, CenterNet-style), moved to the lowest
  point of the mask below it (:func:`snap_feet`); 'learned' uses the rules only in clusters with
  no learned foot, 'both' takes the feet of either (:data:`FEET_METHODS`);
- two trunks or more in one cluster: the cluster is split between them, each pixel going to
  the trunk nearest it inside the mask (:func:`split_at_trunks`);
- each instance's **base** is its trunk's foot (the pixel where the tree meets the ground), followed
  down the photo to where the bark ends (:func:`trunk_end`: the mask loses the last rows of a thin
  trunk), or, without a trunk, the bottom centre of its mask; its top is its highest row;
- instances lower than ``min_height`` of the photo or smaller than ``min_area`` go, and so do
  blurred ones (median sharpness below ``focus_ratio`` of the sharpest instance's: trees far
  behind, out of focus).

Functions over arrays; the networks are :class:`~treeform.learn.infer.Segmenter` and
:class:`~treeform.learn.infer.FeetDetector`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from treeform._shared.errors import InputError, NoTreeFoundError
from treeform.segment.learned_feet import snap_feet, union_feet

__all__ = ["TreeInstance", "find_tree_instances", "all_trees_probability", "split_at_trunks", "trunk_feet",
           "merge_joined_feet", "snap_feet", "run_at", "trunk_end", "FEET_METHODS", "DEFAULT_FEET", "FEET_THRESHOLD"]

FEET_METHODS = ("rules", "learned", "both")
"""Where ``find_tree_instances`` takes the trunks' feet from: the mask's rules (:func:`trunk_feet`), the
learned foot detector's peaks snapped to the mask (:func:`snap_feet`), or both (a foot found by either)."""

DEFAULT_FEET = "both"
"""The default of :data:`FEET_METHODS` (``treeform reconstruct --all-trees``): on the composites of
``benchmarks/bench_scene.py`` it finds 108 / 115 and 113 / 124 trees (seeds 0 and 1) where the rules
find 104 and 107, with as many false trees; see BENCHMARKS.md."""

FEET_THRESHOLD = {"learned": 0.4, "both": 0.5}
"""Lowest heatmap peak taken as a foot, by :data:`FEET_METHODS` entry. 'both' asks more: its learned
feet add to the rules' (at 0.4 they added trees on hedges and lawns of real photos), while
'learned' replaces them (at 0.5 it finds 96 instead of 103 of the 115 trees of seed 0)."""

NARROW = 0.12
"""A trunk's rows are at most this share of its cluster's height."""

JOIN_DEPTH = 0.05
"""Two lowest points of a cluster within a trunk's width of each other are one trunk's foot only
if the mask joins them within this share of the cluster's height above them."""

GROUND_TOLERANCE = 0.01
"""A foot may stand this share of the photo's height above the ground line
(:func:`~treeform.segment.classical.ground_line`) in its column, not more."""

TRUNK_END = 0.01
""":func:`trunk_end` follows a trunk at most this share of the photo's height below the mask's foot."""


@dataclass
class TreeInstance:
    """One tree of a photo: its pixels, box, the pixel of its foot and its top row."""

    mask: np.ndarray
    """(H, W) bool, this tree's pixels."""
    box: tuple
    """(y0, y1, x0, x1) of the mask, end-exclusive."""
    base: tuple
    """(u, v): column and row of the trunk's foot (v: the ground contact, y down)."""
    top: int
    """The highest row of the mask."""
    trunk: bool
    """Whether ``base`` is a trunk's foot found in the mask (else the mask's bottom centre)."""

    @property
    def height_px(self) -> float:
        return float(self.base[1] - self.top + 1)


def _runs(mask: np.ndarray) -> np.ndarray:
    """(H, W) width of the horizontal run of ``mask`` each pixel belongs to (0 outside)."""
    import scipy.ndimage as ndi

    lab, n = ndi.label(mask, structure=[[0, 0, 0], [1, 1, 1], [0, 0, 0]])
    if n == 0:
        return np.zeros(mask.shape, np.int64)
    width = np.bincount(lab.ravel())
    width[0] = 0
    return width[lab]


def run_at(row: np.ndarray, lo: int, hi: int):
    """The run of True in ``row`` overlapping [lo, hi] most, as (lo, hi) inclusive, or None.

    The run holds the covered pixel of [lo - 1, hi + 1] nearest the middle of [lo, hi].

    >>> [int(x) for x in run_at(np.array([0, 1, 1, 0, 0, 1, 1, 1, 0], bool), 4, 4)]
    [5, 7]
    >>> run_at(np.array([0, 1, 1, 0, 0, 0, 0, 1, 0], bool), 4, 4) is None
    True
    """
    seg = row[max(0, lo - 1):hi + 2]
    if not seg.any():
        return None
    idx = np.flatnonzero(seg) + max(0, lo - 1)
    c = idx[np.argmin(np.abs(idx - 0.5 * (lo + hi)))]  # the covered pixel nearest the previous run's centre
    left = c
    while left > 0 and row[left - 1]:
        left -= 1
    right = c
    while right < len(row) - 1 and row[right + 1]:
        right += 1
    return left, right


def trunk_feet(mask: np.ndarray, wood: np.ndarray | None = None, *, ground: np.ndarray | None = None,
               narrow: float = NARROW, min_stem: float = 0.05) -> list[tuple]:
    """Trunks standing in one cluster of a tree mask, as (marker mask, (u, v) foot) pairs.

    A foot is a lowest point of the cluster (nothing of it below, in a neighbourhood of 1 % of
    its width) from which a trunk rises: with ``wood`` (the network's wood pixels), wood
    connected to the foot rises at least ``min_stem`` x the cluster's height above it (within
    ``narrow`` x that height of the foot's column: a trunk, also one whose crown comes down to
    the ground, as a pine's); or, traced upward row by row, the run of the mask above the foot
    stays narrow (at most ``narrow`` x the height) for at least three times that (a trunk the
    network called foliage). A crown's hanging lobe or twig has little wood rising from it and
    widens into the crown soon; a branch of a bare tree has more of the tree below it.

    Parameters
    ----------
    mask : ndarray, shape (H, W), bool
        One cluster (one tree or several touching ones).
    wood : ndarray, shape (H, W), bool, optional
    ground : ndarray, shape (W,), optional
        The first ground row of each column (``H``: none;
        :func:`~treeform.segment.classical.ground_line`). A tree stands on the ground: a lowest
        point more than :data:`GROUND_TOLERANCE` x H above it in its column (a crown's lobe
        hanging over the sky or the ground behind) is no foot; a trunk of upright wood that ends
        above it (in undergrowth that hides its foot) stands on the ground line below.
    narrow, min_stem : float

    Returns
    -------
    list of (ndarray (H, W) bool, (float, float))
        Left to right; the marker is the traced stem and the wood connected to it within
        ``narrow`` x height of the foot's column.

    Examples
    --------
    Two crowns on two trunks, touching:

    >>> m = np.zeros((60, 80), bool); m[5:30, 5:45] = True; m[8:32, 35:75] = True
    >>> m[30:55, 23:27] = True; m[32:50, 53:57] = True
    >>> [foot for _, foot in trunk_feet(m)]
    [(24.5, 54.0), (54.5, 49.0)]
    """
    import scipy.ndimage as ndi

    mask = np.asarray(mask, bool)
    if mask.ndim != 2:
        raise InputError(f"mask: expected an (H, W) array, got shape {mask.shape}")
    rows = np.flatnonzero(mask.any(1))
    if rows.size == 0:
        return []
    cols = np.flatnonzero(mask.any(0))
    height = float(rows[-1] - rows[0] + 1)
    narrow_px = max(3.0, narrow * height)
    H, W = mask.shape
    bottom = np.where(mask.any(0), H - 1 - np.argmax(mask[::-1], axis=0), -1).astype(np.float64)
    d = max(2, int(round(0.01 * (cols[-1] - cols[0] + 1))))
    local = ndi.maximum_filter1d(bottom, 2 * d + 1, mode="constant", cval=-1)
    is_low = (bottom >= 0) & (bottom >= local)
    wood_lab = ndi.label(wood & mask, structure=np.ones((3, 3)))[0] if wood is not None else None
    feet = []
    edges = np.flatnonzero(np.diff(np.r_[0, is_low.astype(np.int8), 0]))
    for a, b in zip(edges[::2], edges[1::2]):  # plateaus of lowest columns [a, b)
        seg = np.arange(a, b)
        v = int(bottom[seg].max())
        seg = seg[bottom[seg] == v]
        u = int(seg[len(seg) // 2])
        run = run_at(mask[v], u, u)
        stem = []
        r = v
        while run is not None and run[1] - run[0] + 1 <= narrow_px and r >= rows[0]:
            stem.append((r, run[0], run[1]))
            r -= 1
            run = run_at(mask[r], *run) if r >= 0 else None
        marker = np.zeros_like(mask)
        for rr, lo, hi in stem:
            marker[rr, lo:hi + 1] = True
        rise, touching = 0, np.zeros(0, np.int64)
        if wood_lab is not None:
            k = max(3, int(round(0.03 * height)))
            lo, hi = int(u - narrow_px / 2), int(u + narrow_px / 2) + 1
            touching = np.unique(wood_lab[max(0, v - k):v + 1, max(0, lo):hi])
            touching = touching[touching > 0]
            if touching.size:  # the trunk goes on up as wood; its branches spreading sideways are left out
                band = np.zeros_like(mask)
                band[:, max(0, int(u - narrow_px)):int(u + narrow_px) + 1] = True
                up = np.isin(wood_lab, touching) & band
                rise = v - int(np.flatnonzero(up.any(1))[0])
                marker |= up
        # a trunk: wood rising from the foot, or a long narrow stem (a trunk the network called foliage);
        # a hanging twig or a crown's lobe has neither
        if ground is not None and ground[u] < H and v < ground[u] - GROUND_TOLERANCE * H:
            continue
        if rise >= min_stem * height or len(stem) >= 3 * min_stem * height:
            if marker.any():
                feet.append((marker, (float(seg.mean()), float(v)), set(touching.tolist())))
    if wood_lab is not None:  # trunks standing in undergrowth: tall, upright, narrow wood, low in the cluster
        for k, sl in enumerate(ndi.find_objects(wood_lab), start=1):
            if sl is None:
                continue
            comp = wood_lab[sl] == k
            h_k, w_k = comp.shape
            widths = comp.sum(1)
            y1 = sl[0].stop - 1
            if (h_k < 0.2 * height or h_k < 2 * w_k or np.median(widths[widths > 0]) > narrow_px
                    or y1 < rows[0] + 0.65 * height):
                continue
            u = float(np.flatnonzero(comp[-1]).mean()) + sl[1].start
            if any(abs(u - f[0]) <= narrow_px for _, f, _ in feet):
                continue
            full = np.zeros_like(mask)
            full[sl] = comp
            g = ground[int(round(u))] if ground is not None else H
            foot_v = float(g) if g < H and y1 < g - GROUND_TOLERANCE * H else float(y1)
            feet.append((full, (u, foot_v), {k}))
    # a branch's end whose wood runs on to a lower foot is that tree's branch, not a tree of its own
    feet = [(m, f) for m, f, w in feet
            if not any(w & w2 and f2[1] > f[1] + 1 for _, f2, w2 in feet)]
    return merge_joined_feet(mask, feet, narrow=narrow)


def merge_joined_feet(mask: np.ndarray, feet: list, *, narrow: float = NARROW, fixed: int = 0) -> list[tuple]:
    """Feet ``(marker, (u, v))`` of one cluster, those of one trunk made one, left to right.

    Two lowest points of one trunk's foot (a root flare, a fork at the ground, or a rule's foot
    and the detector's a little aside on a wide trunk) are one foot: at most ``narrow`` x the
    cluster's height apart and joined by the mask within :data:`JOIN_DEPTH` x that height above
    them (:func:`_joined_low`); two trunks side by side stand apart there. The markers join; the
    foot that stays is the lower one, or, where one of the two is among the first ``fixed`` of
    ``feet`` (the rules' feet, the learned detector's after them) and the other is not, that one
    unless the other stands more than :data:`JOIN_DEPTH` x the height lower: the detector saw the
    trunk go on down where the mask lost its lowest part (a thin trunk over a lawn).

    >>> m = np.zeros((60, 80), bool); m[5:30, 5:45] = True; m[30:55, 22:26] = True; m[50:55, 20:29] = True
    >>> a, b = np.zeros_like(m), np.zeros_like(m); a[50:55, 20:23] = True; b[50:55, 26:29] = True
    >>> [f for _, f in merge_joined_feet(m, [(a, (21.0, 54.0)), (b, (27.0, 54.0))])]   # one flared trunk
    [(21.0, 54.0)]
    """
    rows = np.flatnonzero(np.asarray(mask, bool).any(1))
    if rows.size == 0:
        return []
    height = float(rows[-1] - rows[0] + 1)
    narrow_px = max(3.0, narrow * height)
    depth = max(3, int(round(JOIN_DEPTH * height)))
    merged: list = []  # (marker, foot, fixed)
    order = sorted(range(len(feet)), key=lambda i: feet[i][1][0])
    for comp, foot, fix in ((feet[i][0], feet[i][1], i < fixed) for i in order):
        if merged and abs(foot[0] - merged[-1][1][0]) <= narrow_px and _joined_low(mask, merged[-1][1], foot, depth):
            prev, pfoot, pfix = merged[-1]
            keep = pfoot if pfoot[1] >= foot[1] else foot  # the lower one
            if pfix != fix and abs(pfoot[1] - foot[1]) <= depth:
                keep = pfoot if pfix else foot
            merged[-1] = (prev | comp, keep, pfix or fix)
        else:
            merged.append((comp, foot, fix))
    return [(comp, foot) for comp, foot, _ in merged]


def _joined_low(mask: np.ndarray, f1: tuple, f2: tuple, depth: int) -> bool:
    """Whether two feet ``(u, v)`` are one piece of ``mask`` within ``depth`` rows above the higher
    one (8-connected, in the band of rows from there down to the lower foot).

    >>> m = np.zeros((40, 40), bool); m[5:38, 10:13] = True; m[5:38, 25:28] = True; m[5:10, 10:28] = True
    >>> _joined_low(m, (11.0, 37.0), (26.0, 37.0), 4)    # two stems joined only 28 rows up: two trunks
    False
    >>> m[33:36, 10:28] = True                            # a flare joins them 2 rows above the feet
    >>> _joined_low(m, (11.0, 37.0), (26.0, 37.0), 4)
    True
    """
    import scipy.ndimage as ndi

    H, W = mask.shape
    top = max(0, int(min(f1[1], f2[1])) - depth)
    bot = min(H - 1, int(max(f1[1], f2[1])))
    lab, _ = ndi.label(mask[top:bot + 1], structure=np.ones((3, 3)))

    def piece(f):
        u = int(np.clip(round(f[0]), 0, W - 1))
        cols = lab[:, max(0, u - 1):u + 2]  # the foot's column (a pixel either side), lowest labelled pixel
        hit = np.flatnonzero(cols.max(1) > 0)
        return int(cols[hit[-1]].max()) if hit.size else 0

    a, b = piece(f1), piece(f2)
    return a > 0 and a == b


def split_at_trunks(mask: np.ndarray, trunks: list, *, within: np.ndarray | None = None) -> list[np.ndarray]:
    """Split one cluster between its trunks: each pixel goes to the trunk nearest it inside the mask.

    The trunks' markers grow together, one pixel ring at a time, through the cluster (a
    watershed of a flat relief: a geodesic Voronoi partition), so two crowns that touch part
    along the line halfway between their trunks. A thin trunk and a thick one grow alike (a
    watershed of the distance transform lets the trunk that reaches deepest into the crowns
    take them all). With ``within`` (a region holding the mask, e.g. the mask dilated by a few
    pixels) they grow through that region, so a gap the mask left between a thin trunk and its
    crown does not hand that crown to the neighbour's trunk; the parts are the mask's pixels.
    With fewer than two trunks the cluster is one tree.

    >>> m = np.zeros((60, 80), bool); m[5:30, 5:45] = True; m[8:32, 35:75] = True
    >>> m[30:55, 23:27] = True; m[32:50, 53:57] = True
    >>> parts = split_at_trunks(m, trunk_feet(m))
    >>> [int(p.sum()) for p in parts], bool(parts[0][20, 10] and parts[1][20, 70])
    ([1009, 903], True)
    """
    from skimage.segmentation import watershed

    mask = np.asarray(mask, bool)
    if len(trunks) < 2:
        return [mask]
    markers = np.zeros(mask.shape, np.int32)
    for k, (comp, _) in enumerate(trunks, start=1):
        markers[comp & mask & (markers == 0)] = k
    grow = mask if within is None else (np.asarray(within, bool) | mask)
    lab = watershed(np.zeros(mask.shape, np.float32), markers, mask=grow)
    return [(lab == k) & mask for k in range(1, len(trunks) + 1)]


def _windows(length: int, side: int, stride: float) -> np.ndarray:
    """Starts of windows of ``side`` along ``length`` at most ``stride`` apart, the last flush with the end."""
    if length <= side:
        return np.zeros(1, np.int64)
    return np.unique(np.linspace(0, length - side, int(np.ceil((length - side) / stride)) + 1).round().astype(np.int64))


def all_trees_probability(img: np.ndarray, seg_net) -> tuple[np.ndarray, np.ndarray]:
    """(H, W) probabilities that a pixel is any tree, not only the photo's main one, and that it is wood.

    The network was trained to keep one tree per photo (the main one; neighbours at the frame's
    edges and trees behind are background), so each tree must be the main one of some view: the
    photo is seen whole, by squares of its short side (a quarter of their side apart) and by
    squares of 0.6 of it (half their side apart), and each pixel keeps its highest tree (and
    wood) probability over the views that hold it.
    """
    H, W = img.shape[:2]
    p = seg_net.probabilities(img)
    acc, wood = 1.0 - p[..., 0], p[..., 2].copy()
    for frac, step in ((1.0, 0.25), (0.6, 0.5)):
        side = max(8, int(round(frac * min(H, W))))
        for y in _windows(H, side, step * side):
            for x in _windows(W, side, step * side):
                if side >= max(H, W):  # the whole photo, seen already
                    continue
                p = seg_net.probabilities(img[y:y + side, x:x + side])
                np.maximum(acc[y:y + side, x:x + side], 1.0 - p[..., 0], out=acc[y:y + side, x:x + side])
                np.maximum(wood[y:y + side, x:x + side], p[..., 2], out=wood[y:y + side, x:x + side])
    return acc, wood


def trunk_end(image: np.ndarray, mask: np.ndarray, foot, *, max_rows: int) -> tuple[float, float]:
    """The foot of a trunk moved down the photo to where its bark meets the ground.

    The mask's lowest point is where the segmenter stopped, and it loses the last rows of a thin
    trunk against the lawn (at a scale where the trunk is 2-3 pixels wide, its lowest 2-4 rows).
    The trunk's colour (median of the mask's pixels in the 6 rows above the foot, within 3
    columns) and the ground's (median of the pixels outside the mask 4-10 columns to either
    side, from 3 rows above the foot down) are compared row by row below the foot: the foot
    moves down while one of the three pixels under it (it may drift a column per row) is nearer
    the trunk's colour than the ground's, for at most ``max_rows`` rows. Where the two colours
    are within 25 (RGB distance), or too few pixels tell them, the foot stays.

    Parameters
    ----------
    image : ndarray, shape (H, W, 3), uint8
    mask : ndarray, shape (H, W), bool
        The tree's pixels.
    foot : (u, v)
        Column and row of the mask's foot.
    max_rows : int

    Returns
    -------
    (u, v) : the foot at the trunk's end.

    Examples
    --------
    A brown trunk two pixels wide on a green lawn; the mask stops 3 rows above its end:

    >>> img = np.zeros((30, 30, 3), np.uint8); img[:] = (60, 140, 50); img[2:20, 14:16] = (120, 100, 80)
    >>> m = np.zeros((30, 30), bool); m[2:17, 14:16] = True
    >>> trunk_end(img, m, (14.5, 16.0), max_rows=6)
    (14.5, 19.0)
    >>> trunk_end(img, m, (14.5, 16.0), max_rows=2)
    (14.5, 18.0)
    """
    img = np.asarray(image, np.float32)
    H, W = mask.shape
    u, v = float(foot[0]), float(foot[1])
    iu, iv = int(round(u)), int(round(v))
    if not (0 <= iu < W and 0 <= iv < H) or max_rows < 1:
        return (u, v)
    y0, x0, x1 = max(0, iv - 5), max(0, iu - 3), min(W, iu + 4)
    near = mask[y0:iv + 1, x0:x1]
    if near.sum() < 4:
        return (u, v)
    trunk = np.median(img[y0:iv + 1, x0:x1][near], axis=0)
    ya, yb = max(0, iv - 3), min(H, iv + 1 + int(max_rows))
    xa, xb = max(0, iu - 10), min(W, iu + 11)
    cols = np.arange(xa, xb)
    side = (np.abs(cols - iu) >= 4)[None, :] & ~mask[ya:yb, xa:xb]  # beside the trunk, off the mask
    if side.sum() < 8:
        return (u, v)
    ground = np.median(img[ya:yb, xa:xb][side], axis=0)
    if np.linalg.norm(trunk - ground) < 25.0:
        return (u, v)
    col, last = iu, iv
    for r in range(iv + 1, yb):
        cs = np.array([c for c in (col, col - 1, col + 1) if 0 <= c < W])  # straight down wins a tie
        px = img[r, cs]
        margin = np.linalg.norm(px - ground, axis=1) - np.linalg.norm(px - trunk, axis=1)
        k = int(np.argmax(margin))
        if margin[k] <= 0:
            break
        col, last = int(cs[k]), r
    return (u + (col - iu), float(last))


def _instance(mask: np.ndarray, foot) -> TreeInstance:
    """The instance of ``mask`` standing on ``foot`` (a trunk's), or, with None, on its bottom centre.

    >>> m = np.zeros((10, 10), bool); m[2:8, 3:7] = True
    >>> t = _instance(m, None); t.trunk, t.base, t.top
    (False, (4.5, 7.0), 2)
    >>> _instance(m, (5.0, 7.0)).trunk
    True
    """
    ys, xs = np.nonzero(mask)
    y0, y1, x0, x1 = int(ys.min()), int(ys.max()) + 1, int(xs.min()), int(xs.max()) + 1
    trunk = foot is not None
    if not trunk:
        low = ys >= y1 - 1 - max(1, round(0.03 * (y1 - y0)))
        foot = (float(np.median(xs[low])), float(y1 - 1))
    return TreeInstance(mask, (y0, y1, x0, x1), (float(foot[0]), float(foot[1])), y0, trunk)


def find_tree_instances(image: np.ndarray, *, weights=None, min_height: float = 0.12, min_area: float = 0.004,
                        focus_ratio: float = 0.35, ground: bool = False, feet: str = DEFAULT_FEET,
                        feet_weights=None, feet_threshold: float | None = None) -> list[TreeInstance]:
    """Every tree of an RGB photo as its own mask with the pixel of its foot, left to right.

    Parameters
    ----------
    image : ndarray, shape (H, W, 3), uint8
    weights : path, optional
        Segmentation ONNX weights (default: the shipped ones).
    min_height : float
        Instances lower than this share of the photo's height are dropped.
    min_area : float
        Instances smaller than this share of the photo are dropped.
    focus_ratio : float
        Instances whose median sharpness is below this share of the sharpest one's are
        dropped (out-of-focus trees far behind).
    ground : bool
        Cut what the mask holds below the photo's ground line but for the trunks' feet
        (:func:`~treeform.segment.learned.stand_on_ground`).
    feet : {'rules', 'learned', 'both'}
        Where each cluster's trunks' feet come from (:data:`FEET_METHODS`): the mask's rules
        (:func:`trunk_feet`), the learned foot detector
        (:class:`~treeform.learn.infer.FeetDetector`, its peaks snapped to the mask by
        :func:`snap_feet`; a cluster without a learned foot falls back to the rules), or both.
    feet_weights : path, optional
        Foot-detector ONNX weights (default: the shipped ``feet.onnx``).
    feet_threshold : float, optional
        Lowest heatmap peak taken as a foot (default: :data:`FEET_THRESHOLD` of ``feet``).

    Returns
    -------
    list of TreeInstance

    Raises
    ------
    InputError
        ``image`` is not an (H, W, 3) uint8 array of at least 8 x 8 pixels, or ``feet`` is unknown.
    ModelError
        The foot detector's weights are missing or unreadable (with ``feet`` other than 'rules').
    NoTreeFoundError
        No instance is left.
    """
    import scipy.ndimage as ndi

    from treeform.learn.infer import Segmenter, focus_map
    from treeform.segment.learned import LINK, snap_to_edges, stand_on_ground

    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
        raise InputError(f"image: expected an (H, W, 3) uint8 RGB array, got shape {img.shape} {img.dtype}")
    if min(img.shape[:2]) < 8:
        raise InputError(f"image: expected at least 8 x 8 pixels, got {img.shape[1]} x {img.shape[0]}")
    if feet not in FEET_METHODS:
        raise InputError(f"feet: expected one of {', '.join(FEET_METHODS)}, got {feet!r}")
    if feet_threshold is None:
        feet_threshold = FEET_THRESHOLD.get(feet, 0.5)
    if not 0.0 < float(feet_threshold) < 1.0:
        raise InputError(f"feet_threshold: expected a probability in (0, 1), got {feet_threshold!r}")
    H, W = img.shape[:2]
    seg_net = Segmenter(weights)
    peaks = None
    if feet != "rules":
        from treeform.learn.infer import FeetDetector

        peaks = FeetDetector(feet_weights).detect(img, threshold=feet_threshold)
    from treeform.segment.classical import ground_line

    p_any, p_wood = all_trees_probability(img, seg_net)
    p_tree = snap_to_edges(img, p_any, seg_net.side)
    tree = p_tree > 0.5
    wood = p_wood > 0.5 * p_any  # wood more likely than foliage
    g = ground_line(img)
    if ground:
        tree = stand_on_ground(tree, g)
    specks, n_sp = ndi.label(tree, structure=np.ones((3, 3)))  # specks go; a trunk one pixel wide stays whole
    if n_sp:
        area = np.bincount(specks.ravel())
        area[0] = 0
        tree = area[specks] >= max(4, 2e-5 * H * W)
    r = max(1, int(round(LINK * max(H, W))))
    import cv2

    near = cv2.dilate(tree.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1,) * 2))
    grown, n = ndi.label(near, structure=np.ones((3, 3)))  # each cluster and the LINK radius around it
    clusters = np.where(tree, grown, 0)
    learned = snap_feet(tree, peaks) if peaks is not None else []
    found = []
    for k in range(1, n + 1):
        cl = clusters == k
        if cl.sum() < min_area * H * W:
            continue
        mine = [t for t in learned if (clusters[t[0]] == k).any()]
        if feet == "learned" and mine:
            trunks = [(m & cl, f) for m, f, _ in mine]
        else:
            trunks = trunk_feet(cl, wood, ground=g)
            if feet == "both" and mine:
                # one trunk's feet by the rules and by the detector (a wide trunk's flare) are one
                trunks = merge_joined_feet(cl, union_feet(trunks, [(m & cl, f, sc) for m, f, sc in mine],
                                                          max(2.0, 0.012 * W), max(2.0, 0.02 * H)),
                                           fixed=len(trunks))
        if len(trunks) >= 2:
            parts = split_at_trunks(cl, trunks, within=grown == k)  # across the gaps the clustering bridges
            found += [(part, foot) for part, (_, foot) in zip(parts, trunks) if part.any()]
        else:
            found.append((cl, trunks[0][1] if trunks else None))
    # the mask loses the last rows of a thin trunk: each trunk's foot goes down to the bark's end
    # (bench_scene.py: trees placed within 0.1 of their spacing 96 -> 98 %; BENCHMARKS.md)
    reach = max(2, int(round(TRUNK_END * H)))
    inst = [_instance(m, None if foot is None else trunk_end(img, m, foot, max_rows=reach)) for m, foot in found]
    inst = [t for t in inst if t.height_px >= min_height * H and t.mask.sum() >= min_area * H * W]
    if len(inst) > 1 and focus_ratio > 0:
        focus = focus_map(img, seg_net.side)
        sharp = np.array([float(np.median(focus[t.mask])) for t in inst])
        inst = [t for t, s in zip(inst, sharp) if s >= focus_ratio * sharp.max()]
    if not inst:
        raise NoTreeFoundError("no tree found in the photo")
    return sorted(inst, key=lambda t: t.base[0])
