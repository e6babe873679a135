"""Input checks that raise :class:`~treeform._shared.errors.InputError` naming the argument."""

from __future__ import annotations

import numpy as np

from treeform._shared.errors import InputError


def check_array(value, name: str, *, ndim=None, dtype_kind=None, shape=None, min_size: int = 0) -> np.ndarray:
    """Return ``value`` as an ndarray after checking its rank, dtype kind and shape.

    ``shape`` may hold ``None`` for free axes, e.g. ``(None, 3)``.
    """
    try:
        arr = np.asarray(value)
    except Exception as exc:  # pragma: no cover - defensive
        raise InputError(f"{name}: cannot be converted to an array ({exc})") from None
    if ndim is not None:
        ndims = (ndim,) if isinstance(ndim, int) else tuple(ndim)
        if arr.ndim not in ndims:
            raise InputError(f"{name}: expected {ndim}-D array, got shape {arr.shape}")
    if dtype_kind is not None and arr.dtype.kind not in dtype_kind:
        raise InputError(f"{name}: expected dtype kind in {dtype_kind!r}, got {arr.dtype}")
    if shape is not None:
        if arr.ndim != len(shape) or any(s is not None and s != a for s, a in zip(shape, arr.shape)):
            raise InputError(f"{name}: expected shape {shape}, got {arr.shape}")
    if arr.size < min_size:
        raise InputError(f"{name}: expected at least {min_size} elements, got {arr.size}")
    if arr.dtype.kind == "f" and arr.size and not np.all(np.isfinite(arr)):
        raise InputError(f"{name}: contains NaN or infinite values")
    return arr


def check_positive(value, name: str, *, allow_zero: bool = False) -> float:
    """Return ``value`` as a float after checking it is positive (or >= 0)."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected a number, got {value!r}") from None
    if not np.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        raise InputError(f"{name}: expected a {'non-negative' if allow_zero else 'positive'} number, got {value!r}")
    return v


def check_finite(value, name: str) -> float:
    """Return ``value`` as a float after checking it is a finite number.

    >>> check_finite("2.5", "angle")
    2.5
    """
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected a number, got {value!r}") from None
    if not np.isfinite(v):
        raise InputError(f"{name}: expected a finite number, got {value!r}")
    return v


MAX_TREE_HEIGHT = 150.0
"""Metres; the tallest living trees measure about 116 m."""


def check_height(value, name: str = "tree_height") -> float:
    """Return a tree height in metres after checking it is positive and at most :data:`MAX_TREE_HEIGHT`.

    >>> check_height(12)
    12.0
    """
    v = check_positive(value, name)
    if v > MAX_TREE_HEIGHT:
        raise InputError(f"{name}: expected a tree height in metres up to {MAX_TREE_HEIGHT:g}, got {value!r}")
    return v


def check_int(value, name: str, lo: int, hi: int) -> int:
    """Return ``value`` as an int after checking it is an integer (not a bool) in ``[lo, hi]``.

    Examples
    --------
    >>> check_int(np.int64(3), "n", 1, 5)
    3
    """
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not lo <= value <= hi:
        raise InputError(f"{name}: expected an integer in [{lo}, {hi}], got {value!r}")
    return int(value)


def check_range(value, name: str, lo: float, hi: float) -> float:
    """Return ``value`` as a float after checking it is a finite number in ``[lo, hi]``.

    Examples
    --------
    >>> check_range("0.25", "share", 0, 1)
    0.25
    >>> check_range(float("nan"), "share", 0, 1)
    Traceback (most recent call last):
    ...
    treeform._shared.errors.InputError: share: expected a number in [0, 1], got nan
    """
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = float("nan")
    if isinstance(value, bool) or not np.isfinite(v) or not lo <= v <= hi:
        raise InputError(f"{name}: expected a number in [{lo:g}, {hi:g}], got {value!r}")
    return v


def check_choice(value, name: str, choices) -> str:
    """Return ``value`` after checking it is one of ``choices``."""
    if value not in choices:
        raise InputError(f"{name}: expected one of {', '.join(map(str, choices))}; got {value!r}")
    return value


def check_known_options(cls, options: dict) -> dict:
    """Return a copy of ``options`` after checking every key is a field of dataclass ``cls``."""
    from dataclasses import fields

    unknown = set(options) - {f.name for f in fields(cls)}
    if unknown:
        raise InputError(f"config: unknown option(s) {', '.join(sorted(unknown))}")
    return dict(options)


def check_inputs_exist(inputs) -> None:
    """Check every input path at once; one :class:`InputError` names all the missing ones.

    Parameters
    ----------
    inputs : iterable
        Paths (``str`` / ``os.PathLike``), ``(label, path)`` pairs (e.g. ``("--mask", p)``,
        named as ``--mask p``) or ``None`` (an option not given; skipped).

    Raises
    ------
    InputError
        ``"a.png: no such file"`` for one missing path, ``"no such files: a.png, --mask b.png"``
        for several, in the order given.

    Examples
    --------
    >>> check_inputs_exist(["/", None, ("--root", "/")])
    >>> check_inputs_exist(["/nope/a.png", ("--mask", "/nope/b.png")])
    Traceback (most recent call last):
    ...
    treeform._shared.errors.InputError: no such files: /nope/a.png, --mask /nope/b.png
    """
    import os

    missing = []
    for item in inputs:
        label, path = item if isinstance(item, tuple) else (None, item)
        if path is None or os.path.exists(path):
            continue
        missing.append(f"{label} {os.fspath(path)}" if label else os.fspath(path))
    if len(missing) == 1:
        raise InputError(f"{missing[0]}: no such file")
    if missing:
        raise InputError(f"no such files: {', '.join(missing)}")
