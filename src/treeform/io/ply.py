"""PLY (binary little-endian) export of a :class:`TreeSkeleton` as a graph: nodes and edges.

Readable by MeshLab, CloudCompare, Blender (edges) and plyfile. Coordinates are written
unchanged (metres, +Y up).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from treeform._shared.errors import InputError
from treeform.io._atomic import atomic_path
from treeform.structures.skeleton import TreeSkeleton

__all__ = ["write_skeleton_ply", "read_skeleton_ply", "write_points_ply", "read_points_ply"]

POINT_LABELS = {0: "background", 1: "branch", 2: "leaf"}
"""``label`` values of :func:`write_points_ply` (seed 002 §4.2's point partition)."""

_VERTEX_DTYPE = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("radius", "<f4"), ("order", "<i4")])
_EDGE_DTYPE = np.dtype([("vertex1", "<i4"), ("vertex2", "<i4")])

_PLY_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}


def write_points_ply(path, points, colors, labels) -> Path:
    """Write a labelled, coloured point cloud as a binary little-endian PLY, atomically.

    Elements: ``vertex`` with ``x y z`` (float32), ``red green blue`` (uchar) and ``label``
    (uchar, :data:`POINT_LABELS`: 0 background, 1 branch, 2 leaf).

    Parameters
    ----------
    path : str or path-like
    points : ndarray, shape (N, 3)
    colors : ndarray, shape (N, 3), uint8
    labels : ndarray, shape (N,), uint8

    Examples
    --------
    >>> import tempfile, os
    >>> p = os.path.join(tempfile.mkdtemp(), "p.ply")
    >>> _ = write_points_ply(p, [[0, 1, 2.0]], [[255, 0, 0]], [1])
    >>> read_points_ply(p)[2].tolist()
    [1]
    """
    pts = np.asarray(points, np.float64).reshape(-1, 3)
    n = len(pts)
    cols = np.asarray(colors).reshape(-1, 3)
    labs = np.asarray(labels).reshape(-1)
    if len(cols) != n or len(labs) != n:
        raise InputError(f"write_points_ply: {n} points, {len(cols)} colours, {len(labs)} labels")
    dt = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("red", "u1"), ("green", "u1"), ("blue", "u1"),
                   ("label", "u1")])
    verts = np.empty(n, dt)
    verts["x"], verts["y"], verts["z"] = pts.T
    verts["red"], verts["green"], verts["blue"] = np.clip(cols, 0, 255).astype(np.uint8).T
    verts["label"] = labs.astype(np.uint8)
    return _write_binary_ply(path, "treeform points: metres, +Y up; label 0 background, 1 branch, 2 leaf",
                             [("vertex", verts)])


