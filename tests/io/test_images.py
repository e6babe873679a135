"""read_photo / read_mask / write_png: every bad input gives one clear InputError line."""

from __future__ import annotations

import json
import struct
import subprocess
import sys
import zlib

import numpy as np
import pytest
from PIL import Image, ImageFile

from treeform._shared.errors import InputError, OutputError
from treeform.io import read_mask, read_photo, write_png
from treeform.io.images import MAX_PIXELS
from treeform.structures.photo import Photo


def _raises_one_line(path, match, **kw):
    with pytest.raises(InputError, match=match) as err:
        read_photo(path, **kw)
    msg = str(err.value)
    assert "\n" not in msg and len(msg) < 300 and str(path) in msg
    return msg


def _noise(h, w, c=3, seed=0):
    return np.random.default_rng(seed).integers(0, 256, (h, w, c), dtype=np.uint8)


# ---------------------------------------------------------------- bad inputs
def test_missing_path(tmp_path):
    _raises_one_line(tmp_path / "nope.jpg", "no such file")


def test_directory(tmp_path):
    _raises_one_line(tmp_path, "is a directory")


def test_empty_file(tmp_path):
    (tmp_path / "e.jpg").write_bytes(b"")
    _raises_one_line(tmp_path / "e.jpg", "empty file")


def test_non_image_file(tmp_path):
    (tmp_path / "notes.jpg").write_text("this is not a photograph\n" * 20)
    _raises_one_line(tmp_path / "notes.jpg", "not an image file")


@pytest.mark.parametrize("lenient", [False, True])
def test_truncated_jpeg(tmp_path, monkeypatch, lenient):
    """Half a JPEG is an error, even if someone set LOAD_TRUNCATED_IMAGES globally."""
    monkeypatch.setattr(ImageFile, "LOAD_TRUNCATED_IMAGES", lenient)
    Image.fromarray(_noise(300, 400)).save(tmp_path / "full.jpg", quality=90)
    data = (tmp_path / "full.jpg").read_bytes()
    (tmp_path / "half.jpg").write_bytes(data[: len(data) // 2])
    _raises_one_line(tmp_path / "half.jpg", "truncated")
    assert ImageFile.LOAD_TRUNCATED_IMAGES is lenient  # restored


def test_corrupt_png_data(tmp_path):
    Image.fromarray(_noise(64, 64)).save(tmp_path / "ok.png")
    data = bytearray((tmp_path / "ok.png").read_bytes())
    data[60:200] = b"\x00" * 140  # clobber the IDAT stream, keep the header
    (tmp_path / "bad.png").write_bytes(bytes(data))
    _raises_one_line(tmp_path / "bad.png", "truncated or corrupt|unreadable")


@pytest.mark.parametrize("size", [(1, 1), (15, 200), (200, 15)])
def test_too_small(tmp_path, size):
    Image.new("RGB", size, (10, 200, 10)).save(tmp_path / "tiny.png")
    msg = _raises_one_line(tmp_path / "tiny.png", "image too small")
    assert f"{size[0]}\u00d7{size[1]}" in msg


def _png_header_only(path, w, h):
    """A PNG whose IHDR claims w x h (no decodable pixels): tests the size check cheaply."""
    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))
    ihdr = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * 64))
                     + chunk(b"IEND", b""))


@pytest.mark.parametrize("w,h", [(15000, 14000), (40000, 40000)])
def test_too_large(tmp_path, w, h):
    assert w * h > MAX_PIXELS
    _png_header_only(tmp_path / "huge.png", w, h)
    _raises_one_line(tmp_path / "huge.png", "image too large.*200 MP")


def test_bad_max_size(tmp_path):
    Image.new("RGB", (32, 32)).save(tmp_path / "a.png")
    for bad in (0, 8, 10.5, "1024", True):
        with pytest.raises(InputError, match="max_size"):
            read_photo(tmp_path / "a.png", max_size=bad)


# ---------------------------------------------------------------- huge JPEG
_MAKE_BIG = """
import sys
from PIL import Image, ImageDraw
im = Image.new("RGB", (12000, 9000), (30, 120, 40))
ImageDraw.Draw(im).rectangle([0, 0, 5999, 4499], fill=(220, 30, 30))
im.save(sys.argv[1], quality=50)
"""

