"""The treeform command: happy path and every bad input the issue lists (one-line error, exit != 0, no files)."""

import json
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


def test_leaf_texture_option(tmp_path):
    out = tmp_path / "p"
    proc = cli("reconstruct", SAMPLE, "--out", out, "--leaves", "1000", "--lod", "low", "--leaf-texture", "procedural")
    assert proc.returncode == 0, proc.stderr
    assert '"leaf_texture": "procedural"' in (out / "config.json").read_text()
    bad = cli("reconstruct", SAMPLE, "--out", tmp_path / "l", "--method", "learned", "--leaf-texture", "photo",
              "--depth-ratio", "0.8")
    assert_clean_failure(bad, tmp_path / "l")
    assert "--depth-ratio works with --method envelope" in bad.stderr  # --leaf-texture is learned's too


def test_envelope_options_of_the_paper(tmp_path):
    out = tmp_path / "k"
    proc = cli("reconstruct", SAMPLE, "--out", out, "--leaves", "1000", "--lod", "low", "--k", "4",
               "--profile", "thin-plate", "--rdm-rotations", "60,120", "--depth-ratio", "0.8", "--form", "conifer")
    assert proc.returncode == 0, proc.stderr
    cfg = json.loads((out / "config.json").read_text())["config"]
    assert cfg["tangent_k"] == 4 and cfg["profile"] == "thin-plate" and cfg["rdm_rotations"] == [60, 120]
    assert cfg["form"] == "conifer" and json.loads((out / "metrics.json").read_text())["form"] == "conifer"
    assert "growth form" in proc.stdout and "conifer (one leader" in proc.stdout
    assert cfg["depth_ratio"] == 0.8 and cfg["segment_length"] == 0.04
    bad = cli("reconstruct", SAMPLE, "--out", tmp_path / "b", "--rdm-rotations", "sixty")
    assert_clean_failure(bad, tmp_path / "b")
    both = cli("reconstruct", SAMPLE, "--out", tmp_path / "m", "--method", "learned", "--k", "3", "--profile",
               "rounded", "--form", "broadleaf")
    assert_clean_failure(both, tmp_path / "m")
    assert "--profile, --k, --form work with --method envelope" in both.stderr


def test_help_speaks_to_users():
    """Usage lines show PHOTO (not {PHOTO}), flags carry no <bool>, and no paper sections leak into help."""
    import re

    from typer.testing import CliRunner

    from treeform.cli.app import app
    import typer.main

    runner = CliRunner()
    group = typer.main.get_command(app)
    paths = [[]]
    for name, cmd in group.commands.items():
        subs = getattr(cmd, "commands", None)
        paths += [[name, s] for s in subs] if subs else [[name]]
    for path in paths:
        res = runner.invoke(app, [*path, "--help"], env={"COLUMNS": "200"})
        assert res.exit_code == 0, (path, res.output)
        text = res.output
        assert not re.search(r"\{[A-Za-z_]+\}", text), (path, text)
        assert "<bool>" not in text, (path, text)
        assert not re.search(r"seed 00\d|§|paper 00\d", text), (path, text)


def _sky(tmp_path) -> Path:
    return _write(tmp_path, "sky.png", BAD["sky.png"])


def test_error_is_the_last_line_after_the_progress(tmp_path):
    """Piped stderr: the stages' plain lines, then the error alone on the last line."""
    out = tmp_path / "out"
    proc = cli("reconstruct", _sky(tmp_path), "--out", out)
    assert_clean_failure(proc, out)
    lines = [l for l in proc.stderr.splitlines() if l.strip()]
    assert lines[-1].startswith("error: ") and "no tree" in lines[-1]
    assert any(l.startswith("  segment ") for l in lines[:-1])  # progress came first, on lines of its own
    assert "━" not in proc.stderr  # no bar drawn into a pipe


