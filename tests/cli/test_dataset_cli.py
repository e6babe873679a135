"""``treeform dataset generate`` / ``show`` from the command line: happy path and clean failures."""

from __future__ import annotations

from cli_helpers import assert_clean_failure, cli


def test_generate_and_show(tmp_path):
    out = tmp_path / "ds"
    run = cli("dataset", "generate", "-n", "3", "-o", out, "--size", "48", "--species", "oak,pine", "--workers", "1")
    assert run.returncode == 0, run.stderr
    assert "3 samples in 1 new shard(s)" in run.stdout and (out / "shard-00000.tar").exists()
    show = cli("dataset", "show", out, "--n", "3")
    assert show.returncode == 0, show.stderr
    assert (out / "contact_sheet.png").exists()


def test_bad_arguments_fail_cleanly(tmp_path):
    out = tmp_path / "ds"
    assert_clean_failure(cli("dataset", "generate", "-n", "2", "-o", out, "--species", "palm"), out)
    assert_clean_failure(cli("dataset", "generate", "-n", "2", "-o", out, "--workers", "2", "--scheduler",
                             "tcp://127.0.0.1:1"), out)
    assert_clean_failure(cli("dataset", "generate", "-n", "0", "-o", out), out)
    assert_clean_failure(cli("dataset", "generate", "-n", "2", "-o", out, "--scheduler", "127.0.0.1:1"), out)
    assert_clean_failure(cli("dataset", "generate", "-n", "2", "-o", out, "--backgrounds", tmp_path / "nope"), out)
    unreachable = cli("dataset", "generate", "-n", "2", "-o", out, "--scheduler", "tcp://127.0.0.1:9")
    assert_clean_failure(unreachable)
    assert "cannot connect" in unreachable.stderr
    assert_clean_failure(cli("dataset", "show", tmp_path))