_READ_BIG = """
import json, resource, sys
from treeform.io import read_photo
p = read_photo(sys.argv[1], max_size=1024)
peak_kb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
try:  # VmHWM: this process's own peak (ru_maxrss can carry the parent's over exec)
    for line in open("/proc/self/status"):
        if line.startswith("VmHWM:"):
            peak_kb = int(line.split()[1])
except OSError:
    pass
print(json.dumps({"shape": list(p.shape), "scale": p.scale, "tl": p.image[10, 10].tolist(),
                  "br": p.image[-10, -10].tolist(), "peak_mb": peak_kb / 1024}))
"""


@pytest.fixture(scope="module")
def big_jpeg(tmp_path_factory):
    """A 12000 x 9000 JPEG, made in a child process so this one stays small."""
    path = tmp_path_factory.mktemp("big") / "big.jpg"
    subprocess.run([sys.executable, "-c", _MAKE_BIG, str(path)], check=True, timeout=120)
    return path


def test_huge_jpeg_is_downscaled_with_bounded_memory(big_jpeg):
    proc = subprocess.run([sys.executable, "-c", _READ_BIG, str(big_jpeg)], capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    r = json.loads(proc.stdout)
    assert max(r["shape"]) <= 1024 and r["shape"] == [768, 1024]
    assert r["scale"] == pytest.approx(1024 / 12000)
    assert np.allclose(r["tl"], (220, 30, 30), atol=12) and np.allclose(r["br"], (30, 120, 40), atol=12)
    # a full decode alone would be 12000 * 9000 * 3 B = 324 MB
    assert r["peak_mb"] < 200, f"peak memory {r['peak_mb']:.0f} MB"


def test_huge_jpeg_in_process(big_jpeg):
    p = read_photo(big_jpeg, max_size=512)
    assert p.shape == (384, 512) and p.scale == pytest.approx(512 / 12000)
    assert p.source == str(big_jpeg)


# ---------------------------------------------------------------- conversions
def test_rgb_png_exact_and_scale(tmp_path):
    img = _noise(40, 60)
    Image.fromarray(img).save(tmp_path / "a.png")
    p = read_photo(tmp_path / "a.png")
    assert isinstance(p, Photo) and p.scale == 1.0
    np.testing.assert_array_equal(p.image, img)
    Image.new("RGB", (2048, 1024), (1, 2, 3)).save(tmp_path / "wide.png")
    p = read_photo(tmp_path / "wide.png", max_size=1024)
    assert p.shape == (512, 1024) and p.scale == pytest.approx(0.5)


def test_grayscale(tmp_path):
    g = _noise(32, 48, 1)[..., 0]
    Image.fromarray(g).save(tmp_path / "g.png")
    p = read_photo(tmp_path / "g.png")
    assert p.image.shape == (32, 48, 3)
    for c in range(3):
        np.testing.assert_array_equal(p.image[..., c], g)


def test_cmyk_jpeg(tmp_path):
    img = np.zeros((64, 64, 3), np.uint8)
    img[:32] = (200, 40, 40)
    img[32:] = (40, 60, 200)
    Image.fromarray(img).convert("CMYK").save(tmp_path / "c.jpg", quality=95)
    with Image.open(tmp_path / "c.jpg") as im:
        assert im.mode == "CMYK"
    p = read_photo(tmp_path / "c.jpg")
    assert np.abs(p.image[8, 8].astype(int) - (200, 40, 40)).max() < 20
    assert np.abs(p.image[56, 56].astype(int) - (40, 60, 200)).max() < 20


def test_16bit_png_gradient_spans_full_range(tmp_path):
    grad = np.tile(np.linspace(0, 65535, 256).round().astype(np.uint16), (32, 1))
    Image.fromarray(grad).save(tmp_path / "g16.png")
    with Image.open(tmp_path / "g16.png") as im:
        assert im.mode in ("I;16", "I")
    p = read_photo(tmp_path / "g16.png")
    row = p.image[16, :, 0].astype(int)
    assert row.min() <= 1 and row.max() >= 254  # not clipped to white
    assert np.all(np.diff(row) >= 0) and len(np.unique(row)) > 200
    np.testing.assert_allclose(row, np.arange(256), atol=1)


def test_rgba_and_la_composited_over_white(tmp_path):
    rgba = np.zeros((20, 20, 4), np.uint8)
    rgba[..., 0] = 255
    rgba[:10, :, 3] = 255  # top half opaque red, bottom half fully transparent
    Image.fromarray(rgba).save(tmp_path / "a.png")
    p = read_photo(tmp_path / "a.png")
    assert p.image[2, 2].tolist() == [255, 0, 0] and p.image[15, 15].tolist() == [255, 255, 255]
    Image.fromarray(rgba).convert("LA").save(tmp_path / "la.png")
    p = read_photo(tmp_path / "la.png")
    assert p.image[15, 15].tolist() == [255, 255, 255] and p.image[2, 2, 0] == p.image[2, 2, 1]


def test_palette_with_transparency(tmp_path):
    pal = Image.new("P", (20, 20), 0)
    pal.putpalette([0, 0, 0, 0, 128, 0] + [0] * 762)
    pal.paste(1, (0, 0, 20, 10))
    pal.save(tmp_path / "p.png", transparency=0)
    p = read_photo(tmp_path / "p.png")
    assert p.image[2, 2].tolist() == [0, 128, 0] and p.image[15, 15].tolist() == [255, 255, 255]


def test_exif_orientation(tmp_path):
    img = np.zeros((100, 160, 3), np.uint8)
    img[:20, :20] = (255, 0, 0)  # red marker at the stored top-left
    im = Image.fromarray(img)
    exif = im.getexif()
    exif[0x0112] = 6  # "rotate 90 CW to display"
    im.save(tmp_path / "r.jpg", exif=exif, quality=95)
    p = read_photo(tmp_path / "r.jpg")
    assert p.shape == (160, 100)  # width and height swapped
    assert p.image[5, -5, 0] > 200 and p.image[5, 5, 0] < 50  # marker now at the top-right


def test_read_cutout_alpha_and_straight_colours(tmp_path):
    from treeform.io.images import read_cutout

    rgba = np.zeros((40, 40, 4), np.uint8)
    rgba[..., :3] = (200, 30, 10)  # the colour under the transparency too (straight alpha)
    rgba[:20, :, 3] = 255
    rgba[20:24, :, 3] = 153  # a half-transparent rim: 0.6
    rgba[:10, 15:25, 3] = 0  # a gap between two limbs: no tree is a convex shape
    Image.fromarray(rgba).save(tmp_path / "c.png")
    alpha, rgb = read_cutout(tmp_path / "c.png", (40, 40))
    assert alpha.dtype == np.float32 and alpha.shape == (40, 40)
    assert alpha[5, 5] == 1.0 and alpha[22, 5] == pytest.approx(0.6, abs=0.01) and alpha[30, 5] == 0.0
    assert rgb[22, 5].tolist() == [200, 30, 10]  # the rim's own colour, not a blend with white
    assert read_photo(tmp_path / "c.png").image[22, 5].tolist() != [200, 30, 10]  # what read_photo draws
    half, _ = read_cutout(tmp_path / "c.png", (20, 20))  # at the photo's size (area average)
    assert half.shape == (20, 20) and half[2, 2] == 1.0 and half[15, 2] == 0.0
    # not a cut-out: no alpha, opaque everywhere, or nothing opaque
    Image.fromarray(rgba[..., :3]).save(tmp_path / "rgb.png")
    opaque = rgba.copy()
    opaque[..., 3] = 255
    Image.fromarray(opaque).save(tmp_path / "opaque.png")
    clear = rgba.copy()
    clear[..., 3] = 0
    Image.fromarray(clear).save(tmp_path / "clear.png")
    for name in ("rgb.png", "opaque.png", "clear.png"):
        assert read_cutout(tmp_path / name, (40, 40)) is None, name
    # a photo saved with clear corners (turned a few degrees, or rounded) is a photo, not a cut-out
    photo = Image.fromarray(np.full((60, 80, 3), 90, np.uint8)).convert("RGBA").rotate(8, expand=True)
    photo.save(tmp_path / "turned.png")
    assert (np.asarray(photo)[..., 3] == 0).mean() > 0.05  # its corners are clear ...
    assert read_cutout(tmp_path / "turned.png", photo.size[::-1]) is None  # ... but it is no tree
    round_ = rgba.copy()
    yy, xx = np.mgrid[:40, :40]
    round_[..., 3] = np.where((yy - 19.5) ** 2 + (xx - 19.5) ** 2 < 19 ** 2, 255, 0)
    Image.fromarray(round_).save(tmp_path / "round.png")
    assert read_cutout(tmp_path / "round.png", (40, 40)) is None
    with pytest.raises(InputError, match="no such file"):
        read_cutout(tmp_path / "missing.png", (40, 40))


def test_a_cutout_brings_its_own_mask_to_the_single_photo_methods(tmp_path):
    from treeform.methods._single_photo import load_photo

    rgba = np.zeros((300, 200, 4), np.uint8)
    rgba[..., :3] = (30, 140, 40)
    rgba[40:260, 50:150, 3] = 255
    rgba[40:260, 150:154, 3] = 153  # a rim that read_photo blends with white
    rgba[40:100, 60:80, 3] = 0  # a gap in the crown (a tree's outline is not convex)
    Image.fromarray(rgba).save(tmp_path / "tree.png")
    ph, mask = load_photo(tmp_path / "tree.png", max_size=150)  # read at half size
    assert ph.shape == (150, 100) and mask.shape == (150, 100)
    assert mask[50:130, 25:75].all() and mask.sum() == 110 * 52 - 30 * 10  # the alpha over one half
    assert ph.image[75, 76].tolist() == [30, 140, 40]  # the rim keeps the tree's colour
    assert ph.image[5, 5].tolist() == [255, 255, 255]  # the background as read_photo draws it
    own = np.zeros((150, 100), bool)
    own[:10] = True
    assert (load_photo(tmp_path / "tree.png", own, max_size=150)[1] == own).all()  # a given mask wins
    Image.fromarray(rgba[..., :3]).save(tmp_path / "photo.png")
    assert load_photo(tmp_path / "photo.png", max_size=150)[1] is None  # a photo: segmented as before


# ---------------------------------------------------------------- masks
def test_read_mask_same_size_any_mode(tmp_path):
    m = np.zeros((40, 60), bool)
    m[10:30, 20:50] = True
    Image.fromarray(m.astype(np.uint8) * 255).save(tmp_path / "m.png")
    np.testing.assert_array_equal(read_mask(tmp_path / "m.png", (40, 60)), m)
    Image.fromarray(m.astype(np.uint8) * 255).convert("RGB").save(tmp_path / "rgb.png")
    np.testing.assert_array_equal(read_mask(tmp_path / "rgb.png", (40, 60)), m)
    Image.fromarray(m).save(tmp_path / "one.png")  # mode "1"
    np.testing.assert_array_equal(read_mask(tmp_path / "one.png", (40, 60)), m)
    Image.fromarray(m.astype(np.uint16) * 65535).save(tmp_path / "m16.png")
    np.testing.assert_array_equal(read_mask(tmp_path / "m16.png", (40, 60)), m)
    rgba = np.zeros((40, 60, 4), np.uint8)
    rgba[..., :3] = 255
    rgba[..., 3] = m * 255  # white painted on transparent
    Image.fromarray(rgba).save(tmp_path / "a.png")
    out = read_mask(tmp_path / "a.png", (40, 60))
    assert out.dtype == bool and out.shape == (40, 60)
    np.testing.assert_array_equal(out, m)


def test_read_mask_rescaled_nearest(tmp_path):
    m = np.zeros((20, 30), np.uint8)
    m[5:15, 10:20] = 255
    Image.fromarray(m).save(tmp_path / "m.png")
    out = read_mask(tmp_path / "m.png", (40, 60))
    np.testing.assert_array_equal(out, np.kron(m > 127, np.ones((2, 2), bool)))
    assert read_mask(tmp_path / "m.png", (40, 60.0 * 1.005)).shape == (40, 60)  # within 1 %


def test_read_mask_aspect_mismatch(tmp_path):
    Image.new("L", (120, 100), 255).save(tmp_path / "m.png")
    with pytest.raises(InputError) as err:
        read_mask(tmp_path / "m.png", (100, 200))
    msg = str(err.value)
    assert "120\u00d7100" in msg and "200\u00d7100" in msg and "\n" not in msg
    with pytest.raises(InputError, match="no such file"):
        read_mask(tmp_path / "none.png", (10, 10))
    with pytest.raises(InputError, match="shape"):
        read_mask(tmp_path / "m.png", (0, 5))


# ---------------------------------------------------------------- write_png
def test_write_png_round_trips(tmp_path):
    rgb, rgba = _noise(16, 24), _noise(16, 24, 4)
    for arr in (rgb, rgba, rgb[..., 0], rgb[..., :1]):
        out = np.asarray(Image.open(write_png(arr, tmp_path / "x.png")))
        np.testing.assert_array_equal(out, arr[..., 0] if arr.shape[-1:] == (1,) else arr)
    b = np.eye(16, dtype=bool)
    assert np.asarray(Image.open(write_png(b, tmp_path / "b.png"))).max() == 255
    u16 = (np.arange(16 * 16, dtype=np.uint16) * 250).reshape(16, 16)
    np.testing.assert_array_equal(np.asarray(Image.open(write_png(u16, tmp_path / "u.png"))), u16)
    f = np.linspace(0, 1, 256).reshape(16, 16)
    assert np.asarray(Image.open(write_png(f, tmp_path / "f.png"))).max() == 255
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.png", "f.png", "u.png", "x.png"]


def test_write_png_errors(tmp_path):
    with pytest.raises(InputError, match="shape"):
        write_png(np.zeros((4, 4, 2), np.uint8), tmp_path / "x.png")
    with pytest.raises(InputError, match=r"\[0, 1\]"):
        write_png(np.full((4, 4), 2.0), tmp_path / "x.png")
    with pytest.raises(InputError, match="dtype|expected"):
        write_png(np.zeros((4, 4), np.int64), tmp_path / "x.png")
    with pytest.raises(OutputError, match="does not exist"):
        write_png(np.zeros((4, 4), np.uint8), tmp_path / "sub" / "x.png")
    (tmp_path / "d.png").mkdir()
    with pytest.raises(OutputError, match="directory"):
        write_png(np.zeros((4, 4), np.uint8), tmp_path / "d.png")
    assert [p.name for p in tmp_path.iterdir()] == ["d.png"]


def test_phone_formats_read_like_a_png(tmp_path):
    """HEIC (a phone camera's default) and AVIF photos read as the same photo; a HEIC cut-out keeps its alpha."""
    import pillow_heif

    from treeform.batch import list_photos
    from treeform.io.images import read_cutout

    yy, xx = np.mgrid[:120, :90]
    img = np.stack([xx * 2.5, yy * 2, 255 - xx * 2], -1).astype(np.uint8)
    img[30:90, 20:60] = (40, 150, 50)
    Image.fromarray(img).save(tmp_path / "ref.png")
    pillow_heif.from_pillow(Image.fromarray(img)).save(tmp_path / "IMG_0001.HEIC", quality=95)
    Image.fromarray(img).save(tmp_path / "IMG_0002.avif", quality=95)
    ref = read_photo(tmp_path / "ref.png").image.astype(int)
    for name in ("IMG_0001.HEIC", "IMG_0002.avif"):
        got = read_photo(tmp_path / name).image.astype(int)
        assert got.shape == ref.shape, name
        assert np.abs(got - ref).mean() < 4, name  # lossy, but the same picture
    assert [p.name for p in list_photos(tmp_path)] == ["IMG_0001.HEIC", "IMG_0002.avif", "ref.png"]
    rgba = np.zeros((120, 90, 4), np.uint8)
    rgba[..., :3] = img
    rgba[20:100, 15:75, 3] = 255
    rgba[20:60, 40:50, 3] = 0  # a gap in the crown
    pillow_heif.from_pillow(Image.fromarray(rgba)).save(tmp_path / "cut.heic", quality=95)
    alpha, _ = read_cutout(tmp_path / "cut.heic", (120, 90))
    assert ((alpha >= 0.5) == (rgba[..., 3] > 0)).mean() > 0.99
    (tmp_path / "fake.heic").write_bytes(b"\x00\x00\x00\x18ftypheic" + b"\x00" * 64)
    _raises_one_line(tmp_path / "fake.heic", "fake.heic")
