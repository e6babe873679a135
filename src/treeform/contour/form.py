"""Growth form of an exemplar from its silhouette: broadleaf, conifer or palm.

Variations combine exemplars of the same form (seed 000 §7, Limitations: combining
radically different trees gives implausible ones; a palm's fronds smeared into a
broadleaf crown), and the single-photo envelope route grows a conifer with a leader
(:func:`treeform.methods.envelope.pipeline.tree_form`). The form is read from the alpha
mask alone, never from a file name, so it works for any user library or photo.
Descriptor (:func:`form_descriptor`), on the mask normalised to 256 px
(:func:`treeform.contour.normalize.normalize_rgba`):

* **stem**: the bare stem, as a fraction of the tree's height: rows counted up from the
  bottom while the mask's width there is at most 12 % of the widest row's extent.
  The rows above it are the *canopy*.
* **aspect**: canopy width (2nd to 98th percentile of its columns) / canopy height.
* **widest**: where the canopy's (smoothed) extent is largest, 0 at its top, 1 at its
  bottom; **width15**, **width30**: its extent 15 % and 30 % of the way down, relative
  to the largest extent.
* **radiality**: how much the silhouette's edges in the canopy point away from one hub
  on the tree's axis: ``1 - mean |cos|`` of the angle between the edge direction's
  normal (the alpha gradient) and the direction from the hub, weighted by the
  gradient, at the best of 33 hubs in the top 80 % of the tree. Long fronds radiating
  from the top of a palm's stem have edges along the radius (radiality about 0.6);
  the leaf clusters of a broadleaf and the tiers of a conifer have edges in every
  direction (about 0.4). **hub**: that hub's height below the top, in tree heights.

Rule (:func:`classify_form`), first match wins:

* **palm**: radiality >= 0.46, hub in the top 45 % of the tree, a bare stem of at
  least 15 % of the height, and a canopy no more than 1.2 times as wide as tall
  (umbrella-shaped acacias are wider and their twigs radiate too);
* **conifer**: a narrow cone reaching the lower part of the tree: widest in the lower
  40 % of the canopy, pointed (width15 <= 0.45, width30 <= 0.7), canopy at most 0.75
  times as wide as tall, and a bare stem of at most 30 % of the height; or a narrow
  column (canopy at most 0.35 times as wide as tall) down to within 15 % of the ground,
  without radiating twigs (radiality <= 0.45; a leafless fastigiate broadleaf has them);
* **broadleaf**: everything else.

On the 35 FlightGear and CesiumGS cut-outs of ``../shared/data/billboards`` whose form
is clear (two cacti left out), the rule is right for 31: all 12 broadleaves, 14 of 16
conifers (a Scots pine with a broad, flat top and an Araucaria are called broadleaf),
5 of 7 palms (a banana plant and a fan palm in a skirt of dead leaves are called
broadleaf); the thresholds were chosen on these trees and their other seasons in
``billboards/more`` (176 of 202 right there).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import cv2
import numpy as np

from treeform.contour.normalize import normalize_rgba

__all__ = ["FORMS", "FormDescriptor", "form_descriptor", "classify_form"]

FORMS = ("broadleaf", "conifer", "palm")
"""The growth forms :func:`classify_form` returns."""

_SIDE = 256
_HUBS = 33


@dataclass(frozen=True)
class FormDescriptor:
    """Silhouette measures of a tree (see the module docstring); all dimensionless."""

    stem: float
    aspect: float
    widest: float
    width15: float
    width30: float
    radiality: float
    hub: float

    @property
    def form(self) -> str:
        """'palm', 'conifer' or 'broadleaf' by the rule of :func:`classify_form`."""
        if self.radiality >= 0.46 and self.hub <= 0.45 and self.stem >= 0.15 and self.aspect <= 1.2:
            return "palm"
        if (self.widest >= 0.6 and self.width15 <= 0.45 and self.width30 <= 0.7 and self.aspect <= 0.75
                and self.stem <= 0.3):
            return "conifer"  # a narrow cone
        if self.aspect <= 0.35 and self.stem <= 0.15 and self.radiality <= 0.45:
            return "conifer"  # a narrow column
        return "broadleaf"

    def to_dict(self) -> dict:
        return {k: round(float(v), 4) for k, v in asdict(self).items()}


def _alpha(tree) -> np.ndarray:
    """(256, 256) float32 alpha of the tree, normalised (cropped, scaled, on the bottom)."""
    rgba = tree.rgba if hasattr(tree, "rgba") else tree  # normalize_rgba checks it is (H, W, 4) uint8
    return normalize_rgba(rgba, size=_SIDE)[..., 3].astype(np.float32) / 255.0


def _drop_specks(mask: np.ndarray) -> np.ndarray:
    """Components under 1 % of the largest one (stray atlas pixels) removed."""
    n, lab, st, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    if n <= 2:
        return mask
    area = st[:, cv2.CC_STAT_AREA]
    keep = area >= 0.01 * area[1:].max()
    keep[0] = False
    return keep[lab]


def form_descriptor(tree) -> FormDescriptor:
    """Silhouette descriptor of a tree (module docstring).

    Parameters
    ----------
    tree : Exemplar or ndarray, shape (H, W, 4), uint8
        An RGBA tree on a transparent background.

    Returns
    -------
    FormDescriptor

    Raises
    ------
    InputError
        Not an RGBA image.
    NoTreeFoundError
        No opaque pixel.
    """
    alpha = _alpha(tree)
    m = _drop_specks(alpha >= 0.5)
    alpha = alpha * m
    ys, xs = np.nonzero(m)
    top, bot = int(ys.min()), int(ys.max())
    height = bot - top + 1
    sub = m[top:bot + 1]
    count = sub.sum(1)
    has = count > 0
    first = np.argmax(sub, 1)
    last = sub.shape[1] - 1 - np.argmax(sub[:, ::-1], 1)
    extent = np.where(has, last - first + 1, 0).astype(np.float64)
    # bare stem: rows from the bottom no wider than 12 % of the widest extent
    y = height - 1
    while y > 0 and count[y] <= 0.12 * extent.max():
        y -= 1
    stem = (height - 1 - y) / height
    canopy = extent[:y + 1]
    k = max(1, len(canopy) // 15)
    smooth = np.convolve(canopy, np.ones(k) / k, "same")
    smooth /= smooth.max()
    n = len(smooth)
    widest = float(np.argmax(smooth)) / max(1, n - 1)
    width15 = float(smooth[int(0.15 * (n - 1))])
    width30 = float(smooth[int(0.30 * (n - 1))])
    cm = m.copy()
    cm[top + y + 1:] = False
    cx = np.nonzero(cm)[1]
    lo, hi = np.percentile(cx, [2, 98])
    aspect = float((hi - lo + 1) / (y + 1))
    # radiality of the canopy's edges about hubs on the axis (the stem's foot)
    gx = cv2.Sobel(alpha, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(alpha, cv2.CV_32F, 0, 1, ksize=3)
    g = np.hypot(gx, gy)
    ey, ex = np.nonzero((g > 0.5) & (np.arange(m.shape[0])[:, None] <= top + y))
    w = g[ey, ex]
    ux, uy = gx[ey, ex] / w, gy[ey, ex] / w
    axis = float(np.median(xs[ys >= bot - max(2, int(0.03 * height))]))
    best, hub = 0.0, 0.0
    for hy in np.linspace(top, top + 0.8 * height, _HUBS):
        rx, ry = ex - axis, ey - hy
        r = np.hypot(rx, ry) + 1e-6
        sel = r > 0.05 * height
        if sel.sum() < 10:
            continue
        score = 1.0 - float(np.average(np.abs((rx * ux + ry * uy) / r)[sel], weights=w[sel]))
        if score > best:
            best, hub = score, (hy - top) / height
    return FormDescriptor(float(stem), aspect, widest, width15, width30, best, float(hub))


def classify_form(tree) -> str:
    """Growth form of a tree from its silhouette: 'broadleaf', 'conifer' or 'palm'.

    Parameters
    ----------
    tree : Exemplar or ndarray, shape (H, W, 4), uint8

    Returns
    -------
    str
        One of :data:`FORMS` (rule in the module docstring).

    Examples
    --------
    >>> yy, xx = np.mgrid[:200, :120]
    >>> cone = (np.abs(xx - 60) <= 0.3 * yy) & (yy < 190) | (np.abs(xx - 60) <= 3)
    >>> rgba = np.zeros((200, 120, 4), np.uint8); rgba[cone] = (40, 90, 40, 255)
    >>> classify_form(rgba)
    'conifer'
    """
    return form_descriptor(tree).form
