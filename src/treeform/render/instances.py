"""Per-instance placement of a model: ``(x, y, z, scale, yaw, count)`` rows.

A model point ``p`` (the tree's own frame: Y up, base at the origin, metres) of instance
``(x, y, z, s, yaw, count)`` is drawn at ``R_y(yaw) (s p) + (x, y, z)``, ``R_y`` the right-handed
turn about +Y. ``count`` is for passes that draw only the first ``count`` of their points for
that instance (billboard clouds: fewer billboards far away); others ignore it. The GLSL side is
:data:`treeform.render.shaders.YAW_GLSL`.
"""

from __future__ import annotations

import numpy as np

from treeform._shared.checks import check_array
from treeform._shared.errors import InputError

__all__ = ["check_instances", "instance_points", "yaw_matrix"]


def check_instances(instances, name: str = "instances") -> np.ndarray:
    """``instances`` as a C-contiguous (N, 6) float32 array; (N, 5) gets ``count`` 0.

    Examples
    --------
    >>> check_instances([[0, 0, 0, 1, 0]]).shape
    (1, 6)
    """
    arr = check_array(instances, name, ndim=2, dtype_kind="fiu")
    if arr.shape[1] not in (5, 6):
        raise InputError(f"{name}: expected (N, 6) rows (x, y, z, scale, yaw, count), got shape {arr.shape}")
    if arr.shape[1] == 5:
        arr = np.concatenate([arr, np.zeros((len(arr), 1))], axis=1)
    if len(arr) and not np.all(arr[:, 3] > 0):
        raise InputError(f"{name}: scales must be > 0")
    return np.ascontiguousarray(arr, np.float32)


def yaw_matrix(yaw) -> np.ndarray:
    """(..., 3, 3) rotations about +Y by ``yaw`` radians (as the shaders turn instances)."""
    yaw = np.asarray(yaw, np.float64)
    c, s = np.cos(yaw), np.sin(yaw)
    m = np.zeros(yaw.shape + (3, 3))
    m[..., 0, 0], m[..., 0, 2], m[..., 1, 1], m[..., 2, 0], m[..., 2, 2] = c, s, 1.0, -s, c
    return m


def instance_points(instances, points) -> np.ndarray:
    """Model ``points`` (P, 3) placed by every instance: (N, P, 3) world positions.

    Examples
    --------
    >>> instance_points([[1, 0, 0, 2, np.pi / 2, 0]], [[1.0, 0, 0]]).round(6)
    array([[[ 1.,  0., -2.]]])
    """
    inst = check_instances(instances).astype(np.float64)
    pts = check_array(points, "points", shape=(None, 3)).astype(np.float64)
    rot = yaw_matrix(inst[:, 4])
    return np.einsum("nij,pj->npi", rot, pts) * inst[:, None, 3:4] + inst[:, None, :3]
