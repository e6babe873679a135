"""`treeform cloud`: a photo through the billboard path to a GLB + sidecar + strip, and bad
inputs (one `error:` line, non-zero exit, no partial files)."""

from pathlib import Path

import numpy as np
import pytest
from cli_helpers import assert_clean_failure, cli
from PIL import Image

SAMPLE = Path(__file__).resolve().parents[2] / "src" / "treeform" / "data" / "Celtis_occidentalis_1.jpg"


def test_photo_to_cloud_with_views(tmp_path, gl):
    out = tmp_path / "out"
    out.mkdir()
    proc = cli("cloud", SAMPLE, "-o", out / "tree.glb", "--views", out / "views.png", "--segments", "128",
               "--compactness", "0.2", "--seed", "2")
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in out.iterdir()) == ["tree.glb", "tree.json", "views.png"]
    assert "billboards (front" in proc.stdout and "IoU" in proc.stdout
    iou = float(proc.stdout.rsplit("IoU", 1)[1].strip())
    assert iou >= 0.95
    assert '"kind":"photo"' in (out / "tree.json").read_text()


def _missing(d: Path) -> Path:
    return d / "missing.png"


def _text(d: Path) -> Path:
    (d / "notes.png").write_text("not an image")
    return d / "notes.png"


def _transparent(d: Path) -> Path:
    Image.fromarray(np.zeros((32, 32, 4), np.uint8)).save(d / "empty.png")
    return d / "empty.png"


def _photo(d: Path) -> Path:
    return SAMPLE


@pytest.mark.parametrize("make, name, words", [
    (_missing, "c.glb", "no such file"),
    (_text, "c.glb", "not an image"),
    (_transparent, "c.glb", "no opaque"),
    (_photo, "c.obj", ".glb"),
])
def test_bad_input_one_line_no_files(make, name, words, tmp_path):
    src = tmp_path / "in"
    src.mkdir()
    out = tmp_path / "out"
    out.mkdir()
    proc = cli("cloud", make(src), "-o", out / name, "--views", out / "v.png")
    assert_clean_failure(proc, out)
    assert words in proc.stderr
