"""``treeform leaflets`` from the command line."""

from __future__ import annotations

from cli_helpers import assert_clean_failure, cli


def test_leaflets_command(tmp_path):
    out = tmp_path / "leaf"
    run = cli("leaflets", "--shape", "cone", "--out", out, "--size", "64", "--attractors", "120")
    assert run.returncode == 0, run.stderr
    assert (out / "channels.png").exists() and (out / "ao.png").exists()
    bad = tmp_path / "bad"
    assert_clean_failure(cli("leaflets", "--shape", "cube", "--out", bad), bad)
    assert_clean_failure(cli("leaflets", "--leaflet", tmp_path / "missing.png", "--out", bad), bad)
