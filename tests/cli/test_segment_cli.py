"""``treeform segment``, ``treeform species`` and ``treeform reconstruct --method learned``."""

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from cli_helpers import assert_clean_failure, cli

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = ROOT / "src" / "treeform" / "data" / "Celtis_occidentalis_1.jpg"


@pytest.mark.parametrize("segmenter", ["learned", "classical"])
def test_segment_writes_single_channel_labels_at_photo_size(tmp_path, segmenter):
    out, ov = tmp_path / "labels.png", tmp_path / "overlay.png"
    proc = cli("segment", SAMPLE, "-o", out, "--overlay", ov, "--segmenter", segmenter)
    assert proc.returncode == 0, proc.stderr
    im = Image.open(out)
    assert im.mode == "L" and im.size == Image.open(SAMPLE).size
    lab = np.asarray(im)
    assert set(np.unique(lab)) <= {0, 1, 2} and (lab == 1).any()
    assert Image.open(ov).size == im.size


def test_segment_treeless_photo_fails_cleanly(tmp_path):
    noise = np.random.default_rng(1).integers(0, 256, (200, 300, 3)).astype(np.uint8)
    Image.fromarray(noise).save(tmp_path / "noise.png")
    out = tmp_path / "out"
    out.mkdir()
    proc = cli("segment", tmp_path / "noise.png", "-o", out / "labels.png", "--segmenter", "learned")
    assert_clean_failure(proc, out)
    assert "no tree found" in proc.stderr


def test_species_prints_top3_and_json():
    proc = cli("species", SAMPLE)
    assert proc.returncode == 0, proc.stderr
    lines = [l.split() for l in proc.stdout.strip().splitlines()]
    assert len(lines) == 3 and all(len(l) == 2 for l in lines)
    ps = [float(l[1]) for l in lines]
    assert ps == sorted(ps, reverse=True) and 0 < sum(ps) <= 1.001
    proc = cli("species", SAMPLE, "--json")
    d = json.loads(proc.stdout)
    assert len(d) == 7 and abs(sum(d.values()) - 1) < 1e-3


def test_reconstruct_learned_with_species_override(tmp_path):
    out = tmp_path / "t"
    proc = cli("reconstruct", SAMPLE, "--method", "learned", "--species", "maple", "--lod", "low", "-o", out)
    assert proc.returncode == 0, proc.stderr
    m = json.loads((out / "metrics.json").read_text())
    assert m["species"] == "maple" and (out / "tree.glb").stat().st_size > 10_000
    bad = cli("reconstruct", SAMPLE, "--method", "learned", "--species", "palm", "-o", tmp_path / "u")
    assert_clean_failure(bad, tmp_path / "u")
