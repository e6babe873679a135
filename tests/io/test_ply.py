"""Skeleton PLY writer/reader."""

from __future__ import annotations

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.io import read_skeleton_ply, write_skeleton_ply


def test_round_trip(tmp_path, skeleton):
    path = write_skeleton_ply(skeleton, tmp_path / "s.ply")
    data = path.read_bytes()
    header = data[: data.index(b"end_header\n") + 11].decode()
    assert "format binary_little_endian 1.0" in header
    assert f"element vertex {skeleton.n_nodes}" in header and f"element edge {skeleton.n_nodes - 1}" in header
    for prop in ("float x", "float y", "float z", "float radius", "int order", "int vertex1", "int vertex2"):
        assert f"property {prop}" in header
    assert len(data) == len(header) + skeleton.n_nodes * 20 + (skeleton.n_nodes - 1) * 8
    positions, radius, edges = read_skeleton_ply(path)
    np.testing.assert_allclose(positions, skeleton.positions, atol=1e-6)
    np.testing.assert_allclose(radius, skeleton.radius, atol=1e-7)
    np.testing.assert_array_equal(edges, np.column_stack([skeleton.parent[1:], np.arange(1, skeleton.n_nodes)]))
    order = np.frombuffer(data[len(header):], dtype=[("p", "<f4", 4), ("order", "<i4")], count=skeleton.n_nodes)["order"]
    np.testing.assert_array_equal(order, skeleton.order)


def test_single_node(tmp_path):
    from treeform.structures.skeleton import TreeSkeleton

    s = TreeSkeleton(np.zeros((1, 3)), np.array([-1]))
    positions, radius, edges = read_skeleton_ply(write_skeleton_ply(s, tmp_path / "one.ply"))
    assert positions.shape == (1, 3) and edges.shape == (0, 2)


def test_errors(tmp_path, skeleton):
    with pytest.raises(InputError, match="TreeSkeleton"):
        write_skeleton_ply(np.zeros((3, 3)), tmp_path / "x.ply")
    with pytest.raises(InputError, match="no such file"):
        read_skeleton_ply(tmp_path / "missing.ply")
    (tmp_path / "t.ply").write_text("hello")
    with pytest.raises(InputError, match="not a PLY"):
        read_skeleton_ply(tmp_path / "t.ply")
    data = write_skeleton_ply(skeleton, tmp_path / "s.ply").read_bytes()
    (tmp_path / "cut.ply").write_bytes(data[:-5])
    with pytest.raises(InputError, match="truncated"):
        read_skeleton_ply(tmp_path / "cut.ply")
    (tmp_path / "a.ply").write_text("ply\nformat ascii 1.0\nelement vertex 0\nend_header\n")
    with pytest.raises(InputError, match="binary_little_endian"):
        read_skeleton_ply(tmp_path / "a.ply")
