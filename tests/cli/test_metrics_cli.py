"""``treeform metrics TREE``: table and JSON for skeleton JSON / GLB, one-line errors otherwise."""

import json

import numpy as np
import pytest

from cli_helpers import assert_clean_failure as _clean
from cli_helpers import cli
from treeform.geometry import tree_mesh
from treeform.io import write_glb
from treeform.metrics import leaf_area_index, tree_metrics
from treeform.structures import Foliage, TreeSkeleton





def assert_clean_failure(proc):
    _clean(proc, only_error=True)


def skeleton():
    pos = np.array([[0, 0, 0], [0, 1, 0], [0, 2, 0], [1, 2, 0], [0, 3, 0], [-0.7, 3.5, 0.3]], float)
    return TreeSkeleton(pos, np.array([-1, 0, 1, 1, 2, 2]), np.array([0.2, 0.15, 0.1, 0.05, 0.06, 0.03]),
                        np.array([0, 0, 0, 1, 0, 1]))


def foliage():
    rng = np.random.default_rng(0)
    m = 40
    n = rng.normal(size=(m, 3)) + [0, 2, 0]
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    up = np.cross(n, [1.0, 0, 0])
    up /= np.linalg.norm(up, axis=1, keepdims=True)
    return Foliage(rng.uniform([-1, 2, -1], [1, 3.5, 1], (m, 3)), n, up, np.full(m, 0.3), np.full((m, 3), 0.5))


@pytest.fixture(scope="module")
def tree_dir(tmp_path_factory):
    d = tmp_path_factory.mktemp("tree")
    write_glb(tree_mesh(skeleton(), foliage()), d / "tree.glb")
    skeleton().save(d / "skeleton.json")
    return d


def test_metrics_table_for_a_skeleton_json(tree_dir):
    proc = cli("metrics", tree_dir / "skeleton.json")
    assert proc.returncode == 0, proc.stderr
    for name in ("branching_angle_deg", "tree_height_m", "trunk_diameter_m", "leaf_area_index", "biomass_m3", "mrt_m"):
        assert name in proc.stdout
    assert "n/a" in proc.stdout  # no foliage in a skeleton JSON


def test_metrics_json_for_a_skeleton_json(tree_dir):
    proc = cli("metrics", tree_dir / "skeleton.json", "--json")
    assert proc.returncode == 0, proc.stderr
    res = json.loads(proc.stdout)
    expected = tree_metrics(skeleton())
    got = res["metrics"]
    for k in ("branching_angle_deg", "tree_height_m", "trunk_diameter_m", "biomass_m3"):
        assert got[k] == pytest.approx(expected[k], rel=1e-5)
    assert got["mrt_m"] == pytest.approx(expected["mrt_m"], rel=1e-5)
    assert got["leaf_area_index"] is None and res["skeleton"].endswith("skeleton.json")


def test_crown_width_and_recorded_leaf_count(tmp_path):
    sk = skeleton()
    sk.meta["n_leaves"] = 40  # what the pipelines record when they save a tree's skeleton
    sk.save(tmp_path / "skeleton.json")
    write_glb(tree_mesh(skeleton(), foliage()), tmp_path / "tree.glb")
    for tree in ("skeleton.json", "tree.glb"):
        proc = cli("metrics", tmp_path / tree, "--json")
        assert proc.returncode == 0, proc.stderr
        m = json.loads(proc.stdout)["metrics"]
        # extents from the outermost node to the outermost node; the crown width is their mean
        assert m["crown_extent_x_m"] == pytest.approx(1.7) and m["crown_extent_z_m"] == pytest.approx(0.3)
        assert m["crown_width_m"] == pytest.approx(1.0)
        assert m["n_leaves"] == 40, tree
    table = cli("metrics", tmp_path / "skeleton.json")
    assert table.returncode == 0 and "crown_width_m" in table.stdout
    # a skeleton from elsewhere, with no count recorded: the count is unknown, not made up
    proc = cli("metrics", tree_dir_skeleton(tmp_path), "--json")
    assert json.loads(proc.stdout)["metrics"]["n_leaves"] is None


def tree_dir_skeleton(tmp_path):
    path = tmp_path / "bare" / "skeleton.json"
    path.parent.mkdir()
    skeleton().save(path)
    return path


def test_metrics_of_a_glb_uses_the_skeleton_beside_it(tree_dir):
    proc = cli("metrics", tree_dir / "tree.glb", "--json")
    assert proc.returncode == 0, proc.stderr
    res = json.loads(proc.stdout)
    assert res["skeleton"] == str(tree_dir / "skeleton.json")
    assert res["metrics"]["branching_angle_deg"] == pytest.approx(tree_metrics(skeleton())["branching_angle_deg"])
    # LAI from the GLB's leaf cards equals the LAI of the foliage they were made from
    assert res["metrics"]["leaf_area_index"] == pytest.approx(leaf_area_index(foliage(), skeleton()), rel=1e-3)


def test_metrics_of_a_lone_glb_says_what_it_could_compute(tmp_path, tree_dir):
    (tmp_path / "tree.glb").write_bytes((tree_dir / "tree.glb").read_bytes())
    proc = cli("metrics", tmp_path / "tree.glb", "--json")
    assert proc.returncode == 0, proc.stderr
    res = json.loads(proc.stdout)
    assert res["skeleton"] is None and "no skeleton.json" in res["notes"][0]
    m = res["metrics"]
    assert m["tree_height_m"] > 3.4 and "biomass_m3" not in m and m["leaf_area_index"] > 0
    table = cli("metrics", tmp_path / "tree.glb")
    assert table.returncode == 0 and "no skeleton.json" in table.stdout


def test_metrics_fails_cleanly(tmp_path):
    assert_clean_failure(cli("metrics", tmp_path / "missing.json"))
    (tmp_path / "other.json").write_text(json.dumps({"hello": "world"}))
    assert_clean_failure(cli("metrics", tmp_path / "other.json"))
    (tmp_path / "broken.json").write_text("{not json")
    assert_clean_failure(cli("metrics", tmp_path / "broken.json", "--json"))
    (tmp_path / "bad.json").write_text(json.dumps({"format": "treeform.skeleton", "positions": "x", "parent": [-1],
                                                   "radius": [1], "order": [0]}))
    assert_clean_failure(cli("metrics", tmp_path / "bad.json"))
    (tmp_path / "tree.glb").write_bytes(b"definitely not a glb file")
    assert_clean_failure(cli("metrics", tmp_path / "tree.glb"))
    (tmp_path / "tree.ply").write_text("ply")
    assert_clean_failure(cli("metrics", tmp_path / "tree.ply"))
    assert_clean_failure(cli("metrics", tmp_path))
