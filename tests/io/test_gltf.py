"""GLB writer: structure, alignment, round trips (own reader, trimesh), Khronos validator."""

from __future__ import annotations

import io
import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from treeform._shared.errors import InputError, OutputError
from treeform.io import gltf as gltf_mod
from treeform.io import read_glb, read_glb_counts, write_glb
from treeform.io.gltf import accessor_array
from treeform.structures.mesh import Material, Mesh

REPO = Path(__file__).resolve().parents[2]
VALIDATOR_SCRIPT = REPO / "tools" / "gltf_validate.mjs"
VALIDATOR_PACKAGE = REPO / "tools" / "node_modules" / "gltf-validator"


@pytest.fixture
def glb(tmp_path, tree_mesh):
    path = write_glb(tree_mesh, tmp_path / "tree.glb", generator="treeform-test")
    return path, tree_mesh


def test_header_chunks_and_alignment(glb):
    path, _ = glb
    data = path.read_bytes()
    magic, version, length = np.frombuffer(data[:12], "<u4")
    assert data[:4] == b"glTF" and version == 2 and length == len(data)
    assert len(data) % 4 == 0
    jlen, jtype = np.frombuffer(data[12:20], "<u4")
    assert data[16:20] == b"JSON" and jlen % 4 == 0
    json_chunk = data[20:20 + jlen]
    assert json_chunk == json_chunk.rstrip(b" ") + b" " * (len(json_chunk) - len(json_chunk.rstrip(b" ")))
    blen, _ = np.frombuffer(data[20 + jlen:28 + jlen], "<u4")
    assert data[24 + jlen:28 + jlen] == b"BIN\0" and blen % 4 == 0
    assert 28 + jlen + blen == len(data)
    gltf, bin_chunk = read_glb(path)
    assert gltf["buffers"] == [{"byteLength": len(bin_chunk)}]
    for view in gltf["bufferViews"]:
        assert view["byteOffset"] % 4 == 0
        assert view["byteOffset"] + view["byteLength"] <= len(bin_chunk)


def test_document_contents(glb):
    path, mesh = glb
    gltf, bin_chunk = read_glb(path)
    assert gltf["asset"] == {"version": "2.0", "generator": "treeform-test"}
    assert gltf["scene"] == 0 and gltf["scenes"][0]["nodes"] == [0]
    assert len(gltf["nodes"]) == 1 and gltf["nodes"][0]["mesh"] == 0
    assert gltf["nodes"][0]["name"] == gltf["meshes"][0]["name"] == "bark+leaves+veil"  # empty part skipped
    prims = gltf["meshes"][0]["primitives"]
    assert [p["extras"]["name"] for p in prims] == ["bark", "leaves", "veil"]
    parts = [p for p in mesh.parts if p.n_triangles]
    for prim, part in zip(prims, parts):
        attrs = prim["attributes"]
        assert {"POSITION", "NORMAL", "TEXCOORD_0"} <= set(attrs)
        # COLOR_0 only where colours are not all 1
        assert ("COLOR_0" in attrs) == bool(np.any(part.colors != 1))
        pos_acc = gltf["accessors"][attrs["POSITION"]]
        assert pos_acc["min"] == part.positions.min(0).tolist()
        assert pos_acc["max"] == part.positions.max(0).tolist()
        np.testing.assert_array_equal(accessor_array(gltf, bin_chunk, attrs["POSITION"]), part.positions)
        normals = accessor_array(gltf, bin_chunk, attrs["NORMAL"])
        np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-6)
        np.testing.assert_array_equal(accessor_array(gltf, bin_chunk, attrs["TEXCOORD_0"]), part.uvs)
        if "COLOR_0" in attrs:
            acc = gltf["accessors"][attrs["COLOR_0"]]
            assert (acc["componentType"], acc["type"]) == (5126, "VEC4")
            np.testing.assert_array_equal(accessor_array(gltf, bin_chunk, attrs["COLOR_0"]), part.colors)
        idx = gltf["accessors"][prim["indices"]]
        assert idx["componentType"] == 5123  # small parts -> UNSIGNED_SHORT
        np.testing.assert_array_equal(accessor_array(gltf, bin_chunk, prim["indices"]).reshape(-1, 3), part.indices)
    mats = gltf["materials"]
    assert [m["alphaMode"] for m in mats] == ["OPAQUE", "MASK", "BLEND"]
    assert [("alphaCutoff" in m) for m in mats] == [False, True, False]
    assert mats[1]["alphaCutoff"] == pytest.approx(0.4)
    assert [m["doubleSided"] for m in mats] == [False, True, False]
    assert mats[2]["pbrMetallicRoughness"]["baseColorFactor"] == [0.5, 0.6, 0.7, 0.5]
    assert mats[0]["pbrMetallicRoughness"]["roughnessFactor"] == pytest.approx(0.95)
    assert "baseColorTexture" not in mats[0]["pbrMetallicRoughness"]
    assert gltf["samplers"] == [{"magFilter": 9729, "minFilter": 9987, "wrapS": 10497, "wrapT": 10497}]
    assert all(im["mimeType"] == "image/png" and "bufferView" in im for im in gltf["images"])
    assert len(gltf["textures"]) == 2


