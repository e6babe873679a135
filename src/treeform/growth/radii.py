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
    parent = np.asarray(parent, np.int64)
    n = len(parent)
    acc = np.zeros(n)
    has_child = np.zeros(n, bool)
    has_child[parent[1:]] = True
    acc[~has_child] = tip_radius**exponent
    # children have larger indices: a reverse sweep sees every child before its parent
    for i in range(n - 1, 0, -1):
        acc[parent[i]] += acc[i]
    return acc ** (1.0 / exponent)


def branch_orders(parent: np.ndarray, radius: np.ndarray) -> np.ndarray:
    """Branch order per node: the thickest child continues its parent's order, others add one.

    Examples
    --------
    >>> branch_orders(np.array([-1, 0, 1, 1]), np.array([2, 2, 1.5, 1.0])).tolist()
    [0, 0, 0, 1]
    """
    parent = np.asarray(parent, np.int64)
    radius = np.asarray(radius, np.float64)
    n = len(parent)
    order = np.zeros(n, np.int32)
    if n < 2:
        return order
    # main child of each parent: the child with the largest radius (lowest index on ties)
    kids = np.arange(1, n)
    key = np.lexsort((kids, -radius[1:], parent[1:]))
    sorted_kids = kids[key]
    first = np.ones(len(sorted_kids), bool)
    first[1:] = parent[sorted_kids[1:]] != parent[sorted_kids[:-1]]
    is_main = np.zeros(n, bool)
    is_main[sorted_kids[first]] = True
    for i in range(1, n):
        order[i] = order[parent[i]] + (0 if is_main[i] else 1)
    return order
