import ast
from pathlib import Path

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.structures import Camera, Foliage, Material, Mesh, MeshPart, Photo, RadialDistanceMap, Segmentation, TreeSkeleton
from treeform.structures.rdm import direction_to_texel, texel_directions

PKG = Path(__file__).resolve().parents[2] / "src" / "treeform"


def test_structures_import_nothing_but_numpy_and_shared_errors():
    for f in (PKG / "structures").glob("*.py"):
        tree = ast.parse(f.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("treeform"):
                assert node.module.startswith(("treeform.structures", "treeform._shared")), (f.name, node.module)
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                mod = node.module if isinstance(node, ast.ImportFrom) else node.names[0].name
                assert mod is None or mod.split(".")[0] in {"numpy", "treeform", "__future__", "dataclasses", "json", "os",
                                                            "pathlib", "math", "ast"}, (f.name, mod)


def test_domain_folders_never_import_methods_or_cli():
    for folder in ("structures", "io", "render", "segment", "crown", "growth", "geometry", "metrics", "report"):
        for f in (PKG / folder).glob("*.py"):
            src = f.read_text()
            assert "treeform.methods" not in src and "treeform.cli" not in src, f


def _skeleton():
    pos = np.array([[0, 0, 0], [0, 1, 0], [0.5, 1.5, 0], [-0.5, 1.6, 0.1]], float)
    return TreeSkeleton(pos, np.array([-1, 0, 1, 1]), np.array([0.1, 0.08, 0.05, 0.04]), np.array([0, 0, 0, 1]))


def test_skeleton_round_trip_and_determinism(tmp_path):
    s = _skeleton()
    s.save(tmp_path / "a.json")
    s.save(tmp_path / "b.json")
    assert (tmp_path / "a.json").read_bytes() == (tmp_path / "b.json").read_bytes()
    t = TreeSkeleton.load(tmp_path / "a.json")
    np.testing.assert_allclose(t.positions, s.positions)
    assert t.parent.tolist() == [-1, 0, 1, 1]
    assert sorted(t.tips().tolist()) == [2, 3]
    chains = s.chains()
    assert sum(len(c) for c in chains) == s.n_nodes + len(chains) - 1  # each side chain starts at its parent


@pytest.mark.parametrize("parent", [[0, 0], [-1, 1], [-1, -1], [-1, 2, 0]])
def test_skeleton_rejects_bad_parents(parent):
    with pytest.raises(InputError):
        TreeSkeleton(np.zeros((len(parent), 3)), np.array(parent))


def test_skeleton_load_errors(tmp_path):
    (tmp_path / "x.json").write_text("{}")
    with pytest.raises(InputError):
        TreeSkeleton.load(tmp_path / "x.json")
    with pytest.raises(InputError):
        TreeSkeleton.load(tmp_path / "missing.json")


def test_npz_round_trips(tmp_path):
    seg = Segmentation(np.array([[0, 1], [2, 1]], np.uint8))
    seg.save(tmp_path / "s.npz")
    assert np.array_equal(Segmentation.load(tmp_path / "s.npz").labels, seg.labels)
    ph = Photo(np.zeros((3, 4, 3), np.uint8), "x.jpg", 0.5)
    ph.save(tmp_path / "p.npz")
    assert Photo.load(tmp_path / "p.npz").scale == 0.5
    f = Foliage(np.zeros((2, 3)), [[0, 0, 1]] * 2, [[0, 1, 0]] * 2, [0.1, 0.2], [[0.1, 0.5, 0.1]] * 2)
    f.save(tmp_path / "f.npz")
    assert len(Foliage.load(tmp_path / "f.npz")) == 2
    with pytest.raises(InputError):
        Foliage.load(tmp_path / "s.npz")  # a Segmentation file is not a Foliage file
    mat = Material("leaves", texture=np.zeros((2, 2, 4), np.uint8), alpha_mode="MASK", double_sided=True)
    part = MeshPart(np.zeros((3, 3)), [[0, 0, 1]] * 3, np.zeros((3, 2)), None, [[0, 1, 2]], mat, "leaves")
    Mesh([part]).save(tmp_path / "m.npz")
    back = Mesh.load(tmp_path / "m.npz")
    assert back.n_triangles == 1 and back.parts[0].material.alpha_mode == "MASK"


def test_foliage_texture_rectangles_survive_subsets_and_files(tmp_path):
    f = Foliage(np.zeros((3, 3)), [[0, 0, 1]] * 3, [[0, 1, 0]] * 3, [0.1, 0.2, 0.3], [[0.1, 0.5, 0.1]] * 3,
                uv=[[0, 0, 0.5, 0.5], [0.5, 0, 1, 0.5], [0, 0.5, 0.5, 1]])
    sub = f.subset(np.array([False, True, True]))
    np.testing.assert_array_equal(sub.uv, f.uv[1:])
    f.save(tmp_path / "f.npz")
    np.testing.assert_array_equal(Foliage.load(tmp_path / "f.npz").uv, f.uv)
    np.testing.assert_array_equal(f.with_colors(np.ones((3, 3))).uv, f.uv)
    assert Foliage(np.zeros((1, 3)), [[0, 0, 1]], [[0, 1, 0]], [0.1], [[0, 0, 0]]).subset([0]).uv is None
    with pytest.raises(InputError, match="uv"):
        Foliage(np.zeros((1, 3)), [[0, 0, 1]], [[0, 1, 0]], [0.1], [[0, 0, 0]], uv=[[0, 0, 2, 1]])
    with pytest.raises(InputError, match="uv"):
        Foliage(np.zeros((2, 3)), [[0, 0, 1]] * 2, [[0, 1, 0]] * 2, [0.1] * 2, [[0, 0, 0]] * 2, uv=[[0, 0, 1, 1]])


def test_segmentation_validation():
    with pytest.raises(InputError):
        Segmentation(np.full((2, 2), 3, np.uint8))
    with pytest.raises(InputError):
        Segmentation(np.zeros((2, 2), np.uint8), np.full((2, 2), 2.0))


def test_camera_project_unproject_round_trip():
    cam = Camera(640, 480, 40, (1, 5, 30), (1, 5, 0))
    rng = np.random.default_rng(0)
    u, v, d = rng.uniform(0, 640, 50), rng.uniform(0, 480, 50), rng.uniform(10, 50, 50)
    back = cam.project(cam.unproject(u, v, d))
    np.testing.assert_allclose(back, np.stack([u, v, d], 1), atol=1e-9)
    # world up projects upward in the image (row decreases)
    p = cam.project(np.array([[1, 5, 0], [1, 6, 0]]))
    assert p[1, 1] < p[0, 1]
    side = cam.orbit(90)
    assert np.allclose(side.position, (31, 5, 0), atol=1e-9)


def test_cubemap_texel_round_trip():
    r = 12
    d = texel_directions(r).reshape(-1, 3)
    f, row, col = direction_to_texel(d, r)
    ff, rr, cc = np.meshgrid(np.arange(6), np.arange(r), np.arange(r), indexing="ij")
    assert np.array_equal(f, ff.ravel()) and np.array_equal(row, rr.ravel()) and np.array_equal(col, cc.ravel())


def test_rdm_contains_matches_a_sphere():
    rdm = RadialDistanceMap(np.array([1.0, 2.0, 3.0]), np.full((6, 16, 16), 2.0, np.float32))
    rng = np.random.default_rng(1)
    p = rng.uniform(-3, 3, (2000, 3)) + [1, 2, 3]
    truth = np.linalg.norm(p - [1, 2, 3], axis=1) <= 2
    assert np.array_equal(rdm.contains(p), truth)
    lo, hi = rdm.bounds()
    assert np.all(lo >= np.array([1, 2, 3]) - 2.0001) and np.all(hi <= np.array([1, 2, 3]) + 2.0001)


def test_rdm_compiled_lookups_equal_the_texel_formula():
    # lookup / contains / bounds run compiled; they must pick the texel direction_to_texel picks,
    # on ties between axes and on the axes themselves too, and bound the texel_directions points
    rng = np.random.default_rng(2)
    r = 32
    rdm = RadialDistanceMap(rng.normal(size=3), (rng.random((6, r, r)) * 3).astype(np.float32))
    d = np.concatenate([rng.normal(size=(20000, 3)), np.round(rng.normal(size=(5000, 3))),
                        np.eye(3), -np.eye(3), [[1, 1, 1], [-1, 1, -1], [0, 0, 0]]])
    f, row, col = direction_to_texel(d, r)
    ref = rdm.radii[f, row, col].astype(np.float64)
    np.testing.assert_array_equal(rdm.lookup(d), ref)
    np.testing.assert_array_equal(rdm.contains(rdm.center + d), np.linalg.norm(d, axis=1) <= ref)
    pts = rdm.center + texel_directions(r).reshape(-1, 3) * rdm.radii.reshape(-1, 1)
    lo, hi = rdm.bounds()
    np.testing.assert_array_equal(lo, pts.min(axis=0))
    np.testing.assert_array_equal(hi, pts.max(axis=0))
