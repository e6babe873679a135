"""Where the crown and the trunk are in a segmented photo."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.ndimage as ndi

from treeform._shared.errors import NoTreeFoundError
from treeform.structures.segmentation import Segmentation


CROWN_PART = 0.02
"""A part of the crown apart from the rest (a sapling's clumps of leaves along its stem, the lower limbs of a
bare tree the mask found in two pieces) is kept when its area is at least this share of the largest part's;
smaller ones are specks."""

TRUNK_PRIOR = 0.02
"""Trunk width / tree height (pixels) where the photo does not show the trunk: open-grown trees' trunks
are 1-4 % of their height across (the growth engine's species: 0.8-4.2 %)."""


@dataclass
class TreeLayout:
    """Pixel measurements of the tree in its photo (row 0 at the top).

    Attributes
    ----------
    crown_mask : ndarray, shape (H, W), bool
        The crown silhouette (holes filled) the envelope inflates.
    base : tuple of float
        (column, row) of the trunk base: where the tree meets the ground.
    trunk_top : tuple of float
        (column, row) where the trunk enters the crown.
    top_row : int
        Highest tree row.
    trunk_width : float
        Median trunk width in pixels: of the wood at the base, else (the trunk hidden)
        :data:`TRUNK_PRIOR` of the tree's height.
    trunk_path : ndarray, shape (K, 2)
        The trunk's centre line (column, row) from the base up to ``trunk_top``.
    """

    crown_mask: np.ndarray
    base: tuple
    trunk_top: tuple
    top_row: int
    trunk_width: float
    trunk_path: np.ndarray | None = None

    def __post_init__(self):
        if self.trunk_path is None:
            self.trunk_path = np.array([self.base, self.trunk_top], np.float64)

    @property
    def height_px(self) -> float:
        return max(self.base[1] - self.top_row, 1.0)


def tree_layout(seg: Segmentation) -> TreeLayout:
    """Measure the crown silhouette, trunk base, trunk top and trunk width.

    The crown is the foliage closed over small gaps, holes filled, keeping its parts of at
    least :data:`CROWN_PART` of the largest one's area (the whole tree mask when there is almost
    no foliage, e.g. a bare tree).
    The trunk base is :func:`~treeform.skeleton.trunk_foot` (the bottom of the thickest wood
    near the bottom of the tree, so a twig or a weeping curtain hanging lower is not taken);
    the trunk is then traced up through the wood pixels, row by row, while one run of wood at
    least half the trunk's width continues it; the trunk top is where it forks, thins or ends,
    and never lower than the crown's lowest row.

    Examples
    --------
    >>> lab = np.zeros((40, 30), np.uint8); lab[5:25, 5:25] = 1; lab[25:38, 13:17] = 2
    >>> lay = tree_layout(Segmentation(lab))
    >>> lay.base, lay.trunk_width
    ((15.0, 37.5), 4.0)
    """
    tree = seg.tree_mask
    if tree.sum() < 16:
        raise NoTreeFoundError("no tree found: the tree mask has fewer than 16 pixels")
    rows = np.nonzero(tree.any(axis=1))[0]
    top, bottom = int(rows.min()), int(rows.max())
    size = bottom - top + 1
    foliage = seg.foliage_mask
    r = max(1, size // 100)
    if foliage.sum() > 0.2 * tree.sum():
        # pad so the closing does not eat crowns cut by the image frame
        crown = ndi.binary_closing(np.pad(foliage, r + 1, mode="edge"), np.ones((2 * r + 1, 2 * r + 1), bool))
        crown = crown[r + 1:-(r + 1), r + 1:-(r + 1)]
    else:
        crown = tree
    crown = ndi.binary_fill_holes(crown)
    lab, n = ndi.label(crown)
    if n == 0:
        raise NoTreeFoundError("no tree found: no crown region in the mask")
    areas = np.bincount(lab.ravel())[1:]
    crown = np.isin(lab, np.flatnonzero(areas >= CROWN_PART * areas.max()) + 1)
    from treeform.skeleton.wood import trunk_foot

    foot_col, bottom = trunk_foot(tree, seg.wood_mask)
    base_col = foot_col + 0.5
    crown_rows = np.nonzero(crown.any(axis=1))[0]
    crown_bottom = int(crown_rows.max())
    # trunk: the wood region touching the base, else hidden
    trunk_wood = _base_wood(seg.wood_mask, base_col, bottom, size)
    if trunk_wood is not None:
        rows_w = np.nonzero(trunk_wood.any(axis=1))[0]
        lo_r, hi_r = rows_w.min(), rows_w.max()
        span = hi_r - lo_r + 1
        band_rows = trunk_wood[hi_r - int(0.5 * span): hi_r - int(0.1 * span) + 1]  # above the root flare
        widths = band_rows.sum(axis=1)
    else:
        # no wood at the foot: the trunk is hidden. What the mask shows under the crown is not it -- a
        # bush behind the foot, leaves hanging low, the foliage of a crown down to the ground (as wide as
        # those, the trunk became a log: a radius of 6 % of the height, the pipeline's upper bound)
        widths = np.array([TRUNK_PRIOR * size])
    widths = widths[widths > 0]
    trunk_width = float(np.median(widths)) if len(widths) else TRUNK_PRIOR * size
    # trunk top: where the trunk meets the crown (the tree centre a little below the crown bottom)
    probe = min(bottom, crown_bottom + max(1, size // 50))
    row = tree[probe]
    if row.any():
        xs = np.nonzero(row)[0]
        top_col = float(xs[np.argmin(np.abs(xs - base_col))]) + 0.5
        near = xs[np.abs(xs - top_col) < max(trunk_width, 3)]
        top_col = float(near.mean()) + 0.5 if len(near) else top_col
    else:
        top_col = base_col
    trunk_top = (top_col, crown_bottom + 0.5)
    path = None
    if trunk_wood is not None:
        traced = _trace_trunk(trunk_wood, base_col, bottom, trunk_width)
        if traced is not None and traced[-1][1] < trunk_top[1]:
            trunk_top = tuple(traced[-1])
            path = np.concatenate([[[base_col, bottom + 0.5]], traced])
    return TreeLayout(crown, (base_col, bottom + 0.5), trunk_top, top, trunk_width, path)


def _base_wood(wood: np.ndarray, base_col: float, bottom: int, size: int):
    """The wood components that touch the trunk base (None if there is none)."""
    if not wood.any():
        return None
    lab, n = ndi.label(wood, np.ones((3, 3), bool))
    r = max(3, size // 40)
    b = int(base_col)
    ids = np.unique(lab[max(0, bottom - r): bottom + 1, max(0, b - 3 * r): b + 3 * r + 1])
    ids = ids[ids > 0]
    if len(ids) == 0:
        return None
    comp = np.isin(lab, ids)
    return comp if comp.sum() >= 4 * r else None


def _trace_trunk(wood: np.ndarray, base_col: float, bottom: int, width: float):
    """Follow the trunk's wood up from the base; return its centre line (K, 2) up to where it forks,
    thins, widens into the crown or ends (None if it cannot be followed)."""
    if wood.sum() < 4 * max(width, 1):
        return None
    x = base_col
    last = None
    path = []
    gap = 0
    running = float(width)
    min_run = max(2.0, 0.5 * width)
    for row in range(bottom, -1, -1):
        line = wood[row]
        if not line.any():
            gap += 1
            if gap > max(3, width):
                break
            continue
        # runs of wood on this row
        d = np.diff(np.concatenate([[0], line.astype(np.int8), [0]]))
        starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1)
        # bark texture splits a trunk into stripes: runs closer than 40 % of its width are one
        join = starts[1:] - ends[:-1] < max(3.0, 0.4 * width)
        starts = np.concatenate([starts[:1], starts[1:][~join]])
        ends = np.concatenate([ends[:-1][~join], ends[-1:]])
        centers = (starts + ends) / 2
        lengths = ends - starts
        near = np.abs(centers - x) <= max(width, 3)
        wide = near & (lengths >= min_run) & (lengths <= 3 * max(width, 3))
        if last is None and wide.sum() != 1:  # still in the root flare: keep climbing
            if row < bottom - 4 * max(width, 3):
                break
            continue
        if wide.sum() != 1:  # the trunk forks (two wide runs) or thins out
            if wide.sum() > 1 or gap > max(3, width):
                break
            gap += 1
            continue
        gap = 0
        i = int(np.flatnonzero(wide)[0])
        # a fork whose other limb left the search window shows as a sudden narrowing
        if last is not None and lengths[i] < 0.55 * running:
            break
        running = lengths[i] if last is None else 0.9 * running + 0.1 * lengths[i]
        x = 0.7 * x + 0.3 * centers[i]
        last = (float(x), row + 0.5)
        path.append(last)
    if last is None:
        return None
    return np.array(path[::max(1, int(width) // 2)] + [last], np.float64)


def trunk_pixels(seg: Segmentation, layout: TreeLayout) -> np.ndarray:
    """(H, W) bool: the trunk's own wood — the wood region touching the base, below the trunk top."""
    wood = seg.wood_mask
    lab, n = ndi.label(wood, np.ones((3, 3), bool))
    out = np.zeros_like(wood)
    if n == 0:
        return out
    bu, bv = int(layout.base[0]), min(int(layout.base[1]), wood.shape[0] - 1)
    r = max(2, int(layout.trunk_width))
    ids = np.unique(lab[max(0, bv - r):bv + 1, max(0, bu - r):bu + r + 1])
    ids = ids[ids > 0]
    if len(ids):
        out = np.isin(lab, ids)
        out[: int(layout.trunk_top[1])] = False
    return out


def row_extents(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(H,) each row's occupancy, leftmost and rightmost ``mask`` column (0 for empty rows).

    >>> m = np.zeros((3, 5), bool); m[1, 1:4] = True
    >>> [a.tolist() for a in row_extents(m)]
    [[False, True, False], [0, 1, 0], [0, 3, 0]]
    """
    mask = np.asarray(mask, bool)
    rows = mask.any(1)
    left = np.where(rows, mask.argmax(1), 0)
    right = np.where(rows, mask.shape[1] - 1 - mask[:, ::-1].argmax(1), 0)
    return rows, left, right
