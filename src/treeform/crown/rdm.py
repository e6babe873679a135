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

    Holes (e.g. directions grazing a thin part) take the value of the nearest valid
    texel of the same face (exact Euclidean distance transform), or the smallest valid
    radius when a face has no valid texel at all.

    Parameters
    ----------
    center : array_like, shape (3,)
    radii : ndarray, shape (6, R, R)

    Examples
    --------
    >>> r = np.ones((6, 4, 4), np.float32); r[0, 1, 1] = 0
    >>> float(rdm_from_texels(np.zeros(3), r).radii[0, 1, 1])
    1.0
    """
    radii = np.asarray(radii, np.float32).copy()
    valid = radii > 0
    if not valid.any():
        raise InputError("radii: the envelope did not cover any cubemap texel (is the centre inside it?)")
    if not valid.all():
        fill = float(radii[valid].min())
        for f in range(6):
            hole = ~valid[f]
            if not hole.any():
                continue
            if hole.all():
                radii[f] = fill
                continue
            _, (iy, ix) = ndi.distance_transform_edt(hole, return_indices=True)
            radii[f][hole] = radii[f][iy[hole], ix[hole]]
    return RadialDistanceMap(np.asarray(center, np.float64), radii)
