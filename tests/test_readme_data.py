"""The README's data chain (``dataset``, ``multiview``, ``eval``, ``batch``, ``train``), run as tests/test_readme.py
runs the other commands: in order, in an empty folder, each command its own test."""

from __future__ import annotations

import pytest
from test_readme import ReadmeChain, chain_ids, readme_chain

DATA = readme_chain(data=True)


@pytest.fixture(scope="module")
def data_chain(tmp_path_factory):
    return ReadmeChain(tmp_path_factory.mktemp("readme_data"))


def test_the_chain_makes_data_and_uses_it():
    verbs = {a[0] for a in DATA}
    assert {"dataset", "multiview", "eval", "batch"} <= verbs, verbs


@pytest.mark.parametrize("argv", DATA, ids=chain_ids(DATA))
def test_readme_data_command_runs_in_an_empty_folder(data_chain, argv):
    data_chain.run(argv)


def test_readme_data_chain_wrote_its_results(data_chain):
    for f in ("out/dataset/manifest.json", "out/dataset/contact_sheet.png", "out/multiview/tree.glb",
              "out/batch/summary.html"):
        assert (data_chain.work / f).stat().st_size > 0, f
