"""Every command the README shows runs, in order, in an empty folder with no ``../shared``.

The README is the first thing a new user follows: its commands are parsed from it (not
copied here), run one after another in a fresh folder (so each input a command needs
must come from the sample set or an earlier command), and each must exit 0. Training runs
with a couple of steps (the commands are the README's; only their length is cut) and only
where the ``train`` extra is installed.

The commands form two chains, each in its own folder and file, so that the two workers of
``make test`` run them side by side: the data chain (``dataset``, ``multiview``, ``eval``,
``batch``, ``train``: this file's :data:`DATA_VERBS`) in ``tests/test_readme_data.py``, every
other command here. Both start with ``sample-data``. Each command is its own test (a failure
names the command; the commands after a failed one in its chain are skipped), so pytest-xdist,
which hands out a file's tests together and the files with the most tests first, starts the
two long chains first instead of last.
"""

from __future__ import annotations

import importlib.util
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PREFIX = ".venv/bin/treeform"
# shorter runs of the slow commands: appended options override the README's values
SHORTER = {("train", "seg"): ["--steps", "2", "--batch", "2", "--chunk", "2", "--test-scenes", "8"], ("train", "species"): ["--epochs", "1"],
           ("train", "rbv"): ["--epochs", "1"]}
# the abs search at 4 candidates instead of the README's 24 (same stages, a sixth of the models rendered)
SHORTER_METHOD = {"abs": ["--candidates", "4"]}
# the multi-view mattes at 320 px instead of 512 (the same stages; about 0.75x the run's time)
SHORTER_VERB = {"multiview": ["--mask-size", "320"]}
# the verbs of the data chain (tests/test_readme_data.py); the others run here
DATA_VERBS = {"dataset", "multiview", "eval", "batch", "train"}
HAS_TORCH = importlib.util.find_spec("torch") is not None


def shorter(argv: list[str]) -> list[str]:
    """``argv`` with the options that cut a slow README command's run (appended: the last value wins)."""
    extra = list(SHORTER.get(tuple(argv[:2]), [])) + SHORTER_VERB.get(argv[0] if argv else "", [])
    if "--method" in argv[:-1]:
        extra += SHORTER_METHOD.get(argv[argv.index("--method") + 1], [])
    return argv + extra


def readme_commands() -> list[list[str]]:
    """The ``treeform`` command lines of the README's bash blocks, in order, as argv lists."""
    text = (ROOT / "README.md").read_text()
    cmds = []
    for block in re.findall(r"```bash\n(.*?)```", text, flags=re.S):
        for line in block.splitlines():
            line = line.strip()
            if line.startswith(PREFIX + " ") or line == PREFIX:
                cmds.append(shlex.split(line, comments=True)[1:])
    return cmds


def readme_chain(data: bool) -> list[list[str]]:
    """The shortened commands of one chain in README order: the data chain or the other, each after ``sample-data``.

    ``train`` commands are left out where torch is missing (tests/learn/test_train.py covers them where present).
    """
    every = readme_commands()
    first = [a for a in every if a[:1] == ["sample-data"]][:1]
    return first + [shorter(a) for a in every if a[:1] != ["sample-data"]
                    and (a[:1] != ["train"] or HAS_TORCH) and (a[:1] and a[0] in DATA_VERBS) == data]


def chain_ids(cmds: list[list[str]]) -> list[str]:
    """Test ids: the command's place in its chain and its verb (with the sub-verb of the two-word verbs)."""
    return [f"{i:02d}-" + "-".join(a[:2] if a[:1] in (["train"], ["dataset"], ["library"]) else a[:1])
            for i, a in enumerate(cmds)]


class ReadmeChain:
    """Runs a chain's commands one after another in one empty folder (``work``), with its own cache."""

    def __init__(self, tmp: Path):
        self.env = {**os.environ, "TREEFORM_CACHE_DIR": str(tmp / "cache"), "COLUMNS": "120"}
        self.work = tmp / "work"
        self.work.mkdir()
        assert not (self.work / ".." / "shared").exists()
        self.failed: str | None = None

    def run(self, argv: list[str]) -> None:
        if self.failed is not None:
            pytest.skip(f"after the failed README command `treeform {self.failed}`")
        self.failed = shlex.join(argv)
        proc = subprocess.run([sys.executable, "-m", "treeform", *argv], cwd=self.work, env=self.env,
                              capture_output=True, text=True, timeout=600)
        assert proc.returncode == 0, f"treeform {shlex.join(argv)} -> {proc.returncode}\n{proc.stderr[-2000:]}"
        assert "Traceback" not in proc.stderr, proc.stderr
        self.failed = None


MAIN = readme_chain(data=False)


def test_readme_commands_are_self_contained():
    cmds = readme_commands()
    assert len(cmds) >= 25
    for argv in cmds:
        assert not any("../shared" in a or a.startswith("~") or "[" in a for a in argv), argv
    # every command is in exactly one chain, sample-data (once in the README) opening both
    assert len(MAIN) + len(readme_chain(data=True)) - 1 == len(cmds) - sum(
        a[:1] == ["train"] for a in cmds if not HAS_TORCH)
    assert len(MAIN) >= 25


def test_readme_shows_every_verb():
    import typer.main

    from treeform.cli.app import app

    group = typer.main.get_command(app)
    verbs = set(group.commands)
    shown = {argv[0] for argv in readme_commands() if argv and not argv[0].startswith("-")}
    assert verbs - shown == set(), f"verbs without a README example: {sorted(verbs - shown)}"


@pytest.fixture(scope="module")
def main_chain(tmp_path_factory):
    return ReadmeChain(tmp_path_factory.mktemp("readme"))


@pytest.mark.parametrize("argv", MAIN, ids=chain_ids(MAIN))
def test_readme_command_runs_in_an_empty_folder(main_chain, argv):
    main_chain.run(argv)


def test_readme_chain_wrote_its_results(main_chain):
    for f in ("out/mytree/tree.glb", "out/oak_rbv/tree.glb", "out/autumn/contact_sheet.png", "out/cloud.glb"):
        assert (main_chain.work / f).stat().st_size > 0, f
