"""load_photos: folder listing, EXIF orientation, resizing, focal prior, and the errors."""

import math

import numpy as np
import pytest
from conftest import ROTATED, focal_35mm, save_jpeg
from PIL import Image

from treeform._shared.errors import InputError
from treeform.sfm.photos import PhotoView, exif_focal_px, load_photos


def _pattern(h=60, w=80, seed=0):
    """An asymmetric RGB test image (any rotation or flip changes it)."""
    rng = np.random.default_rng(seed)
    im = rng.integers(0, 255, (h, w, 3), dtype=np.uint8)
    im[:10, :20] = (255, 0, 0)
    return im


def test_reads_the_capture_sorted_upright_with_the_exif_focal(capture):
    folder, cams = capture
    views = load_photos(folder)
    assert [v.name for v in views] == sorted(cams)
    for v in views:
        cam = cams[v.name]
        assert v.size == (cam.width, cam.height)  # the rotated photo comes back landscape
        assert v.focal_source == "exif_35mm"
        assert v.focal_px == pytest.approx(cam.focal, rel=0.02)  # f35 is rounded to whole mm
        assert v.scale == 1.0
    with Image.open(folder / ROTATED) as raw:
        assert raw.size == (cams[ROTATED].height, cams[ROTATED].width)  # stored portrait


def test_exif_orientation_is_applied(tmp_path):
    upright = _pattern()
    for k, (arr, orientation) in enumerate([(upright, None), (np.rot90(upright, 1), 6), (np.rot90(upright, -1), 8),
                                            (upright[::-1, ::-1], 3)]):
        exif = Image.Exif()
        if orientation:
            exif[0x0112] = orientation
        Image.fromarray(np.ascontiguousarray(arr)).save(tmp_path / f"p{k}.png", exif=exif)
    views = load_photos(tmp_path)
    assert len(views) == 4
    for v in views:
        np.testing.assert_array_equal(v.image, upright, err_msg=v.name)


def test_resizes_to_max_size_and_scales_the_focal(tmp_path):
    for k in range(3):
        save_jpeg(tmp_path / f"a{k}.JPG", _pattern(600, 800, k), f35=36)  # upper-case suffix is read
    (tmp_path / "notes.txt").write_text("not a photo")
    (tmp_path / ".hidden.jpg").write_bytes(b"")  # hidden files are skipped
    views = load_photos(tmp_path, max_size=400)
    assert [v.name for v in views] == ["a0.JPG", "a1.JPG", "a2.JPG"]
    for v in views:
        assert v.size == (400, 300) and v.original_size == (800, 600)
        assert v.scale == pytest.approx(0.5)
        assert v.focal_px == pytest.approx(36 * 500 / math.hypot(36, 24))  # diagonal of 400 x 300 = 500 px


def test_mixed_sizes_and_a_list_of_paths(tmp_path):
    paths = []
    for k, (h, w) in enumerate([(60, 80), (80, 60), (90, 90)]):
        Image.fromarray(_pattern(h, w, k)).save(tmp_path / f"m{k}.png")
        paths.append(tmp_path / f"m{k}.png")
    views = load_photos([paths[2], paths[0], paths[1]])  # a list keeps its order
    assert [v.size for v in views] == [(90, 90), (80, 60), (60, 80)]
    assert all(v.focal_px is None and v.focal_source == "none" for v in views)


def test_exif_focal_rules():
    assert exif_focal_px({0xA405: 36}, (1500, 1000)) == (1500.0, "exif_35mm")
    # FocalLength with the sensor's pixel density: 4 mm at 1000 px / mm, photo halved
    f, src = exif_focal_px({0x920A: 4.0, 0xA20E: 1000.0, 0xA210: 4}, (2000, 1500), (4000, 3000))
    assert src == "exif_focal_plane" and f == pytest.approx(2000.0)
    # inch units (the EXIF default)
    f, src = exif_focal_px({0x920A: 4.0, 0xA20E: 25400.0}, (4000, 3000))
    assert src == "exif_focal_plane" and f == pytest.approx(4000.0)
    assert exif_focal_px({0x920A: 4.0}, (4000, 3000)) == (None, "none")  # no sensor size: no prior
    assert exif_focal_px({0xA405: 1}, (4000, 3000)) == (None, "none")  # a 170° lens: broken EXIF
    assert exif_focal_px({0xA405: 0}, (4000, 3000)) == (None, "none")


def test_too_few_photos(tmp_path):
    for k in range(2):
        Image.fromarray(_pattern(seed=k)).save(tmp_path / f"p{k}.png")
    with pytest.raises(InputError, match="need at least 3 photos of the tree, found 2"):
        load_photos(tmp_path)
    with pytest.raises(InputError, match="found 1"):
        load_photos(tmp_path / "p0.png")
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="found 0"):
        load_photos(tmp_path / "empty")


def test_unreadable_file_is_named(tmp_path):
    for k in range(3):
        Image.fromarray(_pattern(seed=k)).save(tmp_path / f"p{k}.png")
    (tmp_path / "broken.jpg").write_bytes(b"\xff\xd8\xff\xe0 this is not a jpeg")
    with pytest.raises(InputError, match="broken.jpg"):
        load_photos(tmp_path)


def test_missing_folder_and_duplicate_names(tmp_path):
    with pytest.raises(InputError, match="no such folder"):
        load_photos(tmp_path / "nowhere")
    for d in ("a", "b"):
        (tmp_path / d).mkdir()
        Image.fromarray(_pattern()).save(tmp_path / d / "same.png")
    Image.fromarray(_pattern()).save(tmp_path / "other.png")
    with pytest.raises(InputError, match="same file name"):
        load_photos([tmp_path / "a" / "same.png", tmp_path / "b" / "same.png", tmp_path / "other.png"])


def test_photo_view_checks():
    with pytest.raises(InputError, match="PhotoView.image"):
        PhotoView("x", np.zeros((10, 10), np.uint8))
    with pytest.raises(InputError, match="focal_px"):
        PhotoView("x", np.zeros((20, 20, 3), np.uint8), focal_px=-1.0)
    v = PhotoView("x", np.zeros((20, 30, 3), np.uint8))
    assert v.size == (30, 20) and v.original_size == (30, 20) and v.photo.shape == (20, 30)


def test_focal_35mm_helper_matches_the_reader(capture):
    folder, cams = capture
    cam = cams["v00.jpg"]
    f35 = focal_35mm(cam)
    assert exif_focal_px({0xA405: f35}, (cam.width, cam.height))[0] == pytest.approx(cam.focal, rel=0.02)