def _screen(raw: str) -> list[str]:
    """What a terminal shows after ``raw``: text, CR, LF, cursor up (ESC[nA), erase line (ESC[2K)."""
    import re

    rows, row, col = [[]], 0, 0
    for tok in re.findall(r"\x1b\[[0-9;?]*[A-Za-z]|\r|\n|[^\x1b\r\n]", raw):
        if tok == "\r":
            col = 0
        elif tok == "\n":
            row, col = row + 1, 0
            if row == len(rows):
                rows.append([])
        elif tok.startswith("\x1b["):
            if tok.endswith("A"):
                row = max(0, row - int(tok[2:-1] or 1))
            elif tok == "\x1b[2K":
                rows[row] = []
        else:
            line = rows[row]
            line.extend(" " * (col - len(line)))
            line[col:col + 1] = [tok]
            col += 1
    text = ["".join(r).rstrip() for r in rows]
    while text and not text[-1]:
        text.pop()
    return text


def test_error_in_a_terminal_comes_after_the_bar_is_gone(tmp_path):
    """In a terminal the live bar is erased before the error line: no half-drawn bar beside it."""
    import os
    import pty
    import subprocess

    from cli_helpers import EXE

    master, slave = pty.openpty()
    env = {k: v for k, v in os.environ.items() if k not in ("NO_COLOR", "TERM")}
    env.update(TERM="xterm", COLUMNS="100")
    proc = subprocess.Popen([str(EXE), "reconstruct", str(_sky(tmp_path)), "--out", str(tmp_path / "out")],
                            stdout=slave, stderr=slave, env=env)
    os.close(slave)
    raw = b""
    while True:
        try:
            chunk = os.read(master, 65536)
        except OSError:  # the child closed the terminal
            break
        if not chunk:
            break
        raw += chunk
    os.close(master)
    assert proc.wait(timeout=240) != 0
    screen = _screen(raw.decode("utf-8", "replace"))
    assert screen[-1].startswith("error: ") and "no tree" in screen[-1], screen
    assert not any("━" in l for l in screen), screen  # the bar was drawn (live) but is gone now
    assert "━".encode() in raw


@pytest.mark.parametrize("args, named", [
    (("morph", "a.png", "b.png", "--out", "{tmp}/strip.png"), "no such files: a.png, b.png"),
    (("grow", "--rbv", "v.npz", "--mask", "m.png", "--out", "{tmp}/g"), "no such files: --rbv v.npz, --mask m.png"),
    (("reconstruct", "p.jpg", "--mask", "m.png", "--out", "{tmp}/r"), "no such files: p.jpg, --mask m.png"),
    (("vary", "lib", "--from", "t.png", "--season", "s.jpg", "--out", "{tmp}/v"),
     "no such files: lib, --from t.png, --season s.jpg"),
    (("train", "seg", "--data", "d1", "--test-data", "d2", "--out", "{tmp}/t"),
     "no such files: --data d1, --test-data d2"),
])
def test_every_missing_input_is_named_at_once(tmp_path, monkeypatch, args, named):
    monkeypatch.chdir(tmp_path)
    proc = cli(*[a.format(tmp=tmp_path) for a in args])
    assert_clean_failure(proc, only_error=True)  # checked before any progress is shown
    assert proc.stderr.strip() == f"error: {named}"
    assert proc.returncode == 2 and not any(tmp_path.iterdir())


def test_one_missing_input_among_several(tmp_path):
    out = tmp_path / "strip.png"
    proc = cli("morph", SAMPLE, tmp_path / "b.png", "--out", out)
    assert_clean_failure(proc, only_error=True)
    assert proc.stderr.strip() == f"error: {tmp_path / 'b.png'}: no such file" and not out.exists()


def test_a_learned_tree_taller_than_any_tree_is_one_line(tmp_path):
    """An out-of-range value that only one method refuses (tests/cli/test_option_sweep.py sweeps every
    option of every command with its defaults)."""
    out = tmp_path / "out"
    out.mkdir()
    proc = cli("reconstruct", SAMPLE, "--method", "learned", "--height", "500", "--out", out, timeout=120)
    assert_clean_failure(proc, out)
