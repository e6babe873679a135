"""Deterministic npz save/load used by the containers (atomic: temp file, then rename)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from treeform._shared.errors import InputError


def save_npz(path, kind: str, **arrays) -> Path:
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp.npz")
    np.savez_compressed(tmp, __kind__=np.array(kind), **arrays)
    os.replace(tmp, path)
    return path


def load_npz(path, kind: str) -> dict:
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except Exception as exc:
        raise InputError(f"{path}: not a treeform {kind} file ({type(exc).__name__})") from None
    if str(data.pop("__kind__", "")) != kind:
        raise InputError(f"{path}: not a treeform {kind} file")
    return data
