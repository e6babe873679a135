"""save(obj, path) dispatch by extension."""

from __future__ import annotations

import json

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.io import known_extensions, read_glb_counts, read_skeleton_ply, save
from treeform.structures.photo import Photo
from treeform.structures.skeleton import TreeSkeleton


def test_dispatch(tmp_path, tree_mesh, skeleton):
    from PIL import Image

    assert read_glb_counts(save(tree_mesh, tmp_path / "t.glb")) == (tree_mesh.n_vertices, tree_mesh.n_triangles)
    assert save(tree_mesh, tmp_path / "t.OBJ").exists() and (tmp_path / "t.mtl").exists()
    assert TreeSkeleton.load(save(skeleton, tmp_path / "s.json")).n_nodes == skeleton.n_nodes
    assert json.loads((tmp_path / "s.json").read_text())["format"] == "treeform.skeleton"
    assert len(read_skeleton_ply(save(skeleton, tmp_path / "s.ply"))[0]) == skeleton.n_nodes
    img = np.arange(16 * 20 * 3, dtype=np.uint8).reshape(16, 20, 3)
    np.testing.assert_array_equal(np.asarray(Image.open(save(img, tmp_path / "i.png"))), img)
    np.testing.assert_array_equal(np.asarray(Image.open(save(Photo(img), tmp_path / "p.png"))), img)


def test_unknown_extension_lists_known_ones(tmp_path, tree_mesh):
    with pytest.raises(InputError) as err:
        save(tree_mesh, tmp_path / "tree.fbx")
    msg = str(err.value)
    assert "'.fbx'" in msg and "\n" not in msg
    for ext in known_extensions():
        assert ext in msg
    assert known_extensions() == [".glb", ".json", ".obj", ".ply", ".png"]
    with pytest.raises(InputError, match="no extension"):
        save(tree_mesh, tmp_path / "tree")
    assert list(tmp_path.iterdir()) == []


def test_wrong_object_for_extension(tmp_path, tree_mesh, skeleton):
    with pytest.raises(InputError, match=r"cannot save a Mesh as \.ply.*\.glb, \.obj"):
        save(tree_mesh, tmp_path / "t.ply")
    with pytest.raises(InputError, match=r"cannot save a TreeSkeleton as \.glb.*\.json, \.ply"):
        save(skeleton, tmp_path / "s.glb")
    with pytest.raises(InputError, match=r"cannot save a str as \.png"):
        save("hello", tmp_path / "s.png")
