"""Season transfer: the colours of a photographed tree onto an exemplar (seed 000 §5.3).

§5.3 matches the histogram of each colour channel of a generated tree to a reference
image [GW07]. Taken literally over a whole photo, the reference histogram is mostly sky
and lawn: the blue channel's upper quantiles are sky, so a green crown came out cyan,
and the trunk, whose red and blue values are the highest of a green tree, was mapped
onto the sky and clouds and came out purple. Here the reference is the *tree* in the
photo, and crown and trunk are matched separately:

1. :func:`season_reference` segments the photo (:func:`treeform.segment.segment`;
   labels 0 background, 1 foliage, 2 wood) and splits the tree into its **trunk**, the
   wood standing at the foot of the tree, under it, and its **crown**, the rest of the tree
   less the sky seen through gaps in it (:func:`treeform.segment.matting.sky_gaps`).
   The crown keeps the wood labelled inside it (branches, and the red or orange leaves
   that the bark colour model also calls wood), as an exemplar's crown keeps its
   branches. A trunk smaller than ``min_trunk`` of the tree counts as not visible.
2. :func:`season_transfer` maps each channel of the exemplar's crown pixels onto the
   photo's crown, quantile to quantile, and its trunk pixels onto the photo's trunk;
   when the photo shows no trunk, the exemplar's trunk keeps its colours.

The channels are those of CIE L*a*b* by default (``space='lab'``): R, G and B are
strongly correlated (all three follow the lighting), and matching each one's ranks on its
own sends a pixel that is, say, high in R and B but middling in G to a colour no leaf
has; greyish stems and shaded leaves come out pink or purple. L*, a* and b* separate
lightness from the two opponent colour axes, so each quantile map moves one perceptual
property. On the cesium tree, with the yellow mulberry and the green maple
(Morus_rubra_1, Acer_rubrum_2), 5 % and 0.7 % of the crown's pixels end up pink, purple
or blue in L*a*b*, 13 % and 22 % in RGB. ``space='rgb'`` is the paper's transfer.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from treeform._shared.defaults import DEFAULT_SEGMENTER
from treeform._shared.checks import check_choice
from treeform._shared.errors import InputError, NoTreeFoundError

__all__ = ["SeasonReference", "season_reference", "season_transfer", "crown_trunk_labels", "quantile_map", "mean_hue",
           "SPACES"]

SPACES = ("lab", "rgb")
"""Colour spaces :func:`season_transfer` matches channels in."""

_MIN_PIXELS = 50
_STEM_HEIGHT = 0.05  # a trunk component spans at least this fraction of the tree's height
_FOOT = 0.05  # ... and reaches into the lowest 5 % of the tree


@dataclass
class SeasonReference:
    """The colours of a photographed tree, split into crown and trunk.

    Attributes
    ----------
    crown : ndarray, shape (P, 3), uint8
        RGB of the photo's crown pixels.
    trunk : ndarray, shape (Q, 3), uint8, or None
        RGB of its trunk pixels; None when too little trunk is visible (the exemplar's
        trunk then keeps its colours).
    labels : ndarray, shape (H, W), uint8
        Where they came from: 0 not used (background, sky gaps), 1 crown, 2 trunk.
    """

    crown: np.ndarray
    trunk: np.ndarray | None
    labels: np.ndarray

    @property
    def has_trunk(self) -> bool:
        return self.trunk is not None


def _check_image(image) -> np.ndarray:
    a = np.asarray(image)
    if a.ndim != 3 or a.shape[2] not in (3, 4) or a.dtype != np.uint8:
        raise InputError(f"reference: expected an (H, W, 3) photo or (H, W, 4) RGBA uint8 image, "
                         f"got {a.shape} {a.dtype}")
    if min(a.shape[:2]) < 8:
        raise InputError(f"reference: image too small ({a.shape[1]}x{a.shape[0]} px)")
    return a


def _trunk(wood: np.ndarray, tree: np.ndarray) -> np.ndarray:
    """The trunk: wood components that reach the lowest 5 % of the tree, span >= 5 % of its
    height and stand under it (centroid between the 20th and 80th percentile of the tree's
    columns; off-centre "wood" at a tree's foot is a fence post, a path, a dry shrub)."""
    ys, xs = np.nonzero(tree)
    y1 = int(ys.max())
    height = y1 - int(ys.min()) + 1
    left, right = np.percentile(xs, [20, 80])
    n, lab, st, centre = cv2.connectedComponentsWithStats(wood.astype(np.uint8), connectivity=8)
    foot = y1 - max(1, int(round(_FOOT * height)))
    keep = np.zeros(n, bool)
    for k in range(1, n):
        top, h = st[k, cv2.CC_STAT_TOP], st[k, cv2.CC_STAT_HEIGHT]
        keep[k] = top + h - 1 >= foot and h >= _STEM_HEIGHT * height and left <= centre[k, 0] <= right
    return keep[lab]


def season_reference(image, *, segmenter: str = DEFAULT_SEGMENTER, seed: int = 0,
                     min_trunk: float = 0.005) -> SeasonReference:
    """Crown and trunk colours of the tree in a photo (seed 000 §5.3, tree pixels only).

    Parameters
    ----------
    image : ndarray, shape (H, W, 3) or (H, W, 4), uint8
        A photo (segmented with ``segmenter``), or an RGBA tree whose alpha is its mask
        (wood labelled by :func:`treeform.segment.mask_to_segmentation`).
    segmenter : str
        'classical' or 'learned' (:func:`treeform.segment.segment`).
    seed : int
        Seed of the segmentation (same photo + seed -> same reference).
    min_trunk : float
        Smallest trunk, as a fraction of the tree's pixels, that counts as visible.

    Returns
    -------
    SeasonReference

    Raises
    ------
    InputError
        A bad argument.
    NoTreeFoundError
        No tree found, or fewer than 50 crown pixels.
    """
    from treeform.segment import SEGMENTERS, mask_to_segmentation, segment
    from treeform.segment.matting import sky_gaps
    from treeform.structures import Segmentation

    img = _check_image(image)
    check_choice(segmenter, "segmenter", SEGMENTERS)
    if isinstance(min_trunk, bool) or not isinstance(min_trunk, (int, float)) or not 0 <= min_trunk <= 1:
        raise InputError(f"min_trunk: expected a fraction in [0, 1], got {min_trunk!r}")
    rgb = np.ascontiguousarray(img[..., :3])
    cutout = img.shape[2] == 4 and bool((img[..., 3] < 255).any())
    if cutout:
        mask = img[..., 3] >= 128
        if not mask.any():
            raise NoTreeFoundError("reference: no opaque pixel (alpha >= 0.5)")
        seg = mask_to_segmentation(mask, rgb)
    else:
        seg = segment(rgb, method=segmenter, seed=seed)
    tree = seg.tree_mask
    trunk = _trunk(seg.wood_mask, tree)
    if trunk.sum() < min_trunk * tree.sum() or trunk.sum() < _MIN_PIXELS:
        trunk[:] = False
    crown = tree & ~trunk
    if not cutout:  # sky seen through the crown is no colour of the tree
        crown &= ~sky_gaps(rgb, Segmentation(crown.astype(np.uint8)))
    if crown.sum() < _MIN_PIXELS:
        raise NoTreeFoundError(f"reference: too little crown found ({int(crown.sum())} pixels)")
    labels = np.zeros(tree.shape, np.uint8)
    labels[crown] = 1
    labels[trunk] = 2
    return SeasonReference(rgb[crown], rgb[trunk] if trunk.any() else None, labels)


def quantile_map(values, reference) -> np.ndarray:
    """Map values onto a reference distribution, quantile to quantile ([GW07]).

    Each unique source value gets the quantile of the middle of its share of the
    cumulative histogram, and the reference value at that quantile (linear
    interpolation between the reference's sorted values), as in scikit-image's
    ``match_histograms``.

    Parameters
    ----------
    values : ndarray, shape (N,)
    reference : ndarray, shape (M,), M >= 1

    Returns
    -------
    ndarray, shape (N,), float64

    Examples
    --------
    >>> quantile_map(np.array([1.0, 2.0, 3.0, 4.0]), np.array([10.0, 20.0, 30.0, 40.0])).tolist()
    [10.0, 20.0, 30.0, 40.0]
    """
    v = np.asarray(values, np.float64).ravel()
    r = np.sort(np.asarray(reference, np.float64).ravel())
    if r.size == 0:
        raise InputError("reference: no values to match")
    if v.size == 0:
        return v.copy()
    u, inv, cnt = np.unique(v, return_inverse=True, return_counts=True)
    q = (np.cumsum(cnt) - 0.5 * cnt) / cnt.sum()
    rq = (np.arange(r.size) + 0.5) / r.size
    return np.interp(q, rq, r)[inv.ravel()]


def _to_space(rgb8: np.ndarray, space: str) -> np.ndarray:
    f = rgb8.reshape(-1, 3).astype(np.float32) / 255.0
    if space == "lab":
        return cv2.cvtColor(f[None], cv2.COLOR_RGB2LAB)[0].astype(np.float64)
    return f.astype(np.float64)


def _from_space(values: np.ndarray, space: str) -> np.ndarray:
    f = values.astype(np.float32)
    if space == "lab":
        f = cv2.cvtColor(f[None], cv2.COLOR_LAB2RGB)[0]
    return np.clip(np.rint(f * 255.0), 0, 255).astype(np.uint8)


def _match(pixels: np.ndarray, opaque: np.ndarray, reference: np.ndarray, space: str) -> np.ndarray:
    """Per-channel quantile map of ``pixels`` (histogram of the ``opaque`` ones) onto ``reference``."""
    src = _to_space(pixels, space)
    ref = _to_space(reference, space)
    out = np.empty_like(src)
    for c in range(3):
        basis = src[opaque, c]
        u = np.unique(basis)
        mapped = quantile_map(basis, ref[:, c])
        # the map as a function: every unique opaque value -> its reference value;
        # semi-transparent edge pixels interpolate between them
        lut = np.empty(u.size)
        lut[np.searchsorted(u, basis)] = mapped
        out[:, c] = np.interp(src[:, c], u, lut)
    return _from_space(out, space)


def crown_trunk_labels(rgba, labels) -> np.ndarray:
    """The crown / trunk labels :func:`season_transfer` uses: trunk pixels coloured like the
    crown made crown.

    An exemplar's trunk label takes everything below the crown baseline
    (:func:`~.exemplar.split_crown_trunk`), low leaves included: a trunk pixel whose a*b*
    is more than twice as near the crown's median as the trunk's is a leaf, and takes the
    crown's colours.

    Parameters
    ----------
    rgba : ndarray, shape (H, W, 4), uint8
    labels : ndarray, shape (H, W), uint8
        0 background, 1 crown, 2 trunk.

    Returns
    -------
    ndarray, shape (H, W), uint8
    """
    img, lab = np.asarray(rgba), np.asarray(labels)
    crown, trunk = (lab == 1) & (img[..., 3] > 0), (lab == 2) & (img[..., 3] > 0)
    if not crown.any() or not trunk.any():
        return lab
    ab_c = np.median(_to_space(img[crown][:, :3], "lab")[:, 1:], axis=0)
    ys, xs = np.nonzero(trunk)
    ab = _to_space(img[ys, xs, :3], "lab")[:, 1:]
    ab_t = np.median(ab, axis=0)
    leaf = 2.0 * np.linalg.norm(ab - ab_c, axis=1) < np.linalg.norm(ab - ab_t, axis=1)
    out = lab.copy()
    out[ys[leaf], xs[leaf]] = 1
    return out


def season_transfer(rgba, labels, reference: SeasonReference, *, space: str = "lab",
                    threshold: float = 0.5) -> np.ndarray:
    """Give a tree the colours of a photographed tree, crown and trunk apart (seed 000 §5.3).

    Parameters
    ----------
    rgba : ndarray, shape (H, W, 4), uint8
        The tree (an exemplar or a synthesised variation), straight alpha.
    labels : ndarray, shape (H, W), uint8, or None
        0 background, 1 crown, 2 trunk (:attr:`Exemplar.labels`,
        :attr:`Synthesis.labels`); None: every pixel is crown. Trunk pixels coloured
        like the crown (low leaves below the crown baseline) count as crown.
    reference : SeasonReference
        From :func:`season_reference`.
    space : str
        'lab' (default) or 'rgb': the channels matched one by one.
    threshold : float
        Alpha in [0, 1] from which a pixel counts in the histograms; the maps are applied
        to every pixel with alpha > 0. Alpha is unchanged.

    Returns
    -------
    ndarray, shape (H, W, 4), uint8
        Crown pixels matched to the photo's crown; trunk pixels matched to its trunk, or
        unchanged when ``reference`` has no trunk.
    """
    img = np.asarray(rgba)
    if img.ndim != 3 or img.shape[2] != 4 or img.dtype != np.uint8:
        raise InputError(f"rgba: expected an (H, W, 4) uint8 RGBA image, got {img.shape} {img.dtype}")
    if labels is None:
        lab = np.where(img[..., 3] > 0, 1, 0).astype(np.uint8)
    else:
        lab = np.asarray(labels)
        if lab.shape != img.shape[:2]:
            raise InputError(f"labels: expected shape {img.shape[:2]}, got {lab.shape}")
    if not isinstance(reference, SeasonReference):
        raise InputError(f"reference: expected a SeasonReference, got {type(reference).__name__}")
    check_choice(space, "space", SPACES)
    if isinstance(threshold, bool) or not isinstance(threshold, (int, float)) or not 0 <= threshold <= 1:
        raise InputError(f"threshold: expected a value in [0, 1], got {threshold!r}")
    lab = crown_trunk_labels(img, lab)
    out = img.copy()
    alpha = img[..., 3]
    opaque = alpha >= max(threshold * 255.0, 1)
    for value, ref in ((1, reference.crown), (2, reference.trunk)):
        if ref is None or len(ref) == 0:
            continue
        part = (lab == value) & (alpha > 0)
        if not (part & opaque).any():
            continue
        ys, xs = np.nonzero(part)
        out[ys, xs, :3] = _match(img[ys, xs, :3], opaque[ys, xs], np.asarray(ref, np.uint8), space)
    return out


def mean_hue(pixels) -> tuple[float, float]:
    """Hue angle and chroma of the mean CIE a*b* of RGB pixels.

    Parameters
    ----------
    pixels : ndarray, shape (N, 3), uint8

    Returns
    -------
    hue : float
        Degrees in (-180, 180]: about 40 red, 60-80 orange and brown, 90-100 yellow,
        120-140 green, -90 blue.
    chroma : float

    Examples
    --------
    >>> [round(mean_hue(np.array([rgb], np.uint8))[0]) for rgb in ([200, 40, 30], [110, 80, 55], [60, 140, 40])]
    [37, 65, 135]
    """
    p = np.asarray(pixels, np.uint8).reshape(-1, 3)
    if len(p) == 0:
        raise InputError("pixels: no pixel to take a hue of")
    lab = _to_space(p, "lab")
    a, b = lab[:, 1].mean(), lab[:, 2].mean()
    return float(np.degrees(np.arctan2(b, a))), float(np.hypot(a, b))
