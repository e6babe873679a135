"""TreeSkeleton: an array-based branching graph (one root, parents before children)."""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from treeform._shared.errors import InputError

SKELETON_FORMAT = "treeform.skeleton"
SKELETON_VERSION = 1


def subtree_sizes(parent) -> np.ndarray:
    """(N,) number of nodes in each node's subtree, itself included, of a parent array (children after parents).

    >>> subtree_sizes(np.array([-1, 0, 1, 1, 0])).tolist()
    [5, 3, 1, 1, 1]
    """
    parent = np.asarray(parent, np.int64)
    size = np.ones(len(parent), np.int64)
    for i in range(len(parent) - 1, 0, -1):
        size[parent[i]] += size[i]
    return size


@dataclass
class TreeSkeleton:
    """A tree as nodes with a parent index each.

    Node 0 is the root (the trunk base) with ``parent[0] == -1``; every other node's
    parent has a smaller index, so a forward loop visits parents before children
    and a backward loop visits children before parents.

    Parameters
    ----------
    positions : ndarray, shape (N, 3), float64
        Node positions in metres, Y up, the root at the origin.
    parent : ndarray, shape (N,), int64
        Parent index, -1 for the root.
    radius : ndarray, shape (N,), float64
        Branch radius at the node in metres.
    order : ndarray, shape (N,), int32
        Branch order: 0 trunk, 1 its laterals, ...
    age : ndarray, shape (N,), float64, optional
        Creation step of each node (growth iteration).

    Examples
    --------
    >>> s = TreeSkeleton(np.array([[0, 0, 0], [0, 1, 0.]]), np.array([-1, 0]))
    >>> s.n_nodes, s.tips().tolist()
    (2, [1])
    """

    positions: np.ndarray
    parent: np.ndarray
    radius: np.ndarray | None = None
    order: np.ndarray | None = None
    age: np.ndarray | None = None
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        self.positions = np.ascontiguousarray(self.positions, dtype=np.float64).reshape(-1, 3)
        n = len(self.positions)
        self.parent = np.ascontiguousarray(self.parent, dtype=np.int64).reshape(-1)
        self.radius = np.full(n, 0.01) if self.radius is None else np.ascontiguousarray(self.radius, dtype=np.float64).reshape(-1)
        self.order = np.zeros(n, np.int32) if self.order is None else np.ascontiguousarray(self.order, dtype=np.int32).reshape(-1)
        self.age = np.zeros(n) if self.age is None else np.ascontiguousarray(self.age, dtype=np.float64).reshape(-1)
        self.validate()

    @property
    def n_nodes(self) -> int:
        return len(self.positions)

    def validate(self) -> None:
        n = len(self.positions)
        if n < 1:
            raise InputError("TreeSkeleton: needs at least one node")
        for name in ("parent", "radius", "order", "age"):
            if len(getattr(self, name)) != n:
                raise InputError(f"TreeSkeleton.{name}: length {len(getattr(self, name))} != {n} nodes")
        if not np.all(np.isfinite(self.positions)) or not np.all(np.isfinite(self.radius)):
            raise InputError("TreeSkeleton: positions and radius must be finite")
        if self.parent[0] != -1 or np.any(self.parent[1:] < 0):
            raise InputError("TreeSkeleton.parent: node 0 must be the only root (parent -1)")
        if np.any(self.parent[1:] >= np.arange(1, n)):
            raise InputError("TreeSkeleton.parent: every parent index must be smaller than its child's")
        if np.any(self.radius < 0):
            raise InputError("TreeSkeleton.radius: must be non-negative")

    def child_counts(self) -> np.ndarray:
        """(N,) number of children of each node."""
        return np.bincount(self.parent[1:], minlength=self.n_nodes)

    def subtree_sizes(self) -> np.ndarray:
        """(N,) number of nodes in each node's subtree, itself included (:func:`subtree_sizes`)."""
        return subtree_sizes(self.parent)

    def tips(self) -> np.ndarray:
        """Indices of the terminal nodes (no children)."""
        return np.flatnonzero(self.child_counts() == 0)

    def segment_lengths(self) -> np.ndarray:
        """(N,) length of the segment from each node's parent to it (0 for the root)."""
        d = np.zeros(self.n_nodes)
        d[1:] = np.linalg.norm(self.positions[1:] - self.positions[self.parent[1:]], axis=1)
        return d

    def chains(self) -> list[np.ndarray]:
        """Split the graph into branches: lists of node indices from a branch start to a tip.

        A chain starts at the root or at a node's parent, and continues through the child
        with the largest radius (the child with the same order first); the other children
        start new chains that begin at their parent node, so meshes join without gaps.
        """
        n = self.n_nodes
        children: list[list[int]] = [[] for _ in range(n)]
        for i in range(1, n):
            children[self.parent[i]].append(i)
        chains = []
        stack = [(0, -1)]
        while stack:
            start, from_node = stack.pop()
            chain = [from_node, start] if from_node >= 0 else [start]
            node = start
            while children[node]:
                kids = children[node]
                main = max(kids, key=lambda k: (self.order[k] == self.order[node], self.radius[k], -k))
                for k in kids:
                    if k != main:
                        stack.append((k, node))
                chain.append(main)
                node = main
            chains.append(np.array(chain, dtype=np.int64))
        return chains

    def nearest_kept(self, keep) -> np.ndarray:
        """(N,) int64: for each node, the nearest of it and its ancestors that ``keep`` selects (-1: none).

        Examples
        --------
        >>> s = TreeSkeleton(np.array([[0, 0, 0], [0, 1, 0], [1, 1, 0], [0, 2, 0.]]), np.array([-1, 0, 1, 1]))
        >>> s.nearest_kept([True, False, True, False]).tolist()
        [0, 0, 2, 0]
        """
        keep = np.asarray(keep, bool).reshape(-1)
        if len(keep) != self.n_nodes:
            raise InputError(f"TreeSkeleton.nearest_kept: keep has {len(keep)} entries for {self.n_nodes} nodes")
        out = np.where(keep, np.arange(self.n_nodes), -1)
        for i in range(1, self.n_nodes):  # parents come first
            if not keep[i]:
                out[i] = out[self.parent[i]]
        return out

    def prune(self, keep) -> tuple["TreeSkeleton", np.ndarray]:
        """The nodes selected by ``keep`` whose ancestors are all selected (a dropped node takes
        its subtree with it); the root always stays.

        Returns
        -------
        (TreeSkeleton, ndarray (N,) int64)
            The pruned skeleton and each old node's new index (-1 where dropped).

        Examples
        --------
        >>> s = TreeSkeleton(np.array([[0, 0, 0], [0, 1, 0], [1, 1, 0], [0, 2, 0.]]), np.array([-1, 0, 1, 1]))
        >>> t, new = s.prune([True, True, False, True])
        >>> t.n_nodes, new.tolist(), t.parent.tolist()
        (3, [0, 1, -1, 2], [-1, 0, 1])
        """
        keep = np.asarray(keep, bool).reshape(-1).copy()
        if len(keep) != self.n_nodes:
            raise InputError(f"TreeSkeleton.prune: keep has {len(keep)} entries for {self.n_nodes} nodes")
        keep[0] = True
        for i in range(1, self.n_nodes):  # parents come first: one forward sweep closes the set
            keep[i] = keep[i] and keep[self.parent[i]]
        return self.splice(keep)  # every kept node's parent is kept: nothing is re-hung

    def splice(self, keep) -> tuple["TreeSkeleton", np.ndarray]:
        """The nodes selected by ``keep``, each hung, where it is, from its nearest selected ancestor
        (unlike :meth:`prune`, a dropped node leaves its subtree); the root always stays.

        Returns
        -------
        (TreeSkeleton, ndarray (N,) int64)
            The spliced skeleton and each old node's new index (-1 where dropped).

        Examples
        --------
        >>> s = TreeSkeleton(np.array([[0, 0, 0], [0, 1, 0], [1, 1, 0], [0, 2, 0.]]), np.array([-1, 0, 1, 1]))
        >>> t, new = s.splice([True, False, True, True])
        >>> new.tolist(), t.parent.tolist()
        ([0, -1, 1, 2], [-1, 0, 0])
        """
        keep = np.asarray(keep, bool).reshape(-1).copy()
        if len(keep) != self.n_nodes:
            raise InputError(f"TreeSkeleton.splice: keep has {len(keep)} entries for {self.n_nodes} nodes")
        keep[0] = True
        idx = np.flatnonzero(keep)
        new = np.full(self.n_nodes, -1, np.int64)
        new[idx] = np.arange(len(idx))
        above = self.nearest_kept(keep)[np.maximum(self.parent[idx], 0)]
        parent = np.where(self.parent[idx] >= 0, new[above], -1)
        return TreeSkeleton(self.positions[idx], parent, self.radius[idx], self.order[idx], self.age[idx],
                            dict(self.meta)), new

    # ------------------------------------------------------------------ io
    def to_dict(self) -> dict:
        """A JSON-ready dict; floats rounded to 1e-6 m so output is byte-stable."""
        return {
            "format": SKELETON_FORMAT,
            "version": SKELETON_VERSION,
            "units": "metres",
            "up": "+Y",
            "n_nodes": self.n_nodes,
            "positions": np.round(self.positions, 6).tolist(),
            "parent": self.parent.tolist(),
            "radius": np.round(self.radius, 6).tolist(),
            "order": self.order.tolist(),
            "age": np.round(self.age, 6).tolist(),
            "meta": self.meta,
        }

    @classmethod
    def from_dict(cls, d: dict) -> "TreeSkeleton":
        if not isinstance(d, dict) or d.get("format") != SKELETON_FORMAT:
            raise InputError("not a treeform skeleton (missing format 'treeform.skeleton')")
        try:
            return cls(
                np.array(d["positions"], dtype=np.float64),
                np.array(d["parent"], dtype=np.int64),
                np.array(d["radius"], dtype=np.float64),
                np.array(d["order"], dtype=np.int32),
                np.array(d.get("age", np.zeros(len(d["parent"]))), dtype=np.float64),
                dict(d.get("meta", {})),
            )
        except KeyError as exc:
            raise InputError(f"skeleton JSON lacks the field {exc}") from None

    def to_json(self) -> str:
        """The skeleton JSON text (compact, sorted keys): same skeleton -> same bytes."""
        return json.dumps(self.to_dict(), separators=(",", ":"), sort_keys=True)

    def save(self, path) -> Path:
        """Write skeleton JSON atomically."""
        path = Path(path)
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(self.to_json())
        os.replace(tmp, path)
        return path

    @classmethod
    def load(cls, path) -> "TreeSkeleton":
        path = Path(path)
        try:
            d = json.loads(Path(path).read_text())
        except FileNotFoundError:
            raise InputError(f"{path}: no such file") from None
        except (UnicodeDecodeError, json.JSONDecodeError):
            raise InputError(f"{path}: not a JSON file") from None
        return cls.from_dict(d)