def test_texture_pixels_round_trip(glb):
    from PIL import Image

    path, mesh = glb
    gltf, bin_chunk = read_glb(path)
    for mat, part in zip(gltf["materials"][1:], [mesh.parts[1], mesh.parts[3]]):
        tex = gltf["textures"][mat["pbrMetallicRoughness"]["baseColorTexture"]["index"]]
        image = gltf["images"][tex["source"]]
        view = gltf["bufferViews"][image["bufferView"]]
        png = bin_chunk[view["byteOffset"]: view["byteOffset"] + view["byteLength"]]
        assert png[:8] == b"\x89PNG\r\n\x1a\n"
        pixels = np.asarray(Image.open(io.BytesIO(png)).convert("RGBA"))
        np.testing.assert_array_equal(pixels, part.material.texture)


def test_read_glb_textures(glb, tmp_path):
    from treeform.io.gltf import read_glb_textures

    path, mesh = glb
    tex = read_glb_textures(path)
    assert set(tex) == {"leaf", "veil"}  # the bark material has no texture
    np.testing.assert_array_equal(tex["leaf"], mesh.parts[1].material.texture)
    np.testing.assert_array_equal(tex["veil"], mesh.parts[3].material.texture)  # stored as RGB, read as RGBA
    with pytest.raises(InputError, match="GLB"):
        read_glb_textures(REPO / "pyproject.toml")


def test_counts_round_trip(glb):
    path, mesh = glb
    assert read_glb_counts(path) == (mesh.n_vertices, mesh.n_triangles)


def test_trimesh_loads_same_counts(glb):
    trimesh = pytest.importorskip("trimesh")
    path, mesh = glb
    scene = trimesh.load(path, process=False)
    geoms = list(scene.geometry.values()) if hasattr(scene, "geometry") else [scene]
    assert sum(len(g.vertices) for g in geoms) == mesh.n_vertices
    assert sum(len(g.faces) for g in geoms) == mesh.n_triangles


def test_large_part_uses_uint32_indices(tmp_path, make_cylinder):
    part = make_cylinder(n=300, rings=240, name="big")  # 72000 vertices > 65535
    path = write_glb(Mesh([part]), tmp_path / "big.glb")
    gltf, bin_chunk = read_glb(path)
    prim = gltf["meshes"][0]["primitives"][0]
    assert gltf["accessors"][prim["indices"]]["componentType"] == 5125
    np.testing.assert_array_equal(accessor_array(gltf, bin_chunk, prim["indices"]).reshape(-1, 3), part.indices)
    assert read_glb_counts(path) == (part.n_vertices, part.n_triangles)


