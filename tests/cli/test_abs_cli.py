"""``treeform reconstruct --method abs`` and ``treeform skeleton2d`` from the command line."""

import json
from pathlib import Path

from cli_helpers import assert_clean_failure, cli

SAMPLE = Path(__file__).resolve().parents[2] / "src" / "treeform" / "data" / "Celtis_occidentalis_1.jpg"


def test_reconstruct_abs_happy_path(tmp_path):
    out = tmp_path / "abs"
    proc = cli("reconstruct", SAMPLE, "--method", "abs", "--candidates", "3", "--lod", "low", "--species", "oak",
               "-o", out)
    assert proc.returncode == 0, proc.stderr
    m = json.loads((out / "metrics.json").read_text())
    assert len(m["candidates"]) == 3 and (out / "candidates.png").exists() and (out / "tree.glb").exists()


def test_abs_options_are_checked(tmp_path):
    out = tmp_path / "x"
    assert_clean_failure(cli("reconstruct", SAMPLE, "--candidates", "3", "-o", out), out, only_error=True)
    assert_clean_failure(cli("reconstruct", SAMPLE, "--method", "abs", "--profile", "rounded", "-o", out), out,
                         only_error=True)
    assert_clean_failure(cli("reconstruct", SAMPLE, "--method", "abs", "--species", "palm", "-o", out), out)


def test_skeleton2d_cli(tmp_path):
    png = tmp_path / "sk.png"
    proc = cli("skeleton2d", SAMPLE, "-o", png, "--branches", "4")
    assert proc.returncode == 0, proc.stderr
    assert png.exists() and png.with_suffix(".json").exists() and "branches" in proc.stdout
    assert_clean_failure(cli("skeleton2d", tmp_path / "missing.jpg", "-o", png.with_name("b.png")))


def test_skeleton2d_cli_source(tmp_path):
    png = tmp_path / "wood.png"
    proc = cli("skeleton2d", SAMPLE, "-o", png, "--source", "wood")
    assert proc.returncode == 0, proc.stderr
    assert "wood skeleton" in proc.stdout and json.loads(png.with_suffix(".json").read_text())["meta"]["mode"] == "wood"
    bad = cli("skeleton2d", SAMPLE, "-o", tmp_path / "bad.png", "--source", "bark")  # a usage error (typer's own)
    assert bad.returncode == 2 and "Traceback" not in bad.stderr and not (tmp_path / "bad.png").exists()


def test_reconstruct_abs_leaf_texture(tmp_path):
    out = tmp_path / "plain"
    proc = cli("reconstruct", SAMPLE, "--method", "abs", "--candidates", "2", "--lod", "low", "--species", "oak",
               "--leaf-texture", "procedural", "-o", out)
    assert proc.returncode == 0, proc.stderr
    assert json.loads((out / "config.json").read_text())["config"]["leaf_texture"] == "procedural"
