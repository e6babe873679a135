"""`treeform multiview` on bad input: one clear line, a non-zero exit, no output folder."""

import numpy as np
import pytest
from cli_helpers import assert_clean_failure, cli
from PIL import Image

pytest.importorskip("pycolmap", reason="pycolmap is not installed (multi-view SfM)")


def test_empty_folder_and_one_photo(tmp_path):
    (tmp_path / "empty").mkdir()
    proc = cli("multiview", tmp_path / "empty", "--out", tmp_path / "out")
    assert_clean_failure(proc, tmp_path / "out")
    assert "at least 3 photos" in proc.stderr
    (tmp_path / "one").mkdir()
    Image.new("RGB", (64, 48), (90, 120, 60)).save(tmp_path / "one" / "a.jpg")
    assert_clean_failure(cli("multiview", tmp_path / "one", "--out", tmp_path / "out"), tmp_path / "out")
    assert_clean_failure(cli("multiview", tmp_path / "missing", "--out", tmp_path / "out"), tmp_path / "out")


def test_photos_of_different_scenes_do_not_register(tmp_path):
    """Photos that share nothing (here: different textures, sizes and an EXIF rotation): the SfM exit
    status 7 with its reason, nothing written."""
    rng = np.random.default_rng(1)
    photos = tmp_path / "photos"
    photos.mkdir()
    for k, size in enumerate([(320, 240), (400, 300), (240, 320), (320, 240)]):
        img = Image.fromarray(rng.integers(0, 255, (size[1], size[0], 3), dtype=np.uint8))
        exif = img.getexif()
        if k == 2:
            exif[0x0112] = 6  # rotated 90 degrees, as a phone held sideways writes it
        img.save(photos / f"p{k}.jpg", exif=exif)
    proc = cli("multiview", photos, "--out", tmp_path / "out")
    assert_clean_failure(proc, tmp_path / "out")
    assert proc.returncode == 7 and "could not register the photos" in proc.stderr
