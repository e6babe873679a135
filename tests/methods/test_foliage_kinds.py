"""Foliage kinds and texture sizes through the pipelines: pine needles, conical-crown needles,
--texture-size (issue 18)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from treeform._shared.errors import InputError
from treeform.geometry import leaf_texture, texture_coverage
from treeform.io.gltf import read_glb_textures
from treeform.methods.envelope.config import EnvelopeConfig
from treeform.methods.learned import GrowConfig
from treeform.methods.learned.config import LearnedConfig
from treeform.methods.learned.grow import grow_tree

SAMPLE = Path(__file__).resolve().parents[2] / "src" / "treeform" / "data" / "Celtis_occidentalis_1.jpg"


@pytest.fixture(scope="module")
def pine(tmp_path_factory):
    out = tmp_path_factory.mktemp("pine") / "t"
    return grow_tree("pine", seed=0, out=out, lod="low", render_size=64, age=6), out


def test_pine_glb_uses_the_needle_texture(pine):
    res, out = pine
    tex = read_glb_textures(out / "tree.glb")
    np.testing.assert_array_equal(tex["leaves"], leaf_texture(256, seed=0, kind="needles"))
    assert texture_coverage(tex["leaves"]) < 0.45  # thin needles, not a paper card
    assert tex["bark"].shape == (512, 512, 4)
    # the OBJ's leaf atlas is made of the same needle tiles
    atlas = np.asarray(Image.open(out / "tree_leaves.png").convert("RGBA"))
    np.testing.assert_array_equal(atlas[:256, :256, 3], tex["leaves"][..., 3])


def test_foliage_override_and_texture_size(tmp_path):
    grow_tree("pine", seed=0, out=tmp_path / "t", lod="low", render_size=64, age=6, foliage="scales",
              texture_size=128)
    tex = read_glb_textures(tmp_path / "t" / "tree.glb")
    np.testing.assert_array_equal(tex["leaves"], leaf_texture(64, seed=0, kind="scales"))
    assert tex["bark"].shape == (128, 128, 4)
    assert Image.open(tmp_path / "t" / "tree_bark.png").size == (128, 128)
    assert Image.open(tmp_path / "t" / "tree_leaves.png").size[0] % 64 == 0  # atlas of 64² tiles
    cfg = json.loads((tmp_path / "t" / "config.json").read_text())["config"]
    assert cfg["foliage"] == "scales" and cfg["texture_size"] == 128
    oak = grow_tree("oak", seed=0, lod="low", render_size=64, age=6, previews=False)
    leaves = next(p for p in oak.mesh.parts if p.name == "leaves")
    np.testing.assert_array_equal(leaves.material.texture, leaf_texture(256, seed=0, kind="cluster"))


def test_configs_check_the_new_options():
    assert EnvelopeConfig(crown="conical").validate().foliage_kind() == "needles"
    assert EnvelopeConfig(crown="round").validate().foliage_kind() == "broadleaf"
    assert EnvelopeConfig(crown="conical", foliage="scales").validate().foliage_kind() == "scales"
    # the growth form: a conifer (given, or found by reconstruct) wears needles on a conical envelope
    auto = EnvelopeConfig().validate()
    assert auto.form == "auto" and auto.crown == "auto"
    assert auto.foliage_kind("conifer") == "needles" and auto.foliage_kind("broadleaf") == "broadleaf"
    assert auto.crown_for("conifer") == "conical" and auto.crown_for("broadleaf") == "round"
    assert EnvelopeConfig(form="conifer", crown="round").validate().crown_for("conifer") == "round"
    assert EnvelopeConfig(form="conifer", foliage="scales").validate().foliage_kind() == "scales"
    with pytest.raises(InputError, match="form"):
        EnvelopeConfig(form="palm").validate()
    for cls in (EnvelopeConfig, GrowConfig, LearnedConfig):
        with pytest.raises(InputError, match="foliage"):
            cls(foliage="ferns").validate()
        with pytest.raises(InputError, match="texture_size"):
            cls(texture_size=4).validate()
        assert cls(texture_size=1024).validate().texture_size == 1024


def test_conical_reconstruct_gets_needles(tmp_path):
    from treeform import reconstruct

    opts = dict(seed=0, max_size=320, attractors=3000, leaves=1500, rdm_resolution=128, lod="low", crown="conical")
    reconstruct(SAMPLE, out=tmp_path / "p", leaf_texture="procedural", **opts)
    tex = read_glb_textures(tmp_path / "p" / "tree.glb")
    np.testing.assert_array_equal(tex["leaves"], leaf_texture(tex["leaves"].shape[0], seed=0, kind="needles"))
    # photo-textured: the photo's crown in needle-cluster outlines (sparser than broadleaf ones)
    res = reconstruct(SAMPLE, out=tmp_path / "t", **opts)
    round_ = reconstruct(SAMPLE, **{**opts, "crown": "round"})
    def opaque(r):
        return float((next(p for p in r.mesh.parts if p.name == "leaves").material.texture[..., 3] > 127).mean())
    assert opaque(res) < 0.8 * opaque(round_)
    # the sparser needle cards are made larger, so the crown still fills the photo's silhouette
    assert res.metrics["reprojection_error"] < 0.2
    assert json.loads((tmp_path / "t" / "config.json").read_text())["config"]["foliage"] == "auto"


def test_learned_route_passes_foliage_and_texture_size_to_growth():
    from treeform.methods.learned.pipeline import reconstruct

    res = reconstruct(SAMPLE, species="pine", lod="low", max_size=320, texture_size=256, leaf_texture="procedural")
    parts = {p.name: p for p in res.mesh.parts}
    np.testing.assert_array_equal(parts["leaves"].material.texture, leaf_texture(128, seed=0, kind="needles"))
    assert parts["bark"].material.texture.shape == (256, 256, 4)
