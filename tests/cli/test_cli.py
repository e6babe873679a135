"""The treeform command: happy path and every bad input the issue lists (one-line error, exit != 0, no files)."""

from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from cli_helpers import assert_clean_failure, cli
from treeform import __version__

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = ROOT / "src" / "treeform" / "data" / "Celtis_occidentalis_1.jpg"




def test_version():
    proc = cli("--version")
    assert proc.returncode == 0 and __version__ in proc.stdout


def test_help_lists_verbs():
    proc = cli("--help")
    assert proc.returncode == 0 and "reconstruct" in proc.stdout and "demo" in proc.stdout


def _celtis():
    return Image.open(SAMPLE).convert("RGB")


def _write(tmp_path, name, fn):
    p = tmp_path / name
    fn(p)
    return p


BAD = {
    "not_an_image.jpg": lambda p: p.write_text("this is not an image\n"),
    "truncated.jpg": lambda p: p.write_bytes(SAMPLE.read_bytes()[: len(SAMPLE.read_bytes()) // 2]),
    "empty.jpg": lambda p: p.write_bytes(b""),
    "one_pixel.png": lambda p: Image.new("RGB", (1, 1), (0, 128, 0)).save(p),
    "sky.png": lambda p: Image.fromarray(np.tile(np.linspace([90, 150, 230], [160, 200, 250], 300)[:, None],
                                                 (1, 400, 1)).astype(np.uint8)).save(p),
}


@pytest.mark.parametrize("name", sorted(BAD))
def test_bad_photos_fail_cleanly(tmp_path, name):
    photo = _write(tmp_path, name, BAD[name])
    out = tmp_path / "out"
    assert_clean_failure(cli("reconstruct", photo, "--out", out), out)


def test_missing_path(tmp_path):
    out = tmp_path / "out"
    proc = cli("reconstruct", tmp_path / "nope.jpg", "--out", out)
    assert_clean_failure(proc, out)
    assert "nope.jpg" in proc.stderr


def test_unwritable_out(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    for out in (blocker, blocker / "sub"):
        proc = cli("reconstruct", SAMPLE, "--out", out)
        assert proc.returncode != 0 and "Traceback" not in proc.stderr
        assert proc.stderr.count("error:") == 1
    assert blocker.read_text() == "x"


def test_bad_mask_size(tmp_path):
    Image.new("L", (37, 91), 255).save(tmp_path / "m.png")
    out = tmp_path / "out"
    assert_clean_failure(cli("reconstruct", SAMPLE, "--mask", tmp_path / "m.png", "--out", out), out)


GOOD = {
    "gray.jpg": lambda p: _celtis().convert("L").save(p),
    "cmyk.jpg": lambda p: _celtis().convert("CMYK").save(p),
    "sixteen.png": lambda p: Image.fromarray((np.asarray(_celtis().convert("L"), np.uint16) * 257)).save(p),
}


@pytest.mark.parametrize("name", sorted(GOOD))
def test_other_modes_give_a_result_or_a_clean_error(tmp_path, name):
    photo = _write(tmp_path, name, GOOD[name])
    out = tmp_path / "out"
    proc = cli("reconstruct", photo, "--out", out, "--leaves", "2000")
    if proc.returncode == 0:
        assert (out / "tree.glb").exists() and (out / "preview.png").exists()
    else:
        assert_clean_failure(proc, out)
    if name == "cmyk.jpg":  # colour is intact: this one must work
        assert proc.returncode == 0, proc.stderr


def test_exif_rotated_photo_is_uprighted(tmp_path):
    im = _celtis().rotate(90, expand=True)  # stored sideways ...
    exif = Image.Exif()
    exif[0x0112] = 6  # ... with "rotate 90° CW to view"
    p = tmp_path / "rotated.jpg"
    im.save(p, exif=exif.tobytes())
    out = tmp_path / "out"
    proc = cli("reconstruct", p, "--out", out, "--leaves", "2000")
    assert proc.returncode == 0, proc.stderr
    import json

    w, h = json.loads((out / "metrics.json").read_text())["photo_size"]
    assert h > w  # portrait again, like the original


def test_huge_photo_is_downscaled(tmp_path):
    p = tmp_path / "huge.jpg"
    _celtis().resize((9000, 12000), Image.BILINEAR).save(p, quality=70)
    out = tmp_path / "out"
    proc = cli("reconstruct", p, "--out", out, "--leaves", "2000")
    assert proc.returncode == 0, proc.stderr
    import json

    w, h = json.loads((out / "metrics.json").read_text())["photo_size"]
    assert max(w, h) <= 640


def test_reconstruct_cli_happy_path(tmp_path):
    out = tmp_path / "o"
    proc = cli("reconstruct", SAMPLE, "--out", out, "--seed", "2", "--crown", "round", "--leaves", "3000", "--lod", "low")
    assert proc.returncode == 0, proc.stderr
    assert "reprojection error" in proc.stdout
    for stage in ("segment", "envelope", "colonize", "export"):
        assert stage in proc.stderr  # per-stage timings on the progress display
    assert (out / "tree.glb").stat().st_size > 10_000
