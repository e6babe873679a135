"""Read a tree written by treeform (an output folder, a skeleton JSON or a GLB) for re-use."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from treeform._shared.errors import InputError
from treeform.structures.skeleton import TreeSkeleton


def read_tree(path) -> TreeSkeleton | np.ndarray:
    """The skeleton of a treeform tree, or the vertices of any GLB tree.

    ``path`` may be an output folder of ``treeform grow`` / ``reconstruct`` (its
    ``skeleton.json`` is read, else its ``tree.glb``), a skeleton ``.json``, or a ``.glb``
    (a treeform GLB with ``skeleton.json`` beside it gives that skeleton; any other GLB gives
    its vertex positions in world space, Y up).

    Parameters
    ----------
    path : str or path-like

    Returns
    -------
    TreeSkeleton or ndarray, shape (V, 3), float64

    Raises
    ------
    InputError
        A missing path, a folder with neither file, an unknown extension, or a malformed file
        (the message names the file).

    Examples
    --------
    >>> import tempfile
    >>> d = Path(tempfile.mkdtemp())
    >>> _ = TreeSkeleton(np.array([[0, 0, 0], [0, 1, 0.]]), np.array([-1, 0])).save(d / "skeleton.json")
    >>> read_tree(d).n_nodes
    2
    """
    from treeform.io.gltf import read_glb_geometry

    p = Path(path)
    if not p.exists():
        raise InputError(f"{p}: no such file or folder")
    if p.is_dir():
        for name in ("skeleton.json", "tree.glb"):
            if (p / name).is_file():
                return read_tree(p / name)
        raise InputError(f"{p}: no skeleton.json or tree.glb in this folder (expected a treeform output folder)")
    suffix = p.suffix.lower()
    if suffix == ".json":
        return TreeSkeleton.load(p)
    if suffix == ".glb":
        beside = p.with_name("skeleton.json")
        if beside.is_file():
            return TreeSkeleton.load(beside)
        return read_glb_geometry(p)[0]
    raise InputError(f"{p}: unknown format {suffix or '(none)'}; expected a folder, a skeleton .json or a .glb")
