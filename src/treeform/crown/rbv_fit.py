"""A radial bounding volume fitted to the photo it was predicted from.

Seed 003 §4.2.3 predicts the RBV from the tree's mask by a network. The prediction is a prior
over the whole crown, the sides the camera cannot see included; the photo itself fixes the
crown's left and right extent in every layer. :func:`fit_rbv_to_silhouette` keeps the
network's shape and rescales each layer so that the volume, seen by the photo's camera,
spans the silhouette's rows from the same left edge to the same right edge.
"""

from __future__ import annotations

import numpy as np

from treeform._shared.checks import check_int
from treeform._shared.errors import InputError
from treeform.crown.layout import row_extents
from treeform.structures.camera import Camera
from treeform.structures.rbv import RadialBoundingVolume

__all__ = ["fit_rbv_to_silhouette", "rbv_layer_extents", "silhouette_layer_extents"]

_ANGLE_SAMPLES = 7  # boundary samples across a sector's arc
_HEIGHT_SAMPLES = 3  # and across a layer's height


def _boundary(rbv: RadialBoundingVolume, layer: int):
    """Points (S, K, 3) on the outer surface of each sector of ``layer``, world metres."""
    edges, angles = rbv.layer_edges(), rbv.sector_edges()
    ys = np.linspace(edges[layer], edges[layer + 1], _HEIGHT_SAMPLES)
    t = np.linspace(0.0, 1.0, _ANGLE_SAMPLES)
    a = angles[:-1, None] + t[None, :] * (angles[1:] - angles[:-1])[:, None]  # (S, A)
    r = rbv.physical_radii[layer][:, None]
    x, z = (r * np.cos(a))[:, :, None], (r * np.sin(a))[:, :, None]
    y = np.broadcast_to(ys[None, None, :], (len(a), _ANGLE_SAMPLES, _HEIGHT_SAMPLES))
    pts = np.stack(np.broadcast_arrays(x, y, z), axis=-1).reshape(len(a), -1, 3)
    return pts + rbv.origin


def rbv_layer_extents(rbv: RadialBoundingVolume, camera: Camera) -> np.ndarray:
    """(n, 2) leftmost and rightmost image column of each layer of ``rbv`` seen by ``camera``.

    A layer whose sectors are all empty gets NaN.
    """
    out = np.full((rbv.n_layers, 2), np.nan)
    for i in range(rbv.n_layers):
        if rbv.physical_radii[i].max() <= 0:
            continue
        u = camera.project(_boundary(rbv, i).reshape(-1, 3))[:, 0]
        out[i] = u.min(), u.max()
    return out


def silhouette_layer_extents(rbv: RadialBoundingVolume, camera: Camera, mask: np.ndarray) -> np.ndarray:
    """(n, 2) leftmost and rightmost column of ``mask`` in the rows of each layer of ``rbv``.

    A layer's rows are those its height range covers on the plane through the volume's axis
    facing the camera; a layer the mask does not reach gets NaN.
    """
    mask = np.asarray(mask, bool)
    h = mask.shape[0]
    edges = rbv.layer_edges()
    o = rbv.origin
    pts = np.array([[o[0], o[1] + y, o[2]] for y in edges])
    v = camera.project(pts)[:, 1]
    rows, left, right = row_extents(mask)
    out = np.full((rbv.n_layers, 2), np.nan)
    for i in range(rbv.n_layers):
        lo, hi = sorted((v[i], v[i + 1]))
        r0, r1 = max(int(np.floor(lo)), 0), min(int(np.ceil(hi)), h)
        if r1 <= r0 or not rows[r0:r1].any():
            continue
        sel = slice(r0, r1)
        ok = rows[sel]
        out[i] = left[sel][ok].min(), right[sel][ok].max() + 1.0
    return out