def test_shared_material_written_once(tmp_path, make_cylinder):
    mat = Material("shared", texture=np.full((4, 4, 4), 200, np.uint8))
    mesh = Mesh([make_cylinder(material=mat, name="a"), make_cylinder(material=mat, name="b")])
    gltf, _ = read_glb(write_glb(mesh, tmp_path / "m.glb"))
    assert len(gltf["materials"]) == 1 and len(gltf["images"]) == 1
    assert {p["material"] for p in gltf["meshes"][0]["primitives"]} == {0}


def test_zero_normals_become_unit(tmp_path, make_cylinder):
    part = make_cylinder()
    part.normals[:3] = 0
    gltf, bin_chunk = read_glb(write_glb(Mesh([part]), tmp_path / "z.glb"))
    n = accessor_array(gltf, bin_chunk, gltf["meshes"][0]["primitives"][0]["attributes"]["NORMAL"])
    np.testing.assert_allclose(np.linalg.norm(n, axis=1), 1.0, atol=1e-6)


def test_bad_inputs(tmp_path, make_cylinder):
    with pytest.raises(InputError, match="Mesh"):
        write_glb("not a mesh", tmp_path / "x.glb")
    with pytest.raises(InputError, match="no non-empty part"):
        write_glb(Mesh([]), tmp_path / "x.glb")
    part = make_cylinder()
    part.uvs[0, 0] = np.nan
    with pytest.raises(InputError, match="uvs"):
        write_glb(Mesh([part]), tmp_path / "x.glb")
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(OutputError, match="does not exist"):
        write_glb(Mesh([make_cylinder()]), tmp_path / "missing" / "x.glb")
    (tmp_path / "junk.glb").write_bytes(b"hello world, not a glb file")
    with pytest.raises(InputError, match="not a GLB"):
        read_glb_counts(tmp_path / "junk.glb")
    with pytest.raises(InputError, match="no such file"):
        read_glb(tmp_path / "nope.glb")


def test_failure_leaves_no_partial_file(tmp_path, tree_mesh, monkeypatch):
    target = tmp_path / "tree.glb"
    target.write_bytes(b"previous")

    def boom(_):
        raise RuntimeError("encoder crashed")

    monkeypatch.setattr(gltf_mod, "_encode_png", boom)
    with pytest.raises(RuntimeError):
        write_glb(tree_mesh, target)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tree.glb"]
    assert target.read_bytes() == b"previous"


def _validator_available() -> bool:
    return shutil.which("node") is not None and VALIDATOR_PACKAGE.is_dir()


@pytest.mark.skipif(not _validator_available(), reason="node or tools/node_modules/gltf-validator missing "
                    "(install with: npm ci --prefix tools)")
def test_khronos_validator_reports_no_errors(glb):
    path, _ = glb
    proc = subprocess.run(["node", str(VALIDATOR_SCRIPT), str(path)], capture_output=True, text=True, timeout=120)
    assert proc.returncode in (0, 1), proc.stderr
    report = json.loads(proc.stdout)
    print(f"\nKhronos glTF validator {report['validator']}: {report['numErrors']} errors, "
          f"{report['numWarnings']} warnings, {report['numInfos']} infos, {report['numHints']} hints; "
          f"info codes {report['infoCodes']}")
    for m in report["messages"]:
        print(f"  {m['severity']}: {m['code']} at {m.get('pointer')}: {m['message']}")
    assert report["numErrors"] == 0, report["messages"]
    assert proc.returncode == 0
    assert report["numWarnings"] == 0, report["messages"]
    info = report["info"]
    assert info["hasTextures"] and info["drawCallCount"] == 3
    assert info["totalVertexCount"] == read_glb_counts(path)[0]
    assert info["totalTriangleCount"] == read_glb_counts(path)[1]


