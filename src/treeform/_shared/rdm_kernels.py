"""Compiled radial distance map lookups (numba, imported lazily by :mod:`treeform.structures.rdm`,
which keeps the structures free of compiled dependencies at import time).

The same arithmetic as :func:`treeform.structures.rdm.direction_to_texel` (OpenGL's face
choice and (sc, tc, ma) of each face), one point at a time: no (N, 3, 3) gathers.
"""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, nogil=True)
def _texel(x, y, z, res):
    ax, ay, az = abs(x), abs(y), abs(z)
    # np.argmax: the first of equal maxima wins
    if ax >= ay and ax >= az:
        if x < 0:
            face, sc, tc, ma = 1, z, -y, -x
        else:
            face, sc, tc, ma = 0, -z, -y, x
    elif ay >= az:
        if y < 0:
            face, sc, tc, ma = 3, x, -z, -y
        else:
            face, sc, tc, ma = 2, x, z, y
    else:
        if z < 0:
            face, sc, tc, ma = 5, -x, -y, -z
        else:
            face, sc, tc, ma = 4, x, -y, z
    ma = max(ma, 1e-12)
    col = min(max(np.int64((sc / ma + 1.0) * 0.5 * res), 0), res - 1)
    row = min(max(np.int64((tc / ma + 1.0) * 0.5 * res), 0), res - 1)
    return face, row, col


@nb.njit(cache=True, nogil=True)
def lookup(directions, radii):
    """(N,) float64 radius of the (6, R, R) map along each of the (N, 3) directions."""
    res = radii.shape[1]
    out = np.empty(directions.shape[0])
    for i in range(directions.shape[0]):
        f, r, c = _texel(directions[i, 0], directions[i, 1], directions[i, 2], res)
        out[i] = radii[f, r, c]
    return out


@nb.njit(cache=True, nogil=True)
def contains(points, center, radii):
    """(N,) bool: whether each of the (N, 3) points lies within the map's radius of ``center``."""
    res = radii.shape[1]
    out = np.empty(points.shape[0], np.bool_)
    for i in range(points.shape[0]):
        x = points[i, 0] - center[0]
        y = points[i, 1] - center[1]
        z = points[i, 2] - center[2]
        f, r, c = _texel(x, y, z, res)
        out[i] = np.sqrt(x * x + y * y + z * z) <= np.float64(radii[f, r, c])
    return out


@nb.njit(cache=True, nogil=True)
def bounds(face_matrices, center, radii):
    """(2, 3) min and max of ``center + direction * radius`` over every texel of the map.

    The direction through a texel centre is :func:`treeform.structures.rdm.texel_directions`'
    (the face's (sc, tc, 1) mapped by its matrix, normalised), computed in the same order.
    """
    res = radii.shape[1]
    out = np.empty((2, 3))
    for a in range(3):
        out[0, a] = np.inf
        out[1, a] = -np.inf
    v = np.empty(3)
    for f in range(6):
        m = face_matrices[f]
        for row in range(res):
            tc = (row + 0.5) / res * 2 - 1
            for col in range(res):
                sc = (col + 0.5) / res * 2 - 1
                for a in range(3):
                    v[a] = sc * m[0, a] + tc * m[1, a] + m[2, a]
                nrm = np.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
                r = np.float64(radii[f, row, col])
                for a in range(3):
                    p = center[a] + v[a] / nrm * r
                    if p < out[0, a]:
                        out[0, a] = p
                    if p > out[1, a]:
                        out[1, a] = p
    return out
