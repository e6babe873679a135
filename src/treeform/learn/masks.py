"""The input of the mask networks (species, RBV): a semantic mask framed the same way every time.

Seed 003 §4.2.3–4.2.4 feed the semantic mask M, split into three channels in [0, 1], to the
species and RBV networks. Photos frame trees in any way, so the mask is first cropped to
the tree's bounding box and scaled into a :data:`MASK_SIZE` square with its foot on a fixed
row and centred left-right: the network sees the tree's shape, not the photographer's
framing (the RBV is normalised by the tree's height, so nothing is lost). Channels are
resampled by area (a thin trunk stays a faint line instead of vanishing).
"""

from __future__ import annotations

import numpy as np

from treeform._shared.errors import InputError, NoTreeFoundError

__all__ = ["MASK_SIZE", "mask_input"]

MASK_SIZE = 96
"""Edge of the networks' square input."""

_FOOT_ROW = 0.96
_EXTENT = 0.92


def mask_input(labels: np.ndarray, *, size: int = MASK_SIZE) -> np.ndarray:
    """(3, size, size) float32 channels background / foliage / wood of a 0/1/2 label image.

    Parameters
    ----------
    labels : ndarray, shape (H, W), integer
        0 background, 1 foliage, 2 wood (other values count as foliage).

    Raises
    ------
    NoTreeFoundError
        No tree pixel.

    Examples
    --------
    >>> lab = np.zeros((50, 40), np.uint8); lab[10:40, 15:25] = 1; lab[40:48, 19:21] = 2
    >>> x = mask_input(lab)
    >>> x.shape, bool(np.allclose(x.sum(0), 1.0))
    ((3, 96, 96), True)
    """
    import cv2

    lab = np.asarray(labels)
    if lab.ndim != 2:
        raise InputError(f"labels: expected an (H, W) label image, got shape {lab.shape}")
    ys, xs = np.nonzero(lab > 0)
    if ys.size == 0:
        raise NoTreeFoundError("the mask holds no tree")
    y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
    crop = lab[y0:y1, x0:x1]
    h, w = crop.shape
    s = _EXTENT * size / max(h, w)
    nh, nw = max(1, int(round(h * s))), max(1, int(round(w * s)))
    fol = (crop > 0) & (crop != 2)
    wood = crop == 2
    onehot = np.stack([fol, wood], -1).astype(np.float32)
    interp = cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR
    small = cv2.resize(onehot, (nw, nh), interpolation=interp).reshape(nh, nw, 2)
    out = np.zeros((size, size, 2), np.float32)
    top = int(round(_FOOT_ROW * size)) - nh
    left = (size - nw) // 2
    ty, tx = max(0, top), max(0, left)
    out[ty:ty + nh - (ty - top), tx:tx + nw - (tx - left)] = small[ty - top:, tx - left:][:size - ty, :size - tx]
    out = np.clip(out, 0.0, 1.0)
    tree = np.clip(out.sum(-1), 0.0, 1.0)
    out[..., 1] = np.minimum(out[..., 1], tree)
    out[..., 0] = tree - out[..., 1]
    return np.ascontiguousarray(np.concatenate([(1.0 - tree)[None], out.transpose(2, 0, 1)], 0), dtype=np.float32)
