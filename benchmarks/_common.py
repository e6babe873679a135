"""Helpers shared by the benchmark scripts (medians, machine description)."""

from __future__ import annotations

import os
import platform
import statistics
import time
from pathlib import Path


def median_time(fn, repeat: int):
    """Median wall-clock seconds of ``fn()`` over ``repeat`` runs, and all the times."""
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), times


def machine() -> str:
    """CPU model, core count and Python version of this machine."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores, Python {platform.python_version()}"


def write_section(path, name: str, text: str) -> None:
    """Put ``text`` into the markdown file ``path`` between ``<!-- name:begin -->`` and ``<!-- name:end -->``.

    The section is replaced where it exists, appended the first time.
    """
    path = Path(path)
    begin, end = f"<!-- {name}:begin -->", f"<!-- {name}:end -->"
    body = f"{begin}\n{text.rstrip()}\n{end}"
    md = path.read_text() if path.exists() else "# Benchmarks\n"
    i, j = md.find(begin), md.find(end)
    if i >= 0 and j > i:
        md = md[:i] + body + md[j + len(end):]
    else:
        md = md.rstrip("\n") + "\n\n" + body + "\n"
    path.write_text(md)
