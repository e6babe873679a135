"""End-to-end tests of the grow pipeline (species preset -> leafy 3D tree, seed 003 §4.3)."""

import json
import os

import numpy as np
import pytest

from treeform._shared.errors import InputError, OutputError
from treeform.io import read_glb_counts
from treeform.methods.learned import GrowConfig
from treeform.growth.leaves import leaf_positions
from treeform.methods.learned.grow import OUTPUT_FILES, STAGES, grow_tree, shape_metrics
from treeform.structures import TreeSkeleton

from preview_checks import assert_panels_show_the_whole_tree

FAST = dict(lod="low", render_size=128, age=6)


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("grow") / "oak"
    events = []
    res = grow_tree("oak", seed=3, out=out, progress=lambda s, e, t: events.append((s, e)), **FAST)
    return res, out, events


def test_outputs_exist_and_agree(run):
    res, out, events = run
    names = {p.name for p in out.iterdir()}
    assert set(OUTPUT_FILES) <= names
    assert not any(n.startswith(".treeform-") for n in names)
    assert not any(p.name.startswith(".treeform-") for p in out.parent.iterdir())
    assert read_glb_counts(out / "tree.glb") == (res.mesh.n_vertices, res.mesh.n_triangles)
    sk = TreeSkeleton.load(out / "skeleton.json")
    np.testing.assert_allclose(sk.positions, res.skeleton.positions, atol=1e-6)
    metrics = json.loads((out / "metrics.json").read_text())
    for key in ("nodes", "tips", "leaves", "triangles", "height", "crown_width"):
        assert key in metrics
    assert metrics["nodes"] == res.skeleton.n_nodes and metrics["leaves"] == len(res.foliage)
    form = metrics["tree_form"]  # seed 003 §6 tree-form metrics
    assert len(form["mrt_m"]) == 5 and form["tree_height_m"] >= metrics["height"]  # leaves reach above the nodes
    assert form["leaf_area_index"] > 0 and form["biomass_m3"] > 0 and 0 < form["branching_angle_deg"] < 90
    assert set(metrics["timings"]) == set(STAGES)
    cfg = json.loads((out / "config.json").read_text())
    assert cfg["method"] == "learned.grow" and cfg["config"]["species"] == "oak" and cfg["config"]["seed"] == 3
    assert cfg["config"]["params"] == {"age": 6} and cfg["parameters"]["age"] == 6
    assert [s for s, e in events if e == "end"] == list(STAGES)


def test_leaves_sit_on_twigs_in_species_green(run):
    res, _, _ = run
    f = res.foliage
    assert len(f) > 100
    assert np.all(f.node > 0)
    # hung near their twig node
    d = np.linalg.norm(f.positions - res.skeleton.positions[f.node], axis=1)
    assert np.median(d) < 2.0
    # green, with per-leaf variation
    assert np.all(f.color[:, 1] > f.color[:, 0]) and np.all(f.color[:, 1] > f.color[:, 2])
    assert f.color.std(axis=0).min() > 0.005


def test_preview_frames_the_tree(run):
    res, out, _ = run
    assert res.preview.ndim == 3 and res.preview.shape[2] == 3
    assert_panels_show_the_whole_tree(res.renders, res.preview)
    from PIL import Image

    assert np.array_equal(np.asarray(Image.open(out / "preview.png").convert("RGB")), res.preview)
    # side and front share one scale (same focal length, distance and image height)
    f, s = res.renders["front"].camera, res.renders["side"].camera
    assert s.height == f.height and s.focal == pytest.approx(f.focal)
    assert np.linalg.norm(np.subtract(s.position, s.target)) == pytest.approx(
        np.linalg.norm(np.subtract(f.position, f.target)))


def test_full_size_previews_fill_their_panels():
    # the oak (seed 3, full size): broad crown, 17.8 m tall; each view framed on its own extent
    res = grow_tree("oak", seed=3, lod="low", leaves=1500)
    assert_panels_show_the_whole_tree(res.renders, res.preview)
    for view in ("front", "side", "top"):
        m = res.renders[view].mask
        ys, xs = np.nonzero(m)
        assert max(np.ptp(ys) / m.shape[0], np.ptp(xs) / m.shape[1]) > 0.75, view


def test_figures_are_the_metrics_modules(run):
    from treeform.metrics.treeform_metrics import crown_extents, tree_height, tree_metrics

    res, out, _ = run
    metrics = json.loads((out / "metrics.json").read_text())
    crown = crown_extents(res.skeleton)
    assert metrics["height"] == pytest.approx(tree_height(res.skeleton), abs=1e-4)
    assert metrics["crown_extent_x"] == pytest.approx(crown["crown_extent_x_m"], abs=1e-4)
    assert metrics["crown_extent_z"] == pytest.approx(crown["crown_extent_z_m"], abs=1e-4)
    assert metrics["crown_width"] == pytest.approx(0.5 * (crown["crown_extent_x_m"] + crown["crown_extent_z_m"]),
                                                   abs=1e-4)
    # the leaf count travels with the skeleton, so metrics of the files report it
    sk = TreeSkeleton.load(out / "skeleton.json")
    assert sk.meta["n_leaves"] == len(res.foliage) == metrics["leaves"]
    assert tree_metrics(sk)["n_leaves"] == len(res.foliage)
    assert tree_metrics(sk)["crown_width_m"] == pytest.approx(metrics["crown_width"], abs=1e-4)


