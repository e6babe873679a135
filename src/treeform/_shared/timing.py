"""Per-stage timing and progress reporting through a callback (only the CLI draws)."""

from __future__ import annotations

import time
from contextlib import contextmanager
from typing import Callable, Optional

ProgressCallback = Callable[[str, str, float], None]
"""``callback(stage, event, seconds)`` with event ``"start"`` or ``"end"``."""


class StageTimer:
    """Collects wall-clock seconds per named stage and forwards events to a callback.

    Examples
    --------
    >>> t = StageTimer()
    >>> with t.stage("load"):
    ...     pass
    >>> list(t.timings)
    ['load']
    """

    def __init__(self, callback: Optional[ProgressCallback] = None):
        self.timings: dict[str, float] = {}
        self.callback = callback

    @contextmanager
    def stage(self, name: str):
        if self.callback:
            self.callback(name, "start", 0.0)
        t0 = time.perf_counter()
        try:
            yield
        finally:
            dt = time.perf_counter() - t0
            self.timings[name] = self.timings.get(name, 0.0) + dt
            if self.callback:
                self.callback(name, "end", dt)
