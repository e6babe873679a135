"""Radial distance map assembly (seed 001 §3.5).

The rasterisation of the envelope into the cubemap is a render pass
(:func:`treeform.render.cubemap.render_radial_cubemap`); this module turns its texels
into a :class:`~treeform.structures.RadialDistanceMap`.
"""

from __future__ import annotations

import numpy as np
import scipy.ndimage as ndi

from treeform._shared.errors import InputError
from treeform.structures.rdm import RadialDistanceMap


def rdm_from_texels(center, radii: np.ndarray) -> RadialDistanceMap:
    """Build a RadialDistanceMap, filling texels no fragment reached (radius 0).

    Holes (e.g. directions grazing a thin part) take the median of the valid texels
    of their face within a 5×5 window, or the global minimum radius if none.

    Parameters
    ----------
    center : array_like, shape (3,)
    radii : ndarray, shape (6, R, R)
    """
    radii = np.asarray(radii, np.float32).copy()
    valid = radii > 0
    if not valid.any():
        raise InputError("radii: the envelope did not cover any cubemap texel (is the centre inside it?)")
    if not valid.all():
        fill = float(radii[valid].min())
        for f in range(6):
            hole = ~valid[f]
            if hole.any():
                med = ndi.generic_filter(np.where(valid[f], radii[f], np.nan), np.nanmedian, size=5, mode="nearest")
                radii[f][hole] = np.where(np.isfinite(med[hole]), med[hole], fill)
    return RadialDistanceMap(np.asarray(center, np.float64), radii)
