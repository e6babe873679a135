"""Statistics over a short first axis with missing values (NaN): per-view medians of many points."""

from __future__ import annotations

import numpy as np

__all__ = ["nanmedian_views"]


def nanmedian_views(a) -> np.ndarray:
    """Median over axis 0 ignoring NaN, NaN where every value is NaN, without warnings.

    The same values as ``np.nanmedian(a, axis=0)`` (for an even count, the mean of the two middle
    values, in ``a``'s dtype), made for a short axis 0 (views) over many points: NumPy takes a
    masked-array path there that sorts each column through Python-level machinery, about 8x slower
    on (24, 900000) float32.

    Parameters
    ----------
    a : array_like, shape (V, ...), float

    Returns
    -------
    ndarray, shape (...)

    Examples
    --------
    >>> a = np.array([[1.0, np.nan, 5.0], [3.0, np.nan, np.nan], [2.0, np.nan, 7.0], [9.0, np.nan, np.nan]])
    >>> nanmedian_views(a).tolist()
    [2.5, nan, 6.0]
    """
    a = np.atleast_1d(np.asarray(a))
    if not np.issubdtype(a.dtype, np.floating):
        a = a.astype(np.float64)
    if a.shape[0] == 0:
        return np.full(a.shape[1:], np.nan, a.dtype)
    s = np.sort(np.moveaxis(a, 0, -1), axis=-1)  # NaN sort last
    k = np.count_nonzero(~np.isnan(s), axis=-1)
    lo = np.take_along_axis(s, np.maximum((k - 1) // 2, 0)[..., None], -1)[..., 0]
    hi = np.take_along_axis(s, np.minimum(k // 2, s.shape[-1] - 1)[..., None], -1)[..., 0]
    return np.where(k > 0, (lo + hi) / a.dtype.type(2), a.dtype.type(np.nan))
