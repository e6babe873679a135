"""``treeform dataset generate`` / ``show`` from the command line: happy path and clean failures."""

from __future__ import annotations

import re

from cli_helpers import assert_clean_failure, cli


def test_generate_and_show(tmp_path, monkeypatch):
    monkeypatch.setenv("TREEFORM_PROGRESS_INTERVAL", "0.5")
    out = tmp_path / "ds"
    run = cli("dataset", "generate", "-n", "3", "-o", out, "--size", "48", "--species", "oak,pine", "--workers", "1")
    assert run.returncode == 0, run.stderr
    assert "3 samples in 1 new shard(s)" in run.stdout and (out / "shard-00000.tar").exists()
    # piped stderr: plain progress lines (no live bar), from the start to the last sample
    lines = run.stderr.splitlines()
    assert any(re.fullmatch(r"samples 0/3  -/s  elapsed \d:\d\d:\d\d  ETA -", l) for l in lines[:3]), lines
    assert len(lines) >= 3  # start, at least one interval line while the cluster starts and works, end
    assert re.fullmatch(r"samples 3/3  [\d.]+/s  elapsed \d:\d\d:\d\d  ETA 0:00:00", lines[-1]), lines
    assert all(l.startswith("samples ") for l in lines) and "━" not in run.stderr
    show = cli("dataset", "show", out, "--n", "3")
    assert show.returncode == 0, show.stderr
    assert (out / "contact_sheet.png").exists()


def test_bad_arguments_fail_cleanly(tmp_path):
    out = tmp_path / "ds"
    # unknown species, -n 0, a missing --backgrounds ...: tests/cli/test_option_sweep.py
    assert_clean_failure(cli("dataset", "generate", "-n", "2", "-o", out, "--workers", "2", "--scheduler",
                             "tcp://127.0.0.1:1"), out)
    assert_clean_failure(cli("dataset", "generate", "-n", "2", "-o", out, "--scheduler", "127.0.0.1:1"), out)
    unreachable = cli("dataset", "generate", "-n", "2", "-o", out, "--scheduler", "tcp://127.0.0.1:9")
    assert_clean_failure(unreachable)
    assert "cannot connect" in unreachable.stderr
    assert_clean_failure(cli("dataset", "show", tmp_path))

