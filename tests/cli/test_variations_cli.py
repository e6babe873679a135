"""`treeform library process`, `vary`, `morph`, `billboard`: happy paths and bad inputs
(one `error:` line, non-zero exit, no partial files)."""

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from typer.testing import CliRunner

from treeform.cli.app import app
from treeform.io import read_photo
from treeform.methods.variations import season_reference
from treeform.methods.variations.season import mean_hue

ROOT = Path(__file__).resolve().parents[2]
BILLBOARDS = ROOT.parent / "shared" / "data" / "billboards"
SAMPLE = ROOT / "src" / "treeform" / "data" / "Celtis_occidentalis_1.jpg"
PICK = ["cesium_tree_billboard.png", "savanna-trees_row3_col0.png", "coniferous_row3_col0.png",
        "tropical-alt_row3_col6.png"]


@pytest.fixture(scope="module")
def lib(tmp_path_factory):
    if not BILLBOARDS.is_dir():
        pytest.skip("../shared/data/billboards is not available")
    d = tmp_path_factory.mktemp("lib")
    for name in PICK:
        (d / name).symlink_to(BILLBOARDS / name)
    return d


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("cache")


def run(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


def assert_clean_failure(res, out: Path | None = None):
    assert res.exit_code != 0, res.stdout + res.stderr
    assert res.exception is None or isinstance(res.exception, SystemExit), repr(res.exception)
    assert "Traceback" not in res.stderr + res.stdout
    lines = [ln for ln in res.stderr.splitlines() if ln.startswith("error:")]
    assert len(lines) == 1, res.stderr
    if out is not None:
        assert not out.exists() or (out.is_dir() and not any(out.iterdir()))


def test_help_lists_the_verbs():
    res = run("--help")
    assert res.exit_code == 0
    for verb in ("library", "vary", "morph", "billboard"):
        assert verb in res.stdout


def test_library_process(lib, cache, tmp_path):
    res = run("library", "process", lib, "--cache", cache, "--sheet", tmp_path / "sheet.png")
    assert res.exit_code == 0, res.stderr
    assert "4 exemplars" in res.stdout and (tmp_path / "sheet.png").is_file()
    assert len(list(cache.glob("*.npz"))) == 4
    again = run("library", "process", lib, "--cache", cache)
    assert "4 from the cache" in again.stdout


def test_vary_happy_paths(lib, cache, tmp_path, photos_dir):
    out = tmp_path / "vars"
    res = run("vary", lib, "-n", 3, "--out", out, "--seed", 2, "--cache", cache)
    assert res.exit_code == 0, res.stderr
    names = sorted(p.name for p in out.iterdir())
    assert names == ["config.json", "contact_sheet.png", "variation_000.png", "variation_001.png",
                     "variation_002.png"]
    with Image.open(out / "variation_000.png") as im:
        assert im.mode == "RGBA" and im.size == (1024, 1024)
    # variations of the (green, broadleaf) cesium tree in the colours of a yellow autumn
    # mulberry: only broadleaf partners without --any-form; yellow crowns, not cyan
    ref = photos_dir / "Morus_rubra_1.jpg"
    photo_hue = mean_hue(season_reference(read_photo(ref).image).crown)[0]
    hues = {}
    for name, extra in (("from", ()), ("any", ("--any-form",))):
        res = run("vary", lib, "-n", 2, "--out", tmp_path / name, "--from", lib / PICK[0], "--season", ref,
                  "--cache", cache, *extra)
        assert res.exit_code == 0, res.stderr
        meta = json.loads((tmp_path / name / "config.json").read_text())
        assert meta["config"]["any_form"] == bool(extra) and meta["season_trunk"] is False
        hues[name] = []
        for rec in meta["variations"]:
            with Image.open(tmp_path / name / rec["file"]) as im:
                a = np.asarray(im)
            hues[name].append(mean_hue(a[a[..., 3] >= 128][:, :3])[0])
    assert all(r["forms"] == ["broadleaf", "broadleaf"] and r["exemplars"][1] == PICK[1]
               for r in json.loads((tmp_path / "from" / "config.json").read_text())["variations"])
    # (the cesium tree's own crown is at 127 deg, the mulberry's at 89)
    assert all(abs(h - photo_hue) < 6 for h in hues["from"] + hues["any"]), (photo_hue, hues)


def test_morph_and_billboard(lib, cache, tmp_path):
    res = run("morph", lib / PICK[0], lib / PICK[1], "--steps", 3, "-o", tmp_path / "strip.png", "--cache", cache)
    assert res.exit_code == 0, res.stderr
    with Image.open(tmp_path / "strip.png") as im:
        assert im.size[0] > 2.5 * im.size[1]
    small = tmp_path / "small.jpg"
    with Image.open(SAMPLE) as im:
        im.resize((120, 160)).save(small)
    res = run("billboard", small, "-o", tmp_path / "tree.png")
    assert res.exit_code == 0, res.stderr
    with Image.open(tmp_path / "tree.png") as im:
        assert im.mode == "RGBA"


def test_bad_inputs(lib, cache, tmp_path):
    out = tmp_path / "out"
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "tree.png").write_text("not an image")
    rgb = tmp_path / "rgb"
    rgb.mkdir()
    Image.new("RGB", (40, 40), (20, 160, 20)).save(rgb / "a.png")
    one = tmp_path / "one"
    one.mkdir()
    (one / PICK[0]).symlink_to(BILLBOARDS / PICK[0])
    (tmp_path / "empty").mkdir()
    afile = tmp_path / "afile.txt"
    afile.write_text("x")
    cases = [
        ("library", "process", tmp_path / "missing", "--cache", cache),
        ("library", "process", tmp_path / "empty", "--cache", cache),
        ("vary", bad, "-n", 2, "--out", out, "--cache", cache),
        ("vary", rgb, "-n", 2, "--out", out, "--cache", cache),
        ("vary", one, "-n", 2, "--out", out, "--cache", cache),
        ("vary", lib, "-n", 0, "--out", out, "--cache", cache),
        ("vary", lib, "-n", 2, "--out", afile, "--cache", cache),
        ("vary", lib, "-n", 2, "--out", out, "--season", afile, "--cache", cache),
        ("vary", lib, "-n", 2, "--out", out, "--from", rgb / "a.png", "--cache", cache),
        ("morph", lib / PICK[0], tmp_path / "nope.png", "-o", out / "s.png", "--cache", cache),
        ("morph", lib / PICK[0], lib / PICK[1], "--steps", 1, "-o", tmp_path / "s.png", "--cache", cache),
        ("billboard", afile, "-o", tmp_path / "t.png"),
        ("billboard", SAMPLE, "-o", tmp_path / "t.jpg"),
        ("billboard", SAMPLE, "-o", afile / "t.png"),  # the parent is a file
    ]
    for args in cases:
        res = run(*args)
        assert_clean_failure(res, out)
    assert not (tmp_path / "s.png").exists() and not (tmp_path / "t.png").exists()
    assert not (tmp_path / "t.jpg").exists()
