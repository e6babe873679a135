"""Mean value coordinates for arbitrary planar polygons (Hormann & Floater 2006).

Seed 000 §5.2 uses mean value coordinates [HF06] of a target pixel with respect to the
simplified target contour Cs' to find its source position ``p = sum_i lambda_i v_i`` on
the source contour Cs. The paper's formulas are not reproduced legibly in our copy of
its text, so this module implements the standard published form (Hormann & Floater,
"Mean value coordinates for arbitrary planar polygons", ACM TOG 25(4), 2006, eq. 7 and
its robust evaluation, section 5):

    s_i = v_i - x,  r_i = |s_i|,  A_i = det(s_i, s_{i+1}) / 2,  D_i = s_i . s_{i+1}
    tan(alpha_i / 2) = (r_i r_{i+1} - D_i) / (2 A_i) = 2 A_i / (r_i r_{i+1} + D_i)
    w_i = (tan(alpha_{i-1} / 2) + tan(alpha_i / 2)) / r_i,   lambda_i = w_i / sum_j w_j

with *signed* angles alpha_i, which makes the coordinates well defined for any simple
polygon (not only convex or star-shaped) and anywhere in the plane except on the
polygon itself, where they are taken as the limit: the unit vector at a vertex and
linear interpolation on an edge. They reproduce linear functions exactly
(``sum_i lambda_i v_i = x``) and interpolate at the vertices (Lagrange property).

Everything is vectorised over pixels x vertices with numpy, in chunks of rows.
"""

from __future__ import annotations

import numpy as np

from treeform._shared.checks import check_array
from treeform._shared.errors import InputError

__all__ = ["mean_value_coordinates", "mvc_map"]

_CHUNK = 16384


def _check_polygon(polygon, name: str) -> np.ndarray:
    v = check_array(polygon, name, ndim=2, dtype_kind="iuf").astype(np.float64)
    if v.shape[1] != 2 or len(v) < 3:
        raise InputError(f"{name}: expected shape (M, 2) with M >= 3, got {v.shape}")
    return v


def _check_points(points) -> np.ndarray:
    x = check_array(points, "points", ndim=(1, 2), dtype_kind="iuf").astype(np.float64)
    if x.ndim == 1:
        x = x.reshape(1, -1)
    if x.shape[1] != 2:
        raise InputError(f"points: expected shape (P, 2), got {x.shape}")
    return x


def _mvc_block(x: np.ndarray, v: np.ndarray, eps: float) -> np.ndarray:
    sx = v[None, :, 0] - x[:, 0:1]  # (P, M)
    sy = v[None, :, 1] - x[:, 1:2]
    sxn = np.roll(sx, -1, axis=1)
    syn = np.roll(sy, -1, axis=1)
    r = np.hypot(sx, sy)
    rn = np.roll(r, -1, axis=1)
    a2 = sx * syn - sy * sxn  # 2 A_i
    d = sx * sxn + sy * syn  # D_i
    rr = r * rn
    # tan(alpha_i / 2) in the better conditioned of its two forms
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(d >= 0, a2 / (rr + d), (rr - d) / a2)
        on_vertex = r <= eps
        on_edge = (np.abs(a2) <= eps * np.maximum(rr, eps)) & (d < 0)
        t = np.where(np.isfinite(t), t, 0.0)
        w = (np.roll(t, 1, axis=1) + t) / r
        w = np.where(np.isfinite(w), w, 0.0)
        total = w.sum(1, keepdims=True)
        lam = w / total
    bad = ~np.isfinite(lam).all(1) | (np.abs(total[:, 0]) < 1e-300)
    special = on_vertex.any(1) | on_edge.any(1) | bad
    if special.any():
        for p in np.nonzero(special)[0]:
            lam[p] = 0.0
            iv = np.nonzero(on_vertex[p])[0]
            ie = np.nonzero(on_edge[p])[0]
            if iv.size:
                lam[p, iv[0]] = 1.0
            elif ie.size:
                i = ie[0]
                j = (i + 1) % len(v)
                lam[p, i] = rn[p, i] / (r[p, i] + rn[p, i])
                lam[p, j] = r[p, i] / (r[p, i] + rn[p, i])
            else:  # numerically degenerate: nearest vertex
                lam[p, int(np.argmin(r[p]))] = 1.0
    return lam


def mean_value_coordinates(points, polygon) -> np.ndarray:
    """Mean value coordinates of points with respect to a closed polygon [HF06].

    Parameters
    ----------
    points : ndarray, shape (P, 2) or (2,)
        Query points ``(x, y)``.
    polygon : ndarray, shape (M, 2)
        Polygon vertices in order (either orientation); repeated consecutive vertices
        are allowed.

    Returns
    -------
    ndarray, shape (P, M), float64
        Coordinates lambda summing to 1 per row, with ``lambda @ polygon == points``.

    Examples
    --------
    >>> sq = np.array([[0, 0], [2, 0], [2, 2], [0, 2]], float)
    >>> mean_value_coordinates([1.0, 1.0], sq).round(3).tolist()
    [[0.25, 0.25, 0.25, 0.25]]
    >>> mean_value_coordinates([[2.0, 0.0], [1.0, 0.0]], sq).round(3).tolist()
    [[0.0, 1.0, 0.0, 0.0], [0.5, 0.5, 0.0, 0.0]]
    """
    x = _check_points(points)
    v = _check_polygon(polygon, "polygon")
    scale = float(np.abs(v).max()) + 1.0
    eps = 1e-12 * scale
    out = np.empty((len(x), len(v)), np.float64)
    for s in range(0, len(x), _CHUNK):
        out[s:s + _CHUNK] = _mvc_block(x[s:s + _CHUNK], v, eps)
    return out


def mvc_map(points, target_polygon, source_polygons) -> np.ndarray:
    """Map points through the mean value coordinate warp f^-1 (seed 000 §5.2).

    For each point p' the coordinates lambda' with respect to ``target_polygon`` (Cs')
    are applied to the vertices of each source polygon (Cs): ``p = sum_i lambda'_i v_i``.
    Target vertices map exactly onto the corresponding source vertices.

    Parameters
    ----------
    points : ndarray, shape (P, 2)
    target_polygon : ndarray, shape (M, 2)
    source_polygons : ndarray, shape (M, 2) or (J, M, 2)

    Returns
    -------
    ndarray, shape (P, 2) or (J, P, 2), float64
    """
    x = _check_points(points)
    vt = _check_polygon(target_polygon, "target_polygon")
    src = check_array(source_polygons, "source_polygons", ndim=(2, 3), dtype_kind="iuf").astype(np.float64)
    single = src.ndim == 2
    src = src[None] if single else src
    if src.shape[1:] != vt.shape:
        raise InputError(f"source_polygons: expected (J, {len(vt)}, 2) to match the target, got {src.shape}")
    out = np.empty((len(src), len(x), 2), np.float64)
    stacked = src.transpose(1, 0, 2).reshape(len(vt), -1)  # (M, 2J)
    for s in range(0, len(x), _CHUNK):
        lam = _mvc_block(x[s:s + _CHUNK], vt, 1e-12 * (float(np.abs(vt).max()) + 1.0))
        out[:, s:s + _CHUNK] = (lam @ stacked).reshape(-1, len(src), 2).transpose(1, 0, 2)
    return out[0] if single else out