def fit_rbv_to_silhouette(rbv: RadialBoundingVolume, camera: Camera, mask: np.ndarray, *,
                          iterations: int = 4, limits: tuple = (0.25, 4.0)) -> RadialBoundingVolume:
    """Rescale each layer of ``rbv`` so that ``camera`` sees it span the silhouette's extent.

    Every sector's radius in layer i is multiplied by ``kL**a * kR**b``: kR is the ratio of
    the silhouette's right extent (from the axis's column) to the volume's, kL the same on the
    left, and ``a = (1 - cos θ) / 2``, ``b = (1 + cos θ) / 2`` for the sector's central angle θ
    (θ = 0 is +X, the image's right). A sector facing the image's right takes kR, one facing
    its left kL, and one facing toward or away from the camera the geometric mean: the hidden
    depth scales with the visible width, so the network's shape is kept. Perspective couples
    the layers' extents to their depth, hence a few fixed-point iterations.

    Parameters
    ----------
    rbv : RadialBoundingVolume
        In the camera's world (metres; the axis through ``rbv.origin``).
    camera : Camera
        The camera that took the photo; ``mask`` is its image.
    mask : ndarray, shape (H, W), bool
        The tree's silhouette in the photo.
    iterations : int
    limits : (float, float)
        Bounds on each layer's scale factors per iteration.

    Returns
    -------
    RadialBoundingVolume
        A new volume in metres (``radial_scale`` folded in); layers the silhouette does not
        reach, or that are empty, keep their radii.

    Examples
    --------
    A 2-layer cylinder of radius 1 m seen from 20 m, fitted to a silhouette twice as wide:

    >>> cam = Camera(200, 200, 30.0, (0, 1, 20.0), (0, 1, 0), (0, 1, 0))
    >>> rbv = RadialBoundingVolume(np.ones((2, 2)), 2.0)
    >>> cols = rbv_layer_extents(rbv, cam)
    >>> mask = np.zeros((200, 200), bool)
    >>> v = cam.project(np.array([[0, 0, 0], [0, 2.0, 0]]))[:, 1]
    >>> mask[int(v[1]):int(v[0]), 100 - 2 * (100 - int(cols[0, 0])):100 + 2 * (int(cols[0, 1]) - 100)] = True
    >>> fit = fit_rbv_to_silhouette(rbv, cam, mask)
    >>> bool(np.allclose(fit.radii, 2.0, atol=0.1))
    True
    """
    if not isinstance(rbv, RadialBoundingVolume):
        raise InputError(f"rbv: expected a RadialBoundingVolume, got {type(rbv).__name__}")
    mask = np.asarray(mask)
    if mask.shape != (camera.height, camera.width):
        raise InputError(f"mask: expected shape {(camera.height, camera.width)}, got {mask.shape}")
    iterations = check_int(iterations, "iterations", 1, 50)
    lo, hi = float(limits[0]), float(limits[1])
    if not 0.0 < lo <= 1.0 <= hi:
        raise InputError(f"limits: expected 0 < low <= 1 <= high, got {limits!r}")
    out = RadialBoundingVolume(rbv.physical_radii, rbv.physical_height, rbv.origin)
    axis_u = float(camera.project(out.origin[None])[0, 0])
    target = silhouette_layer_extents(out, camera, mask)
    edges = out.sector_edges()
    theta = 0.5 * (edges[:-1] + edges[1:])
    a, b = 0.5 * (1.0 - np.cos(theta)), 0.5 * (1.0 + np.cos(theta))
    for _ in range(iterations):
        now = rbv_layer_extents(out, camera)
        radii = out.radii.copy()
        for i in range(out.n_layers):
            if np.isnan(target[i]).any() or np.isnan(now[i]).any():
                continue
            k_left = (axis_u - target[i, 0]) / max(axis_u - now[i, 0], 1e-6)
            k_right = (target[i, 1] - axis_u) / max(now[i, 1] - axis_u, 1e-6)
            k_left, k_right = np.clip([k_left, k_right], lo, hi)
            radii[i] *= k_left ** a * k_right ** b
        out = RadialBoundingVolume(radii, out.height, out.origin)
    return out
