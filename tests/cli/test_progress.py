"""Progress displays: plain lines when stderr is a file or pipe, notices from logging, clean exits."""

from __future__ import annotations

import logging
import re
import time

import pytest

from treeform.cli import progress as pg

CLOCK = r"\d+:\d\d:\d\d"


@pytest.fixture
def fast(monkeypatch):
    monkeypatch.setenv("TREEFORM_PROGRESS_INTERVAL", "0.1")


def _lines(capsys) -> list[str]:
    return [l for l in capsys.readouterr().err.splitlines() if l.strip()]


def test_plain_count_lines_with_rate_and_eta(capsys, fast):
    assert pg.plain_output()  # pytest captures stderr: not a terminal
    with pg.CountProgress("samples") as p:
        p.callback(181, 1000)  # a resumed run starts at 181: the rate must not count those
        for done in range(182, 192):
            time.sleep(0.02)
            p.callback(done, 1000)
        time.sleep(0.15)
        p.callback(192, 1000)
    lines = _lines(capsys)
    assert lines[0].startswith("samples 181/1000  -/s  elapsed 0:00:00  ETA -")
    m = re.fullmatch(rf"samples 192/1000  ([\d.]+)/s  elapsed ({CLOCK})  ETA ({CLOCK})", lines[-1])
    assert m, lines
    rate = float(m.group(1))
    assert 10 < rate < 60  # 11 samples in ~0.35 s, not 192 in 0.35 s
    h, mi, s = map(int, m.group(3).split(":"))
    assert abs((h * 3600 + mi * 60 + s) - 808 / rate) <= 1


def test_plain_lines_are_spaced_by_the_interval(capsys, monkeypatch):
    monkeypatch.setenv("TREEFORM_PROGRESS_INTERVAL", "0.25")
    with pg.CountProgress("samples") as p:
        t0 = time.perf_counter()
        done = 0
        while time.perf_counter() - t0 < 0.6:
            done += 1
            p.callback(done, 10_000)
            time.sleep(0.005)
    lines = _lines(capsys)
    assert 2 <= len(lines) <= 4, lines  # the first update, then one per 0.25 s: not one per update
    assert all(l.startswith("samples ") for l in lines)


def test_plain_count_says_it_is_starting_before_the_first_update(capsys, fast):
    with pg.CountProgress("samples"):
        time.sleep(0.3)
    assert any(re.fullmatch(rf"samples starting  elapsed {CLOCK}", l) for l in _lines(capsys))


def test_plain_stage_lines_and_heartbeat(capsys, fast):
    with pg.StageProgress(("load", "matting")) as p:
        p.callback("load", "start", 0.0)
        p.callback("load", "end", 0.01)
        p.callback("matting", "start", 0.0)
        time.sleep(0.35)
        p.callback("matting", "end", 0.35)
    lines = _lines(capsys)
    assert lines[0] == "  load          0.01 s"
    assert any(re.fullmatch(rf"  matting     running {CLOCK} \(stage 2/2\)", l) for l in lines[1:-1]), lines
    assert lines[-1] == "  matting       0.35 s"


def test_plain_train_line(capsys, fast):
    with pg.TrainProgress("seg") as p:
        p.callback(1, 100, {"loss": 1.5, "images_per_s": 80.0})
        time.sleep(0.05)
        p.callback(100, 100, {"loss": 0.25, "images_per_s": 85.0})
    lines = _lines(capsys)
    assert lines[0].startswith("seg 1/100  loss 1.500  80.0 img/s  elapsed")
    assert re.fullmatch(rf"seg 100/100  loss 0\.250  85\.0 img/s  elapsed {CLOCK}  ETA 0:00:00", lines[-1])


def test_library_notices_show_while_the_display_is_open(capsys, fast):
    log = logging.getLogger("treeform.segment.matting")
    root = logging.getLogger("treeform")
    handlers = list(root.handlers)
    with pg.StageProgress(("matting",)) as p:
        p.callback("matting", "start", 0.0)
        log.info("first run: compiling the matting kernels")
        logging.getLogger("treeform.dataset.generate").warning("sample 3 failed twice")
        log.debug("not shown")
        p.callback("matting", "end", 1.0)
    assert _lines(capsys) == ["note: first run: compiling the matting kernels", "warning: sample 3 failed twice",
                              "  matting       1.00 s"]
    assert root.handlers == handlers  # the display's handler is gone once it is closed
    log.info("after the display: not printed")
    assert "after" not in capsys.readouterr().err


def test_an_error_leaves_no_final_progress_line(capsys, fast):
    """After an error the display prints nothing more: the CLI's error line comes last."""
    with pytest.raises(RuntimeError):
        with pg.CountProgress("samples") as p:
            p.callback(1, 10)
            p.callback(2, 10)  # within the interval: not printed, and not printed on the way out
            raise RuntimeError("boom")
    lines = _lines(capsys)
    assert len(lines) == 1 and lines[0].startswith("samples 1/10  ")


def test_terminal_bar_is_erased_on_an_error(monkeypatch):
    import io

    from rich.console import Console

    buf = io.StringIO()
    monkeypatch.setattr(pg, "_err", Console(file=buf, force_terminal=True, width=60, color_system=None))
    assert not pg.plain_output()
    with pytest.raises(RuntimeError):
        with pg.StageProgress(("load", "segment")) as p:
            p.callback("load", "start", 0.0)
            p.callback("load", "end", 0.5)
            p.callback("segment", "start", 0.0)
            raise RuntimeError("boom")
    out = buf.getvalue()
    assert "  load          0.50 s" in out
    tail = out[out.rindex("load          0.50 s"):]
    assert tail.endswith("\x1b[2K")  # the bar's line is cleared: the next line (the error) starts clean
