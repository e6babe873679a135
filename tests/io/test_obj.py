"""OBJ + MTL + PNG writer."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from treeform._shared.errors import InputError, OutputError
from treeform.io import obj as obj_mod
from treeform.io import write_obj
from treeform.io.gltf import read_glb_textures


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


# --------------------------------------------------------------------------- leaf colours
def _srgb_to_linear(c):
    c = np.asarray(c, np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def _obj_card_colours(obj_path, texture: np.ndarray) -> np.ndarray:
    """(M, 3) linear colour each leaf card of an OBJ shows: its faces' UVs pick a rectangle
    of the leaves material's PNG, whose opaque texels over ``texture``'s (both decoded from
    sRGB, weighted by alpha) give the colour the card multiplies the leaf texture with."""
    from PIL import Image

    text = obj_path.read_text()
    v, vt, _, faces, _, _ = _parse_obj(text)
    group_of_face, cur = [], None
    for line in text.splitlines():
        if line.startswith("g "):
            cur = line.split()[1]
        elif line.startswith("f "):
            group_of_face.append(cur)
    leaf_faces = faces[np.array(group_of_face) == "leaves"]
    assert all(len(x) == 3 for x in np.array(v, dtype=object)[leaf_faces[..., 0].ravel() - 1][:50])  # no v colours
    mtl = _parse_mtl(obj_path.with_suffix(".mtl").read_text())
    png = mtl["leaves"]["map_Kd"][0]
    assert mtl["leaves"]["map_d"] == [png]
    atlas = np.asarray(Image.open(obj_path.with_name(png)).convert("RGBA"))
    ah, aw = atlas.shape[:2]
    th, tw = texture.shape[:2]
    vt = np.array(vt)
    uv = vt[leaf_faces[..., 1] - 1].reshape(-1, 6, 2)  # two triangles per card
    x0 = np.rint(uv[..., 0].min(1) * aw).astype(int)
    y0 = np.rint((1 - uv[..., 1].max(1)) * ah).astype(int)  # OBJ's v grows upwards
    x1 = np.rint(uv[..., 0].max(1) * aw).astype(int)
    y1 = np.rint((1 - uv[..., 1].min(1)) * ah).astype(int)
    assert np.all(x1 - x0 == tw) and np.all(y1 - y0 == th)  # each card shows one whole leaf tile
    lut = _srgb_to_linear(np.arange(256) / 255.0).astype(np.float32)
    full = texture[..., 3] == 255  # fully opaque texels
    base = lut[texture[full][:, :3]].sum(0)
    out = np.empty((len(uv), 3))
    for i, (xa, ya) in enumerate(zip(x0, y0)):
        tile = atlas[ya:ya + th, xa:xa + tw]
        assert np.array_equal(tile[..., 3], texture[..., 3])  # the leaf's alpha, unchanged
        out[i] = lut[tile[full][:, :3]].sum(0) / base
    return out


def _assert_colours_match(shown: np.ndarray, colours: np.ndarray, *, mean_tol: float, p95_tol: float):
    err = np.abs(shown - colours)
    assert err.mean() < mean_tol, err.mean()
    assert np.percentile(err.max(axis=1), 95) < p95_tol, np.percentile(err.max(axis=1), 95)
    # the texture alone (what the OBJ showed before: every card the same light green) is far off
    untinted = np.abs(1.0 - colours).mean()
    assert err.mean() < 0.1 * untinted


def test_reconstructed_tree_obj_shows_the_photo_leaf_colours(tmp_path):
    """With procedural cards the envelope method colours each leaf from the photo (a wide
    spread of greens); the OBJ's leaf atlas, sampled through each card's UVs, shows those colours."""
    from treeform import reconstruct
    from treeform.geometry.textures import BARK_TEXTURE_SIZE, LEAF_TEXTURE_SIZE

    photo = Path(__file__).resolve().parents[2] / "src" / "treeform" / "data" / "Celtis_occidentalis_1.jpg"
    res = reconstruct(photo, out=tmp_path / "t", seed=0, max_size=320, attractors=3000, leaves=1500,
                      rdm_resolution=128, lod="low", leaf_texture="procedural")  # low: thinner bark
    out = tmp_path / "t"
    leaf_tex = read_glb_textures(out / "tree.glb")["leaves"]
    bark_tex = read_glb_textures(out / "tree.glb")["bark"]
    assert leaf_tex.shape[0] >= LEAF_TEXTURE_SIZE and bark_tex.shape[0] >= BARK_TEXTURE_SIZE  # 256², 512²
    from PIL import Image

    assert Image.open(out / "tree_bark.png").size == bark_tex.shape[:2]
    colours = res.foliage.color.astype(np.float64)
    assert colours.std(axis=0).min() > 0.1  # a hard case: many distinct colours, not one green
    shown = _obj_card_colours(out / "tree.obj", leaf_tex)
    assert len(shown) == len(res.foliage)
    _assert_colours_match(shown, colours, mean_tol=0.03, p95_tol=0.08)


def test_photo_textured_tree_obj_shares_the_glb_atlas_and_card_rectangles(tmp_path):
    """Photo-textured cards carry their look in the atlas (no vertex colours to bake): the OBJ
    writes the GLB's atlas as it is, and every card's UVs span exactly its own tile."""
    from treeform import reconstruct

    photo = Path(__file__).resolve().parents[2] / "src" / "treeform" / "data" / "Celtis_occidentalis_1.jpg"
    res = reconstruct(photo, out=tmp_path / "t", seed=0, max_size=320, attractors=3000, leaves=1500,
                      rdm_resolution=128, lod="low")
    from PIL import Image

    atlas = read_glb_textures(tmp_path / "t" / "tree.glb")["leaves"]
    np.testing.assert_array_equal(np.asarray(Image.open(tmp_path / "t" / "tree_leaves.png")), atlas)
    rect = res.foliage.uv
    assert rect is not None and len(rect) == len(res.foliage)
    vt = np.array([[float(x) for x in line.split()[1:3]] for line in
                   (tmp_path / "t" / "tree.obj").read_text().splitlines() if line.startswith("vt ")])
    # OBJ's v runs up: the card corners are the rectangles' corners, v flipped
    corners = np.concatenate([rect[:, [0, 1]], rect[:, [2, 3]], rect[:, [0, 3]], rect[:, [2, 1]]])
    corners[:, 1] = 1.0 - corners[:, 1]
    from scipy.spatial import cKDTree

    d, _ = cKDTree(corners).query(vt[-4 * len(rect):])
    assert d.max() < 1e-4


def test_grown_tree_obj_shows_the_leaf_colours(tmp_path):
    from treeform.methods.learned.grow import grow_tree

    res = grow_tree("oak", seed=1, out=tmp_path / "oak", lod="low", render_size=64, age=6)
    out = tmp_path / "oak"
    shown = _obj_card_colours(out / "tree.obj", read_glb_textures(out / "tree.glb")["leaves"])
    assert len(shown) == len(res.foliage)
    _assert_colours_match(shown, res.foliage.color.astype(np.float64), mean_tol=0.01, p95_tol=0.03)


def test_bake_is_exact_for_few_colours_and_keeps_the_geometry(make_cylinder, make_leaves):
    from treeform.io.obj import _linear_to_srgb, bake_vertex_colors
    from treeform.structures.mesh import MeshPart

    base = make_leaves(n_leaves=5)
    col = np.repeat(np.array([[0.1, 0.5, 0.2], [0.9, 0.2, 0.1], [0.3, 0.3, 0.3], [0.1, 0.5, 0.2], [0.05, 0.1, 0.6]]),
                    4, axis=0)
    part = MeshPart(base.positions, base.normals, base.uvs, np.column_stack([col, np.ones(20)]), base.indices,
                    base.material, "leaves")
    baked = bake_vertex_colors(part)
    tex = part.material.texture
    h, w = tex.shape[:2]
    assert baked.material.texture.shape == (2 * h, 2 * w, 4)  # 4 distinct colours: 2 x 2 tiles
    assert baked.n_vertices == part.n_vertices and np.all(baked.colors == 1)
    # same triangles in space, in the same order
    np.testing.assert_array_equal(baked.positions[baked.indices], part.positions[part.indices])
    assert baked.material.alpha_mode == "MASK" and part.material.texture is tex  # the input is untouched
    atlas = baked.material.texture
    for k in range(5):
        uv = baked.uvs[baked.indices[2 * k: 2 * k + 2].ravel()]
        x0, y0 = int(round(uv[:, 0].min() * 2 * w)), int(round(uv[:, 1].min() * 2 * h))
        assert np.isclose((uv[:, 0].max() - uv[:, 0].min()) * 2 * w, w)
        tile = atlas[y0:y0 + h, x0:x0 + w]
        want = np.rint(_linear_to_srgb(_srgb_to_linear(tex[..., :3] / 255.0) * col[4 * k]) * 255)
        assert np.abs(tile[..., :3].astype(int) - want).max() <= 1
        np.testing.assert_array_equal(tile[..., 3], tex[..., 3])
    # nothing to bake: no texture, white colours, or a repeating texture (UVs beyond [0, 1])
    assert bake_vertex_colors(make_cylinder()) is None
    assert bake_vertex_colors(base) is None
    rep = MeshPart(part.positions, part.normals, part.uvs * 3, part.colors, part.indices, part.material)
    assert bake_vertex_colors(rep) is None
    # an atlas that would not fit: keep the vertex colours
    assert bake_vertex_colors(part, max_texels=3 * h * w) is None
    with pytest.raises(InputError, match="clusters"):
        bake_vertex_colors(part, clusters=0)


def test_bake_clusters_many_colours_deterministically(make_leaves):
    from treeform.io.obj import bake_vertex_colors
    from treeform.structures.mesh import MeshPart

    base = make_leaves(n_leaves=400)
    rng = np.random.default_rng(0)
    col = np.repeat(rng.uniform(0, 1, (400, 3)), 4, axis=0)
    part = MeshPart(base.positions, base.normals, base.uvs, np.column_stack([col, np.ones(1600)]), base.indices,
                    base.material, "leaves")
    a, b = bake_vertex_colors(part), bake_vertex_colors(part)
    np.testing.assert_array_equal(a.material.texture, b.material.texture)
    np.testing.assert_array_equal(a.uvs, b.uvs)
    h, w = part.material.texture.shape[:2]
    assert a.material.texture.shape == (8 * h, 8 * w, 4)  # 64 swatches
    small = bake_vertex_colors(part, clusters=16)
    assert small.material.texture.shape == (4 * h, 4 * w, 4)


def test_obj_keeps_vertex_colours_when_asked(tmp_path, make_leaves):
    from treeform.structures.mesh import Mesh, MeshPart

    base = make_leaves(n_leaves=3)
    col = np.column_stack([np.repeat([[0.1, 0.5, 0.2], [0.9, 0.2, 0.1], [0.3, 0.3, 0.3]], 4, axis=0), np.ones(12)])
    mesh = Mesh([MeshPart(base.positions, base.normals, base.uvs, col, base.indices, base.material, "leaves")])
    write_obj(mesh, tmp_path / "v.obj", colors="vertex")
    v = _parse_obj((tmp_path / "v.obj").read_text())[0]
    assert all(len(x) == 6 for x in v)
    write_obj(mesh, tmp_path / "b.obj")
    v = _parse_obj((tmp_path / "b.obj").read_text())[0]
    assert all(len(x) == 3 for x in v)
    with pytest.raises(InputError, match="colors"):
        write_obj(mesh, tmp_path / "x.obj", colors="both")


def test_tree_outputs_encode_each_texture_once_and_glb_obj_share_it(tmp_path, tree_mesh, skeleton, monkeypatch):
    import treeform.io.images as images
    from treeform.io import write_tree_outputs

    calls = []
    real = images._encode_texture
    monkeypatch.setattr(images, "_encode_texture", lambda t: calls.append(id(t)) or real(t))
    write_tree_outputs(tmp_path / "out", mesh=tree_mesh, skeleton=skeleton,
                       preview=np.zeros((8, 8, 3), np.uint8), config={}, metrics={})
    textures = {id(p.material.texture) for p in tree_mesh.parts if p.material.texture is not None}
    assert sorted(calls) == sorted(textures)  # once each, though both the GLB and the OBJ carry them
    glb = read_glb_textures(tmp_path / "out" / "tree.glb")
    obj_png = (tmp_path / "out" / "tree_leaf.png").read_bytes()
    np.testing.assert_array_equal(glb["leaf"], images.read_rgba(tmp_path / "out" / "tree_leaf.png"))
    assert obj_png == images.texture_png(tree_mesh.parts[1].material.texture)
    assert images._shared is None  # the sharing ends with the call


def test_obj_numbers_are_compiled_fixed_point_and_exact_to_half_a_micrometre():
    from treeform.io._text_kernels import face_rows, float_rows

    v = np.array([[0.0, -0.0, 1.0], [-1.5, 2.25, 1e-7], [123456.789012, -4e-7, -6e-7], [3.0000004, 10.0, -0.1]])
    text = float_rows(np.frombuffer(b"v", np.uint8), v, 6).tobytes().decode()
    assert text.splitlines() == ["v 0 0 1", "v -1.5 2.25 0", "v 123456.789012 0 -0.000001", "v 3 10 -0.1"]
    rng = np.random.default_rng(0)
    x = rng.normal(size=(5000, 3)) * 30
    back = np.array([[float(t) for t in line.split()[1:]]
                     for line in float_rows(np.frombuffer(b"vn", np.uint8), x, 6).tobytes().decode().splitlines()])
    assert np.abs(back - x).max() <= 5.0001e-7
    idx = np.array([[1, 10, 1234567890123], [7, 8, 9]])
    assert face_rows(idx).tobytes().decode() == ("f 1/1/1 10/10/10 1234567890123/1234567890123/1234567890123\n"
                                                 "f 7/7/7 8/8/8 9/9/9\n")


def test_obj_falls_back_to_general_format_for_huge_coordinates(tmp_path, make_cylinder):
    from treeform.structures.mesh import Mesh

    part = make_cylinder()
    big = part.positions.copy()
    big[0] = [3e13, -2e12, 1.0]
    mesh = Mesh([type(part)(big, part.normals, part.uvs, part.colors, part.indices, material=part.material)])
    v, *_ = _parse_obj(write_obj(mesh, tmp_path / "big.obj").read_text())
    np.testing.assert_allclose(np.array(v)[:, :3], big, rtol=1e-5, atol=1e-5)


def test_staged_outputs_start_early_commit_together_or_leave_nothing(tmp_path, tree_mesh, skeleton):
    import threading

    from treeform.io import StagedOutputs, start_tree_outputs, write_tree_outputs

    # the mesh files are written while the caller goes on; the folder appears only at the commit
    staged = start_tree_outputs(tmp_path / "out", mesh=tree_mesh, skeleton=skeleton)
    assert not (tmp_path / "out").exists()
    files = write_tree_outputs(tmp_path / "out", mesh=tree_mesh, skeleton=skeleton,
                               preview=np.zeros((8, 8, 3), np.uint8), config={"a": 1}, metrics={}, staged=staged)
    assert {"tree.glb", "tree.obj", "skeleton.json", "skeleton.ply", "preview.png", "config.json"} <= set(files)
    assert [p.name for p in tmp_path.iterdir()] == ["out"]  # no staging folder left beside it

    # an error after the writers started (e.g. in the render): nothing appears, they are waited for
    started = threading.Event()
    with pytest.raises(RuntimeError, match="render failed"):
        with start_tree_outputs(tmp_path / "failed", mesh=tree_mesh, skeleton=skeleton) as staged:
            staged.submit(lambda d: started.set())
            started.wait(5)
            raise RuntimeError("render failed")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]

    # a writer's failure is the commit's one-line error, and nothing is left
    def full(d):
        raise OSError(28, "No space left on device")

    with pytest.raises(OutputError, match="No space left"):
        with StagedOutputs(tmp_path / "full") as staged:
            staged.submit(lambda d: (d / "a.txt").write_text("a"), full)
            staged.commit()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    with pytest.raises(RuntimeError, match="already"):
        staged.submit(lambda d: None)