@pytest.mark.skipif(not _validator_available(), reason="node or tools/node_modules/gltf-validator missing")
def test_validator_script_fails_on_invalid_file(glb, tmp_path):
    """The tool itself must catch errors: a wrong POSITION min gives exit status 1."""
    import struct

    path, _ = glb
    gltf, bin_chunk = read_glb(path)
    gltf["accessors"][0]["min"] = [-100.0, -100.0, -100.0]
    js = json.dumps(gltf).encode()
    js += b" " * (-len(js) % 4)
    bad = tmp_path / "bad.glb"
    bad.write_bytes(struct.pack("<III", 0x46546C67, 2, 28 + len(js) + len(bin_chunk))
                    + struct.pack("<II", len(js), 0x4E4F534A) + js
                    + struct.pack("<II", len(bin_chunk), 0x004E4942) + bin_chunk)
    proc = subprocess.run(["node", str(VALIDATOR_SCRIPT), str(bad)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1
    report = json.loads(proc.stdout)
    assert report["numErrors"] >= 1
    assert "ACCESSOR_MIN_MISMATCH" in {m["code"] for m in report["messages"]}


def test_normal_mapped_parts_carry_unit_tangents_along_u(tmp_path):
    """A part with a normal texture gets TANGENT: unit, in the surface, along increasing u, w = +-1
    for the UV handedness; a part without one gets none."""
    from treeform.structures.mesh import MeshPart

    pos = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float32)
    nrm = np.tile(np.float32([0, 0, 1]), (4, 1))
    idx = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
    bump = np.full((4, 4, 4), 128, np.uint8)
    parts = []
    for flip in (False, True):
        uv = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)  # glTF: v = 0 at the top
        if flip:
            uv[:, 0] = 1 - uv[:, 0]  # u runs along -x: a mirrored mapping
        parts.append(MeshPart(pos, nrm, uv, np.ones((4, 4), np.float32), idx,
                              Material(name=f"bark{int(flip)}", normal_texture=bump), f"p{int(flip)}"))
    parts.append(MeshPart(pos, nrm, parts[0].uvs, np.ones((4, 4), np.float32), idx, Material(name="plain"), "q"))
    path = write_glb(Mesh(parts), tmp_path / "t.glb")
    gltf, bin_chunk = read_glb(path)
    prims = gltf["meshes"][0]["primitives"]
    t0 = accessor_array(gltf, bin_chunk, prims[0]["attributes"]["TANGENT"])
    t1 = accessor_array(gltf, bin_chunk, prims[1]["attributes"]["TANGENT"])
    assert "TANGENT" not in prims[2]["attributes"]
    np.testing.assert_allclose(t0[:, :3], np.tile([1, 0, 0], (4, 1)), atol=1e-6)
    np.testing.assert_allclose(t1[:, :3], np.tile([-1, 0, 0], (4, 1)), atol=1e-6)
    # bitangent = w * (n x t) points along increasing v: down the quad (v = 0 at the top)
    assert (t0[:, 3] == -1).all() and (t1[:, 3] == 1).all()


def test_read_glb_mesh_round_trip(tmp_path, tree_mesh):
    from treeform.io.gltf import read_glb_mesh, write_glb

    write_glb(tree_mesh, tmp_path / "t.glb")
    back = read_glb_mesh(tmp_path / "t.glb")
    parts = [p for p in tree_mesh.parts if p.n_triangles]
    assert [p.name for p in back.parts] == [p.material.name for p in parts]
    for a, b in zip(parts, back.parts):
        np.testing.assert_allclose(b.positions, a.positions, atol=1e-6)
        np.testing.assert_array_equal(b.indices, a.indices)
        np.testing.assert_allclose(b.uvs, a.uvs, atol=1e-7)
        np.testing.assert_allclose(b.colors, np.clip(a.colors, 0, 1), atol=1e-7)
        assert b.material.alpha_mode == a.material.alpha_mode
        assert b.material.double_sided == a.material.double_sided
        assert (b.material.texture is None) == (a.material.texture is None)
        if a.material.texture is not None:
            np.testing.assert_array_equal(b.material.texture, a.material.texture)
    (tmp_path / "bad.glb").write_bytes(b"glTF but not really")
    with pytest.raises(InputError):
        read_glb_mesh(tmp_path / "bad.glb")
