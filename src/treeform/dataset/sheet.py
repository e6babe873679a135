"""Contact sheet of a generated dataset: each image beside its semantic mask."""

from __future__ import annotations

import numpy as np

from treeform._shared.checks import check_int
from treeform._shared.errors import InputError

__all__ = ["MASK_COLORS", "contact_sheet", "mask_to_rgb", "show_dataset"]

MASK_COLORS = np.array([[255, 255, 255], [40, 170, 60], [40, 70, 230]], np.uint8)
"""Mask colours as in seed 003 Fig. 5: background white, foliage green, branches blue."""


def mask_to_rgb(mask) -> np.ndarray:
    """Labels (H, W) in {0, 1, 2} -> (H, W, 3) uint8 in :data:`MASK_COLORS`."""
    m = np.asarray(mask)
    if m.ndim != 2 or m.size == 0 or m.max() > 2:
        raise InputError(f"mask: expected an (H, W) array of labels 0..2, got shape {m.shape}")
    return MASK_COLORS[m]


def contact_sheet(samples, *, tile: int = 192, cols: int = 4, gap: int = 4) -> np.ndarray:
    """Image | mask pairs with the species written underneath, ``cols`` pairs a row.

    Parameters
    ----------
    samples : sequence of dict
        Each with ``image`` (S, S, 3) uint8, ``mask`` (S, S) and ``species`` (str).

    Returns
    -------
    ndarray, shape (H, W, 3), uint8
    """
    from PIL import Image, ImageDraw

    samples = list(samples)
    if not samples:
        raise InputError("contact_sheet: no samples")
    label_h = 16
    cols = max(1, min(cols, len(samples)))
    rows = -(-len(samples) // cols)
    cell_w, cell_h = 2 * tile + gap, tile + label_h
    sheet = Image.new("RGB", (cols * cell_w + (cols + 1) * gap * 2, rows * cell_h + (rows + 1) * gap), (24, 24, 24))
    draw = ImageDraw.Draw(sheet)
    for k, s in enumerate(samples):
        r, c = divmod(k, cols)
        x = gap * 2 + c * (cell_w + gap * 2)
        y = gap + r * (cell_h + gap)
        img = Image.fromarray(np.asarray(s["image"], np.uint8)).resize((tile, tile), Image.BILINEAR)
        msk = Image.fromarray(mask_to_rgb(s["mask"])).resize((tile, tile), Image.NEAREST)
        sheet.paste(img, (x, y))
        sheet.paste(msk, (x + tile + gap, y))
        draw.text((x + 2, y + tile + 2), f"#{s.get('index', k)} {s.get('species', '')}", fill=(230, 230, 230))
    return np.asarray(sheet)


def show_dataset(directory, *, n: int = 16, out=None, cols: int = 4, tile: int = 192, progress=None):
    """Write a contact sheet of ``n`` samples spread evenly over a dataset (default ``DIR/contact_sheet.png``).

    Returns the path written.
    """
    from pathlib import Path

    from treeform._shared.timing import StageTimer
    from treeform.dataset.loader import SyntheticDataset
    from treeform.io import write_png
    from treeform.io.outputs import check_out_file

    check_int(n, "--n", 1, 2**31)
    timer = StageTimer(progress)
    with timer.stage("load"):
        ds = SyntheticDataset(directory)
        out = check_out_file(Path(directory) / "contact_sheet.png" if out is None else out)
        picks = np.linspace(0, len(ds) - 1, min(n, len(ds))).round().astype(int) if n < len(ds) else range(len(ds))
        samples = [ds[int(i)] for i in picks]
    with timer.stage("sheet"):
        sheet = contact_sheet(samples, tile=tile, cols=cols)
        write_png(sheet, out)
    return out
