"""Running the installed ``treeform`` command in tests (tests/cli is on sys.path under pytest)."""

import os
import subprocess
import sys
from pathlib import Path

EXE = Path(sys.executable).parent / "treeform"


def cli(*args, timeout=240):
    """Run ``treeform ARGS...`` as a separate process (the installed script, else ``python -m treeform``)."""
    cmd = [str(EXE)] if EXE.exists() else [sys.executable, "-m", "treeform"]
    return subprocess.run(cmd + [str(a) for a in args], capture_output=True, text=True, timeout=timeout,
                          env={**os.environ, "COLUMNS": "140"})


def assert_clean_failure(proc, out: Path | None = None, *, only_error: bool = False):
    """Non-zero exit, no traceback, exactly one ``error:`` line, and no files in ``out``.

    ``only_error``: stderr holds nothing but that line (commands without a progress bar).
    """
    assert proc.returncode != 0, proc.stdout + proc.stderr
    assert "Traceback" not in proc.stderr and "Traceback" not in proc.stdout
    lines = [l for l in proc.stderr.splitlines() if l.startswith("error:")]
    assert len(lines) == 1, proc.stderr
    if only_error:
        assert [l for l in proc.stderr.splitlines() if l.strip()] == lines, proc.stderr
    if out is not None:
        assert not out.exists() or not any(out.iterdir()), list(out.iterdir())
