"""`treeform grow`: writes its files; bad input fails with one `error:` line, no traceback, no files."""

import json

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
    out = tmp_path / "no" / "such" / "dir"
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
