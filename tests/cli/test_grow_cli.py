"""`treeform grow`: writes its files; bad input fails with one `error:` line, no traceback, no files."""

import json
from pathlib import Path

import pytest

from cli_helpers import assert_clean_failure, cli





def test_help_lists_grow():
    proc = cli("--help")
    assert proc.returncode == 0 and "grow" in proc.stdout
    proc = cli("grow", "--help")
    assert proc.returncode == 0 and "--species" in proc.stdout and "--leaves" in proc.stdout


def test_grow_writes_its_files(tmp_path):
    out = tmp_path / "pine"
    proc = cli("grow", "--species", "pine", "--seed", "3", "--out", out, "--lod", "low", "--leaves", "2000")
    assert proc.returncode == 0, proc.stderr
    for name in ("tree.glb", "tree.obj", "tree.mtl", "skeleton.json", "skeleton.ply", "preview.png", "metrics.json",
                 "config.json"):
        assert (out / name).is_file(), name
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["species"] == "pine" and metrics["leaves"] == 2000 and metrics["triangles"] <= 20000
    cfg = json.loads((out / "config.json").read_text())["config"]
    assert cfg["seed"] == 3 and cfg["lod"] == "low"
    assert "pine" in proc.stdout and "branches" in proc.stdout


def test_printed_figures_are_those_of_treeform_metrics(tmp_path):
    """Issue 18: `grow --species oak --seed 3` printed 18.7 m wide, `treeform metrics` 20.8 x 26.6 m."""
    import re

    out = tmp_path / "oak"
    proc = cli("grow", "--species", "oak", "--seed", "3", "--out", out, "--lod", "low")
    assert proc.returncode == 0, proc.stderr
    found = re.search(r"(\d+) leaves, .* ([\d.]+) m tall, crown ([\d.]+) x ([\d.]+) m \(width ([\d.]+) m\)",
                      proc.stdout)
    assert found, proc.stdout
    leaves = int(found.group(1))
    height, ex, ez, width = (float(found.group(k)) for k in range(2, 6))
    saved = json.loads((out / "metrics.json").read_text())
    assert (f"{saved['height']:.1f}", f"{saved['crown_extent_x']:.1f}", f"{saved['crown_extent_z']:.1f}",
            f"{saved['crown_width']:.1f}") == (found.group(2), found.group(3), found.group(4), found.group(5))
    assert width == round(0.5 * (saved["crown_extent_x"] + saved["crown_extent_z"]), 1)
    for tree in ("skeleton.json", "tree.glb"):
        proc = cli("metrics", out / tree, "--json")
        assert proc.returncode == 0, proc.stderr
        m = json.loads(proc.stdout)["metrics"]
        for printed, key in ((height, "tree_height_m"), (ex, "crown_extent_x_m"), (ez, "crown_extent_z_m"),
                             (width, "crown_width_m")):
            assert abs(m[key] - printed) <= 0.05 + 1e-3, (tree, key, m[key], printed)
        assert m["crown_width_m"] == pytest.approx(saved["crown_width"], abs=1e-3)
        assert m["n_leaves"] == leaves == saved["leaves"], tree


def test_unknown_species_fails_cleanly(tmp_path):
    out = tmp_path / "x"
    proc = cli("grow", "--species", "baobab", "--out", out)
    assert_clean_failure(proc, out)
    assert "baobab" in proc.stderr and "oak" in proc.stderr


def test_bad_species_file_and_unwritable_out_fail_cleanly(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text('{"parameters": {"age": 3}, "colour": 1}')
    out = tmp_path / "y"
    assert_clean_failure(cli("grow", "--species", bad, "--out", out), out)
    (tmp_path / "file").write_text("x")
    out = tmp_path / "file" / "such" / "dir"  # missing folders are made, but not below a file
    assert_clean_failure(cli("grow", "--species", "oak", "--out", out), out)


def test_grow_inside_an_rbv_from_the_cli(tmp_path):
    from treeform.growth.phenomenological import grow as grow_skeleton
    from treeform.growth.species import load_species
    from treeform.structures import RadialBoundingVolume

    RadialBoundingVolume.from_skeleton(grow_skeleton(load_species("maple"), seed=4), level=4).save(tmp_path / "v.npz")
    out = tmp_path / "g"
    proc = cli("grow", "--species", "oak", "--rbv", tmp_path / "v.npz", "--out", out, "--lod", "low")
    assert proc.returncode == 0, proc.stderr
    assert (out / "tree.glb").exists()
    assert_clean_failure(cli("grow", "--mask", tmp_path / "v.npz", "--out", tmp_path / "h"), tmp_path / "h")


@pytest.mark.parametrize("verb", ["grow", "reconstruct"])
def test_a_negative_seed_is_one_clear_line(tmp_path, verb):
    sample = Path(__file__).resolve().parents[2] / "src" / "treeform" / "data" / "Celtis_occidentalis_1.jpg"
    args = ["--species", "oak"] if verb == "grow" else [str(sample)]
    proc = cli(verb, *args, "--seed", "-5", "--out", tmp_path / "o")
    assert_clean_failure(proc, tmp_path / "o")
    assert "Invalid value for '--seed'" in proc.stderr  # the option's range, checked before anything runs
