"""`treeform cloud`: a photo through the billboard path to a GLB + sidecar + strip, `--report`,
and bad inputs (one `error:` line, non-zero exit, no partial files)."""

import re
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import assert_clean_failure, cli
from PIL import Image

SAMPLE = Path(__file__).resolve().parents[2] / "src" / "treeform" / "data" / "Celtis_occidentalis_1.jpg"
OAK = SAMPLE.parent / "library" / "oak_1.png"  # an RGBA picture: no segmentation, a few seconds


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


def test_report_beside_the_cloud_leaves_the_cloud_as_it_was(tmp_path, gl):
    import base64

    plain, rep = tmp_path / "plain", tmp_path / "rep"
    args = ("--views", "v.png", "--segments", "64", "--seed", "1")
    runs = [cli("cloud", OAK, "-o", d / "oak.glb", *(d / a if a == "v.png" else a for a in args), *extra)
            for d, extra in ((plain, ()), (rep, ("--report",)))]
    for proc in runs:
        assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in plain.iterdir()) == ["oak.glb", "oak.json", "v.png"]
    assert sorted(p.name for p in rep.iterdir()) == ["oak.glb", "oak.json", "oak_report", "v.png"]
    for name in ("oak.glb", "oak.json", "v.png"):  # --report adds a folder and changes nothing else
        assert (rep / name).read_bytes() == (plain / name).read_bytes(), name
    assert "report:" not in runs[0].stdout
    assert runs[1].stdout.splitlines()[-1] == f"report: {rep / 'oak_report' / 'report.html'}"
    d = rep / "oak_report"
    page = (d / "report.html").read_text()
    cells = dict(re.findall(r"data-key='([^']+)'>([^<]*)<", page))
    stdout = runs[1].stdout
    assert cells["billboards"] == stdout.split(": ", 1)[1].split()[0]  # "<out>: N billboards ..."
    for key, label in (("psnr", "PSNR "), ("ssim", "SSIM "), ("iou", "IoU ")):
        printed = stdout.split(label)[1].split()[0].rstrip(",")
        assert abs(float(cells[key]) - float(printed)) <= 10.0 ** -len(printed.split(".")[1]), key  # 4 digits vs 1-3
    assert "id='timings'" in page and "views: picture | front | 30° | 60° | 90°" in page
    assert '"src": "oak.glb.js", "label": "oak.glb"' in page and "assets/viewer.js" in page
    js = (d / "oak.glb.js").read_text()
    assert base64.b64decode(js.split('"')[-2]) == (rep / "oak.glb").read_bytes()
    for i in range(3):  # input, alpha | crown/trunk, views
        assert f"report_{i}.png" in page and (d / f"report_{i}.png").stat().st_size > 1000
    assert not [p.name for p in tmp_path.rglob(".*")]  # no staging folder left


def test_report_that_cannot_be_written_fails_before_anything(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "oak_report").write_text("a file, not a folder")
    proc = cli("cloud", OAK, "-o", out / "oak.glb", "--report")
    assert_clean_failure(proc)
    assert "--report" in proc.stderr and "not a directory" in proc.stderr
    assert [p.name for p in out.iterdir()] == ["oak_report"]
