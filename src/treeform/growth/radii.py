"""Branch radii by the pipe model and branch orders."""

from __future__ import annotations

import numpy as np


def pipe_model_radii(parent: np.ndarray, *, tip_radius: float = 0.005, exponent: float = 2.0) -> np.ndarray:
    """Radius of every node by the pipe model: ``r_p^e = sum(r_c^e)`` over children.

    Tips get ``tip_radius``; ``exponent`` 2 is Leonardo's rule (area preserving),
    values 2–3 are reported for real trees.

    Parameters
    ----------
    parent : ndarray, shape (N,), int
        Parent indices with ``parent[i] < i`` and ``parent[0] == -1``.

    Returns
    -------
    ndarray, shape (N,)

    Examples
    --------
    >>> pipe_model_radii(np.array([-1, 0, 1, 1]), tip_radius=1.0).round(3).tolist()
    [1.414, 1.414, 1.0, 1.0]
    """
    from treeform.growth._kernels import pipe_accumulate

    parent = np.asarray(parent, np.int64)
    # children have larger indices: a reverse sweep sees every child before its parent
    acc = pipe_accumulate(parent, float(tip_radius) ** exponent)
    return acc ** (1.0 / exponent)


def branch_orders(parent: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Branch order per node: the thickest child continues its parent's order, others add one.

    Examples
    --------
    >>> branch_orders(np.array([-1, 0, 1, 1]), np.array([2, 2, 1.5, 1.0])).tolist()
    [0, 0, 0, 1]
    """
    from treeform.growth._kernels import main_child_orders

    parent = np.asarray(parent, np.int64)
    radius = np.asarray(radius, np.float64)
    if len(parent) < 2:
        return np.zeros(len(parent), np.int32)
    # main child of each parent: the child with the largest radius (lowest index on ties)
    return main_child_orders(parent, radius)
