"""Where the crown and the trunk are in a segmented photo."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.ndimage as ndi

from treeform._shared.errors import NoTreeFoundError
from treeform.structures.segmentation import Segmentation


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
        Median trunk width in pixels.
    """

    crown_mask: np.ndarray
    base: tuple
    trunk_top: tuple
    top_row: int
    trunk_width: float

    @property
    def height_px(self) -> float:
        return max(self.base[1] - self.top_row, 1.0)


def tree_layout(seg: Segmentation) -> TreeLayout:
    """Measure the crown silhouette, trunk base, trunk top and trunk width.

    The crown is the foliage closed over small gaps, holes filled, keeping its largest
    component (the whole tree mask when there is almost no foliage, e.g. a bare tree).
    The trunk base is the centre of the lowest tree rows; the trunk top is the trunk's
    column at the crown's lowest row.

    Examples
    --------
    >>> lab = np.zeros((40, 30), np.uint8); lab[5:25, 5:25] = 1; lab[25:38, 13:17] = 2
    >>> lay = tree_layout(Segmentation(lab))
    >>> lay.base, lay.trunk_width
    ((14.5, 37.5), 4.0)
    """
    tree = seg.tree_mask
    if tree.sum() < 16:
        raise NoTreeFoundError("no tree found: the tree mask has fewer than 16 pixels")
    rows = np.nonzero(tree.any(axis=1))[0]
    top, bottom = int(rows.min()), int(rows.max())
    size = bottom - top + 1
    foliage = seg.foliage_mask
    r = max(1, size // 100)
    crown = ndi.binary_closing(foliage, np.ones((2 * r + 1, 2 * r + 1), bool)) if foliage.sum() > 0.2 * tree.sum() else tree
    crown = ndi.binary_fill_holes(crown)
    lab, n = ndi.label(crown)
    if n == 0:
        raise NoTreeFoundError("no tree found: no crown region in the mask")
    crown = lab == (np.argmax(np.bincount(lab.ravel())[1:]) + 1)
    # trunk base: centre of the tree pixels in the lowest 2 % of its rows
    band = tree[max(top, bottom - max(1, size // 50)): bottom + 1]
    cols = np.nonzero(band.any(axis=0))[0]
    base_col = float(np.nonzero(band)[1].mean()) + 0.5
    crown_rows = np.nonzero(crown.any(axis=1))[0]
    crown_bottom = int(crown_rows.max())
    # trunk: the tree pixels below the crown bottom, in the column band of the base
    widths = tree[crown_bottom + 1: bottom + 1].sum(axis=1) if crown_bottom < bottom else np.array([len(cols)])
    widths = widths[widths > 0]
    trunk_width = float(np.median(widths)) if len(widths) else float(len(cols))
    # trunk top: where the trunk meets the crown (the wood / tree centre a little below the crown bottom)
    probe = min(bottom, crown_bottom + max(1, size // 50))
    row = tree[probe]
    if row.any():
        xs = np.nonzero(row)[0]
        top_col = float(xs[np.argmin(np.abs(xs - base_col))]) + 0.5
        near = xs[np.abs(xs - top_col) < max(trunk_width, 3)]
        top_col = float(near.mean()) + 0.5 if len(near) else top_col
    else:
        top_col = base_col
    return TreeLayout(crown, (base_col, bottom + 0.5), (top_col, crown_bottom + 0.5), top, trunk_width)
