"""OBJ + MTL + PNG writer."""

from __future__ import annotations

import numpy as np
import pytest

from treeform._shared.errors import InputError, OutputError
from treeform.io import obj as obj_mod
from treeform.io import write_obj


def _parse_obj(text: str):
    v, vt, vn, faces, usemtl, groups = [], [], [], [], [], []
    for line in text.splitlines():
        tok = line.split()
        if not tok or tok[0] == "#":
            continue
        if tok[0] == "v":
            v.append([float(x) for x in tok[1:]])
        elif tok[0] == "vt":
            vt.append([float(x) for x in tok[1:]])
        elif tok[0] == "vn":
            vn.append([float(x) for x in tok[1:]])
        elif tok[0] == "f":
            faces.append([[int(i) for i in c.split("/")] for c in tok[1:]])
        elif tok[0] == "usemtl":
            usemtl.append(tok[1])
        elif tok[0] == "g":
            groups.append(tok[1])
    return v, vt, vn, np.array(faces), usemtl, groups


def _parse_mtl(text: str) -> dict:
    mats, cur = {}, None
    for line in text.splitlines():
        tok = line.split()
        if not tok:
            continue
        if tok[0] == "newmtl":
            cur = mats.setdefault(tok[1], {})
        elif cur is not None:
            cur[tok[0]] = tok[1:]
    return mats


def test_obj_mtl_png_round_trip(tmp_path, tree_mesh):
    from PIL import Image

    path = write_obj(tree_mesh, tmp_path / "tree.obj")
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["tree.mtl", "tree.obj", "tree_leaf.png", "tree_veil.png"]
    text = path.read_text()
    assert "mtllib tree.mtl" in text
    v, vt, vn, faces, usemtl, groups = _parse_obj(text)
    assert len(v) == len(vt) == len(vn) == tree_mesh.n_vertices
    assert len(faces) == tree_mesh.n_triangles
    assert usemtl == ["bark", "leaf", "veil"] and groups == ["bark", "leaves", "veil"]
    assert faces.min() == 1 and faces.max() == tree_mesh.n_vertices
    # v/vt/vn share one index per corner
    assert np.all(faces[..., 0] == faces[..., 1]) and np.all(faces[..., 0] == faces[..., 2])
    parts = [p for p in tree_mesh.parts if p.n_triangles]
    np.testing.assert_allclose(np.array([x[:3] for x in v]), np.concatenate([p.positions for p in parts]), atol=1e-5)
    # colours only on the coloured bark part
    assert len(v[0]) == 6 and len(v[-1]) == 3
    # OBJ texture origin is bottom-left: vt = (u, 1 - v)
    uvs = np.concatenate([p.uvs for p in parts])
    np.testing.assert_allclose(np.array(vt), np.column_stack([uvs[:, 0], 1 - uvs[:, 1]]), atol=1e-5)
    # faces index the right vertices
    bark = parts[0]
    np.testing.assert_array_equal(faces[: bark.n_triangles, :, 0] - 1, bark.indices)
    offset = bark.n_vertices
    leaves = parts[1]
    np.testing.assert_array_equal(faces[bark.n_triangles: bark.n_triangles + leaves.n_triangles, :, 0] - 1 - offset,
                                  leaves.indices)

    mtl = _parse_mtl((tmp_path / "tree.mtl").read_text())
    assert set(mtl) == {"bark", "leaf", "veil"}
    assert [float(x) for x in mtl["bark"]["Kd"]] == pytest.approx([0.35, 0.25, 0.15])
    assert "map_Kd" not in mtl["bark"]
    assert mtl["leaf"]["map_Kd"] == ["tree_leaf.png"] and mtl["leaf"]["map_d"] == ["tree_leaf.png"]
    assert float(mtl["veil"]["d"][0]) == pytest.approx(0.5)
    assert "map_d" not in mtl["veil"]  # BLEND by factor only; its texture is opaque
    png = np.asarray(Image.open(tmp_path / "tree_leaf.png").convert("RGBA"))
    np.testing.assert_array_equal(png, tree_mesh.parts[1].material.texture)


def test_trimesh_reads_obj(tmp_path, tree_mesh):
    trimesh = pytest.importorskip("trimesh")
    path = write_obj(tree_mesh, tmp_path / "tree.obj")
    loaded = trimesh.load(path, process=False, force="scene")
    assert sum(len(g.faces) for g in loaded.geometry.values()) == tree_mesh.n_triangles


def test_obj_errors_and_atomicity(tmp_path, tree_mesh, monkeypatch):
    with pytest.raises(InputError, match="Mesh"):
        write_obj([1, 2, 3], tmp_path / "x.obj")
    with pytest.raises(OutputError, match="does not exist"):
        write_obj(tree_mesh, tmp_path / "no" / "x.obj")

    def boom(*a, **k):
        raise RuntimeError("disk full")

    monkeypatch.setattr(obj_mod, "_write_rows", boom)
    with pytest.raises(RuntimeError):
        write_obj(tree_mesh, tmp_path / "tree.obj")
    assert list(tmp_path.iterdir()) == []  # neither the PNGs nor the MTL nor temp files remain


def test_unsafe_material_names_are_sanitised(tmp_path, make_cylinder):
    from treeform.structures.mesh import Material, Mesh

    mesh = Mesh([make_cylinder(material=Material("my bark/../x", texture=np.zeros((4, 4, 4), np.uint8))),
                 make_cylinder(material=Material("my bark/../x"))])
    write_obj(mesh, tmp_path / "t.obj")
    mtl = _parse_mtl((tmp_path / "t.mtl").read_text())
    assert set(mtl) == {"my_bark_x", "my_bark_x_2"}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.mtl", "t.obj", "t_my_bark_x.png"]
