"""Every command the README shows runs, in order, in an empty folder with no ``../shared``.

The README is the first thing a new user follows: its commands are parsed from it (not
copied here), run one after another in a fresh folder (so each input a command needs
must come from the sample set or an earlier command), and each must exit 0. Training runs
with a couple of steps (the commands are the README's; only their length is cut) and only
where the ``train`` extra is installed.
"""

from __future__ import annotations

import importlib.util
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path


ROOT = Path(__file__).resolve().parents[1]
PREFIX = ".venv/bin/treeform"
# shorter runs of the slow commands: appended options override the README's values
SHORTER = {("train", "seg"): ["--steps", "2", "--batch", "2", "--chunk", "2", "--test-scenes", "8"], ("train", "species"): ["--epochs", "1"],
           ("train", "rbv"): ["--epochs", "1"]}
# the abs search at 4 candidates instead of the README's 24 (same stages, a sixth of the models rendered)
SHORTER_METHOD = {"abs": ["--candidates", "4"]}


def shorter(argv: list[str]) -> list[str]:
    """``argv`` with the options that cut a slow README command's run (appended: the last value wins)."""
    extra = list(SHORTER.get(tuple(argv[:2]), []))
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


def test_readme_commands_are_self_contained():
    cmds = readme_commands()
    assert len(cmds) >= 25
    for argv in cmds:
        assert not any("../shared" in a or a.startswith("~") or "[" in a for a in argv), argv


def test_readme_shows_every_verb():
    import typer.main

    from treeform.cli.app import app

    group = typer.main.get_command(app)
    verbs = set(group.commands)
    shown = {argv[0] for argv in readme_commands() if argv and not argv[0].startswith("-")}
    assert verbs - shown == set(), f"verbs without a README example: {sorted(verbs - shown)}"


def test_every_readme_command_runs_in_an_empty_folder(tmp_path):
    has_torch = importlib.util.find_spec("torch") is not None
    env = {**os.environ, "TREEFORM_CACHE_DIR": str(tmp_path / "cache"), "COLUMNS": "120"}
    work = tmp_path / "work"
    work.mkdir()
    assert not (work / ".." / "shared").exists()
    ran = 0
    for argv in readme_commands():
        if argv[:1] == ["train"] and not has_torch:
            continue  # needs the train extra (torch); tests/learn/test_train.py covers it where present
        argv = shorter(argv)
        proc = subprocess.run([sys.executable, "-m", "treeform", *argv], cwd=work, env=env, capture_output=True,
                              text=True, timeout=600)
        assert proc.returncode == 0, f"treeform {shlex.join(argv)} -> {proc.returncode}\n{proc.stderr[-2000:]}"
        assert "Traceback" not in proc.stderr, proc.stderr
        ran += 1
    assert ran >= 25
    for f in ("out/mytree/tree.glb", "out/oak_rbv/tree.glb", "out/autumn/contact_sheet.png", "out/cloud.glb",
              "out/dataset/manifest.json"):
        assert (work / f).stat().st_size > 0, f