def read_points_ply(path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Read :func:`write_points_ply`'s file: points (N, 3), colours (N, 3) uint8, labels (N,)."""
    path = Path(path)
    data = path.read_bytes()
    elements, start = _parse_header(path, data)
    if not elements or elements[0][0] != "vertex" or \
            list(elements[0][2].names)[:7] != ["x", "y", "z", "red", "green", "blue", "label"]:
        raise InputError(f"{path}: not a treeform points PLY")
    _name, n, dt = elements[0]
    v = np.frombuffer(data, dt, count=n, offset=start)
    return (np.column_stack([v["x"], v["y"], v["z"]]).astype(np.float64),
            np.column_stack([v["red"], v["green"], v["blue"]]), v["label"].copy())


def write_skeleton_ply(skeleton: TreeSkeleton, path) -> Path:
    """Write ``skeleton`` as a binary little-endian PLY graph, atomically.

    Elements: ``vertex`` with ``x y z radius`` (float32) and ``order`` (int32), one per node;
    ``edge`` with ``vertex1 vertex2`` (int32), one ``(parent, child)`` pair per non-root node.

    Parameters
    ----------
    skeleton : TreeSkeleton
        N nodes; positions (N, 3) in metres, +Y up.
    path : str or path-like

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    InputError
        ``skeleton`` is not a TreeSkeleton or fails validation.
    OutputError
        ``path`` cannot be written.
    """
    if not isinstance(skeleton, TreeSkeleton):
        raise InputError(f"skeleton: expected a TreeSkeleton, got {type(skeleton).__name__}")
    skeleton.validate()
    n = skeleton.n_nodes
    verts = np.empty(n, _VERTEX_DTYPE)
    verts["x"], verts["y"], verts["z"] = skeleton.positions.T
    verts["radius"] = skeleton.radius
    verts["order"] = skeleton.order
    edges = np.empty(n - 1, _EDGE_DTYPE)
    edges["vertex1"] = skeleton.parent[1:]
    edges["vertex2"] = np.arange(1, n)
    return _write_binary_ply(path, "treeform skeleton: metres, +Y up; edges are (parent, child)",
                             [("vertex", verts), ("edge", edges)])


_PLY_NAMES = {"<f4": "float", "<f8": "double", "<i4": "int", "|u1": "uchar", "|i1": "char", "<i2": "short",
              "<u2": "ushort", "<u4": "uint"}


def _write_binary_ply(path, comment: str, elements) -> Path:
    """Write ``elements`` (``(name, structured array)`` pairs) as binary little-endian PLY, atomically."""
    lines = ["ply", "format binary_little_endian 1.0", f"comment {comment}"]
    for name, arr in elements:
        lines.append(f"element {name} {len(arr)}")
        lines += [f"property {_PLY_NAMES[arr.dtype[f].str]} {f}" for f in arr.dtype.names]
    lines.append("end_header")
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as f:
            f.write(("\n".join(lines) + "\n").encode("ascii"))
            for _name, arr in elements:
                f.write(arr.tobytes())
    return Path(path)


def _parse_header(path: Path, data: bytes) -> tuple[list[tuple[str, int, np.dtype]], int]:
    end = data.find(b"end_header")
    if not data.startswith(b"ply") or end < 0:
        raise InputError(f"{path}: not a PLY file")
    nl = data.find(b"\n", end)
    if nl < 0:
        raise InputError(f"{path}: truncated PLY header")
    lines = data[:nl].decode("ascii", "replace").splitlines()
    elements: list[tuple[str, int, list]] = []
    for line in lines[1:]:
        tok = line.split()
        if not tok or tok[0] in ("comment", "obj_info", "end_header"):
            continue
        if tok[0] == "format":
            if len(tok) < 2 or tok[1] != "binary_little_endian":
                raise InputError(f"{path}: unsupported PLY format {' '.join(tok[1:2])!r}, expected binary_little_endian")
        elif tok[0] == "element" and len(tok) == 3:
            elements.append((tok[1], int(tok[2]), []))
        elif tok[0] == "property" and elements:
            if tok[1] == "list":
                raise InputError(f"{path}: PLY list properties are not supported ({line.strip()!r})")
            if len(tok) != 3 or tok[1] not in _PLY_TYPES:
                raise InputError(f"{path}: bad PLY property line {line.strip()!r}")
            elements[-1][2].append((tok[2], "<" + _PLY_TYPES[tok[1]]))
        else:
            raise InputError(f"{path}: bad PLY header line {line.strip()!r}")
    return [(name, count, np.dtype(props)) for name, count, props in elements], nl + 1


def read_skeleton_ply(path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Read a skeleton PLY graph (as written by :func:`write_skeleton_ply`).

    Parameters
    ----------
    path : str or path-like
        A binary little-endian PLY with scalar properties only.

    Returns
    -------
    positions : ndarray, shape (N, 3), float64
    radius : ndarray, shape (N,), float64
        Zeros when the file has no ``radius`` property.
    edges : ndarray, shape (E, 2), int64
        ``(vertex1, vertex2)`` pairs, i.e. ``(parent, child)`` for our files.

    Raises
    ------
    InputError
        Missing, truncated or unsupported file.
    """
    path = Path(path)
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise InputError(f"{path}: is a directory, not a PLY file") from None
    elements, offset = _parse_header(path, data)
    arrays = {}
    for name, count, dtype in elements:
        size = count * dtype.itemsize
        if offset + size > len(data):
            raise InputError(f"{path}: truncated PLY file (element {name!r})")
        arrays[name] = np.frombuffer(data, dtype=dtype, count=count, offset=offset)
        offset += size
    v = arrays.get("vertex")
    if v is None or not {"x", "y", "z"} <= set(v.dtype.names or ()):
        raise InputError(f"{path}: PLY file has no vertex x y z")
    positions = np.column_stack([v["x"], v["y"], v["z"]]).astype(np.float64)
    radius = v["radius"].astype(np.float64) if "radius" in v.dtype.names else np.zeros(len(v))
    e = arrays.get("edge")
    if e is None:
        edges = np.zeros((0, 2), np.int64)
    elif not {"vertex1", "vertex2"} <= set(e.dtype.names or ()):
        raise InputError(f"{path}: PLY edge element lacks vertex1/vertex2")
    else:
        edges = np.column_stack([e["vertex1"], e["vertex2"]]).astype(np.int64)
    return positions, radius, edges
