"""``save(obj, path)``: pick the writer from the file extension.

>>> from treeform.io import known_extensions
>>> known_extensions()
['.glb', '.json', '.obj', '.ply', '.png']
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from treeform._shared.errors import InputError
from treeform.structures.mesh import Mesh
from treeform.structures.photo import Photo
from treeform.structures.skeleton import TreeSkeleton

__all__ = ["save", "register_writer", "known_extensions"]


@dataclass(frozen=True)
class _Writer:
    types: tuple[type, ...]
    write: Callable[[object, Path], object]
    description: str


_WRITERS: dict[str, _Writer] = {}


def register_writer(ext: str, types, write: Callable[[object, Path], object], description: str = "") -> None:
    """Register ``write(obj, path)`` for files ending in ``ext`` holding objects of ``types``.

    Parameters
    ----------
    ext : str
        Extension with the dot, e.g. ``".glb"`` (case-insensitive).
    types : type or tuple of type
        Accepted object types.
    write : callable
        ``write(obj, path)``; must write atomically.
    description : str
        Shown in error messages, e.g. ``"glTF 2.0 binary"``.
    """
    ext = ext.lower()
    if not ext.startswith("."):
        raise InputError(f"ext: expected an extension starting with '.', got {ext!r}")
    _WRITERS[ext] = _Writer(types if isinstance(types, tuple) else (types,), write, description)


def known_extensions() -> list[str]:
    """Sorted list of the extensions :func:`save` knows."""
    return sorted(_WRITERS)


def save(obj, path) -> Path:
    """Write ``obj`` to ``path`` with the writer chosen by the extension.

    ============  ===============================  ==========================================
    extension     object                           writer
    ============  ===============================  ==========================================
    ``.glb``      :class:`Mesh`                    :func:`treeform.io.gltf.write_glb`
    ``.obj``      :class:`Mesh`                    :func:`treeform.io.obj.write_obj` (+ .mtl, .png)
    ``.json``     :class:`TreeSkeleton`            :meth:`TreeSkeleton.save`
    ``.ply``      :class:`TreeSkeleton`            :func:`treeform.io.ply.write_skeleton_ply`
    ``.png``      ndarray or :class:`Photo`        :func:`treeform.io.images.write_png`
    ============  ===============================  ==========================================

    Parameters
    ----------
    obj : Mesh, TreeSkeleton, ndarray or Photo
    path : str or path-like

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InputError
        Unknown extension (the message lists the known ones), or an object the extension's
        writer cannot hold (the message lists the extensions that can).
    OutputError
        ``path`` cannot be written.
    """
    path = Path(os.fspath(path))
    ext = path.suffix.lower()
    writer = _WRITERS.get(ext)
    if writer is None:
        got = f"extension {ext!r}" if ext else "no extension"
        raise InputError(f"{path}: cannot save a file with {got}; known extensions: {', '.join(known_extensions())}")
    if not isinstance(obj, writer.types):
        kind = type(obj).__name__
        fits = [e for e, w in sorted(_WRITERS.items()) if isinstance(obj, w.types)]
        hint = f"; a {kind} can be saved as {', '.join(fits)}" if fits else ""
        raise InputError(f"{path}: cannot save a {kind} as {ext} ({writer.description}){hint}")
    writer.write(obj, path)
    return path


def _write_glb(obj, path):
    from treeform.io.gltf import write_glb

    return write_glb(obj, path)


def _write_obj(obj, path):
    from treeform.io.obj import write_obj

    return write_obj(obj, path)


def _write_ply(obj, path):
    from treeform.io.ply import write_skeleton_ply

    return write_skeleton_ply(obj, path)


def _write_png(obj, path):
    from treeform.io.images import write_png

    return write_png(obj, path)


register_writer(".glb", Mesh, _write_glb, "glTF 2.0 binary mesh")
register_writer(".obj", Mesh, _write_obj, "Wavefront OBJ + MTL mesh")
register_writer(".json", TreeSkeleton, lambda obj, path: obj.save(path), "treeform skeleton JSON")
register_writer(".ply", TreeSkeleton, _write_ply, "PLY skeleton graph")
register_writer(".png", (np.ndarray, Photo), _write_png, "PNG image")
