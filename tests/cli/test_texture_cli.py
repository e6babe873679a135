"""`--foliage` and `--texture-size` on `treeform grow` and `treeform reconstruct` (issue 18)."""

import json

import numpy as np
from cli_helpers import cli

from treeform.geometry import leaf_texture
from treeform.io.gltf import read_glb_textures


def test_grow_texture_size_and_foliage(tmp_path):
    small_pine = tmp_path / "small_pine.json"
    small_pine.write_text(json.dumps({"base": "pine", "parameters": {"age": 6}}))
    out = tmp_path / "t"
    proc = cli("grow", "--species", small_pine, "--lod", "low", "--texture-size", 128, "--out", out)
    assert proc.returncode == 0, proc.stderr
    tex = read_glb_textures(out / "tree.glb")
    assert tex["bark"].shape == (128, 128, 4)
    np.testing.assert_array_equal(tex["leaves"], leaf_texture(64, seed=0, kind="needles"))  # pine's via base
    proc = cli("grow", "--species", small_pine, "--lod", "low", "--foliage", "broadleaf", "--out", tmp_path / "b")
    assert proc.returncode == 0, proc.stderr
    tex = read_glb_textures(tmp_path / "b" / "tree.glb")
    assert tex["bark"].shape == (512, 512, 4)  # the default
    np.testing.assert_array_equal(tex["leaves"], leaf_texture(256, seed=0, kind="cluster"))


def test_options_listed_and_checked(tmp_path):
    for verb in ("grow", "reconstruct"):
        proc = cli(verb, "--help")
        assert "--texture-size" in proc.stdout and "--foliage" in proc.stdout, proc.stdout
    proc = cli("grow", "--texture-size", 4, "--out", tmp_path / "x")
    assert proc.returncode != 0 and "Traceback" not in proc.stderr and not (tmp_path / "x").exists()
    proc = cli("grow", "--foliage", "ferns", "--out", tmp_path / "x")
    assert proc.returncode != 0 and "Traceback" not in proc.stderr and not (tmp_path / "x").exists()