def test_same_seed_same_skeleton_json(tmp_path):
    a = grow_tree("pine", seed=1, out=tmp_path / "a", **FAST)
    b = grow_tree("pine", seed=1, out=tmp_path / "b", **FAST)
    c = grow_tree("pine", seed=2, **FAST)
    assert (tmp_path / "a" / "skeleton.json").read_bytes() == (tmp_path / "b" / "skeleton.json").read_bytes()
    assert np.array_equal(a.foliage.positions, b.foliage.positions)
    assert a.skeleton.n_nodes != c.skeleton.n_nodes or not np.allclose(a.skeleton.positions, c.skeleton.positions)


def test_leaf_count_options():
    res = grow_tree("apple", seed=0, leaves=500, **FAST)
    assert len(res.foliage) == 500
    res = grow_tree("apple", seed=0, leaves=0, **FAST)
    assert len(res.foliage) == 0 and res.mesh.n_triangles > 0


def test_budget_generates_only_the_kept_leaves():
    # pine at 20k triangles: the LOD would keep a fraction of the full foliage, so only that is generated
    from treeform.growth.leaves import twig_nodes

    low = grow_tree("pine", seed=0, lod="low", previews=False)
    full = grow_tree("pine", seed=0, lod="full", previews=False)
    n_full = int(round(3.0 * len(twig_nodes(full.skeleton))))
    assert len(full.foliage) == n_full and 0 < len(low.foliage) < n_full
    assert low.metrics["leaves"] == len(low.foliage) and low.metrics["triangles"] <= 20_000
    leaves = next(p for p in low.mesh.parts if p.name == "leaves")
    assert leaves.n_triangles == 2 * len(low.foliage)  # the mesh keeps every generated cluster
    factor = np.median(low.foliage.size) / np.median(full.foliage.size)
    assert factor == pytest.approx(np.sqrt(n_full / len(low.foliage)), rel=0.05)  # enlarged as the LOD would
    assert leaves.material.texture.shape == next(p for p in full.mesh.parts if p.name == "leaves").material.texture.shape


def test_overrides_and_config():
    res = grow_tree("birch", seed=0, config=GrowConfig(leaves_per_twig=1.0), growth_rate=2.0, **FAST)
    assert res.parameters.growth_rate == 2.0 and res.parameters.age == 6
    assert res.config.leaves_per_twig == 1.0 and res.config.species == "birch"


def test_bad_inputs():
    with pytest.raises(InputError, match="known: acacia"):
        grow_tree("baobab")
    with pytest.raises(InputError, match="unknown option"):
        grow_tree("oak", colour="red")
    with pytest.raises(InputError, match="lod"):
        grow_tree("oak", lod="ultra")
    with pytest.raises(InputError, match="leaves"):
        grow_tree("oak", leaves=-1)


def test_unwritable_out_is_one_line_output_error(tmp_path):
    f = tmp_path / "file"
    f.write_text("x")
    with pytest.raises(OutputError) as err:  # missing parent folders are made, but not below a file
        grow_tree("oak", out=f / "missing" / "deeper", **FAST)
    assert "\n" not in str(err.value)
    with pytest.raises(OutputError):
        grow_tree("oak", out=f, **FAST)
    if os.geteuid() != 0:
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o500)
        try:
            with pytest.raises(OutputError):
                grow_tree("oak", out=ro / "tree", **FAST)
        finally:
            ro.chmod(0o700)


def test_helpers():
    sk = TreeSkeleton(np.array([[0, 0, 0], [0, 1, 0], [0.5, 1.5, 0], [-0.5, 1.5, 0.]]), np.array([-1, 0, 1, 1]))
    pts = leaf_positions(sk, 10, size=0.2, seed=0)
    assert pts.shape == (10, 3) and np.all(pts[:, 1] >= 0.1)
    assert leaf_positions(sk, 0, size=0.2).shape == (0, 3)
    m = shape_metrics(sk)
    assert m["height"] == 1.5 and m["tip_direction_y"] == pytest.approx(np.sqrt(0.5), abs=1e-3)
    # crown extents: outermost node to outermost node; width their mean
    assert (m["crown_extent_x"], m["crown_extent_z"], m["crown_width"]) == (1.0, 0.0, 0.5)
