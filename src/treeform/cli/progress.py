"""Progress displays driven by the library's callbacks: a rich bar in a terminal, plain lines elsewhere.

When stderr is a terminal each display draws a live rich bar. When it is a file, a pipe or a
CI log (or ``TERM=dumb``) it prints plain lines instead: one at the start, one every few
seconds (``TREEFORM_PROGRESS_INTERVAL``, default 5 s), one at the end, e.g.::

    samples 120/10000  2.70/s  elapsed 0:00:44  ETA 1:01:00

so a long run is never silent in a log. While a display is open, the ``treeform`` logger's
INFO and WARNING records (e.g. "first run: compiling the matting kernels ...") are printed
through it (above the bar), prefixed ``note:`` / ``warning:``. On an error the live bar is
erased when the display closes, so that the CLI's ``error:`` line comes last, on its own line.
"""

from __future__ import annotations

import logging
import os
import threading
import time
from collections import deque

from rich.console import Console
from rich.progress import BarColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn
from rich.table import Table

from treeform.methods.envelope.pipeline import STAGES

_err = Console(stderr=True)
_out = Console()

DEFAULT_INTERVAL = 5.0
"""Seconds between plain progress lines (``TREEFORM_PROGRESS_INTERVAL`` overrides)."""


def plain_output() -> bool:
    """True when progress goes to a file or pipe (or a dumb terminal): plain lines, no live bar."""
    return not _err.is_terminal or _err.is_dumb_terminal


def _interval() -> float:
    try:
        return max(0.05, float(os.environ.get("TREEFORM_PROGRESS_INTERVAL", DEFAULT_INTERVAL)))
    except ValueError:
        return DEFAULT_INTERVAL


def _clock(seconds: float) -> str:
    """``h:mm:ss``."""
    s = int(round(max(0.0, seconds)))
    return f"{s // 3600}:{s % 3600 // 60:02d}:{s % 60:02d}"


class _NoticeHandler(logging.Handler):
    """Logging records of the ``treeform`` logger -> lines of the open display."""

    def __init__(self, display):
        super().__init__(logging.INFO)
        self.display = display

    def emit(self, record):
        try:
            prefix = "warning: " if record.levelno >= logging.WARNING else "note: "
            self.display.line(prefix + record.getMessage())
        except Exception:  # pragma: no cover - logging must never break a run
            self.handleError(record)


class _Display:
    """Shared machinery: rich bar or plain lines, a ticker for the plain lines, notices, clean exit.

    Subclasses build ``self.progress`` (rich) in :meth:`_make_progress` and say what a plain
    line reads in :meth:`_status`.
    """

    def __init__(self):
        self.plain = False
        self.progress = None
        self.task = None
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self._ticker = None
        self._handler = None
        self._level = None
        self._t0 = 0.0
        self._last_line = 0.0

    # -- to override --------------------------------------------------------------------------
    def _make_progress(self) -> Progress:
        raise NotImplementedError

    def _add_task(self):
        raise NotImplementedError

    def _status(self) -> str | None:
        """The plain progress line now (None: nothing to say yet)."""
        raise NotImplementedError

    def _final(self) -> str | None:
        """The plain line printed when the display closes without an error."""
        return self._status()

    # -- common -------------------------------------------------------------------------------
    def __enter__(self):
        self.plain = plain_output()
        self._t0 = time.perf_counter()
        self._last_line = self._t0
        if self.plain:
            self._stop.clear()
            self._ticker = threading.Thread(target=self._tick, name="treeform-progress", daemon=True)
            self._ticker.start()
        else:
            self.progress = self._make_progress()
            self.progress.__enter__()
            self.task = self._add_task()
        logger = logging.getLogger("treeform")
        self._handler = _NoticeHandler(self)
        self._level = logger.level
        if logger.getEffectiveLevel() > logging.INFO:
            logger.setLevel(logging.INFO)
        logger.addHandler(self._handler)
        return self

    def __exit__(self, exc_type, exc, tb):
        logger = logging.getLogger("treeform")
        logger.removeHandler(self._handler)
        logger.setLevel(self._level)
        if self.plain:
            self._stop.set()
            self._ticker.join()
            if exc_type is None:
                final = self._final()
                if final:
                    self._print(final)
            return False
        if exc_type is not None:
            self.progress.live.transient = True  # erase the unfinished bar: the error line comes next
        self.progress.__exit__(exc_type, exc, tb)
        return False

    def _print(self, text: str) -> None:
        with self._lock:
            if self.plain or self.progress is None:
                _err.file.write(text + "\n")
                _err.file.flush()
            else:
                self.progress.console.print(text, highlight=False, markup=False)
            self._last_line = time.perf_counter()

    def line(self, text: str) -> None:
        """Print one line: above the bar in a terminal, as it is otherwise."""
        self._print(text)

    def _maybe_status(self, force: bool = False) -> None:
        """Plain mode: print the status line if ``force`` or an interval has passed since the last line."""
        if not self.plain:
            return
        with self._lock:
            if force or time.perf_counter() - self._last_line >= _interval():
                status = self._status()
                if status:
                    self._print(status)

    def _tick(self) -> None:
        while not self._stop.wait(min(1.0, _interval() / 4)):
            self._maybe_status()


class _Rate:
    """Items per second over the last minute of ``(time, done)`` updates (robust to a resumed start)."""

    def __init__(self, window: float = 60.0):
        self.window = window
        self.points: deque = deque()

    def add(self, done: float) -> None:
        now = time.perf_counter()
        self.points.append((now, done))
        while len(self.points) > 2 and now - self.points[0][0] > self.window:
            self.points.popleft()

    def per_second(self) -> float | None:
        if len(self.points) < 2:
            return None
        (t0, d0), (t1, d1) = self.points[0], self.points[-1]
        return (d1 - d0) / (t1 - t0) if t1 > t0 and d1 > d0 else None


class StageProgress(_Display):
    """A progress bar over the pipeline stages, with each finished stage's time.

    Plain output: the same per-stage time lines, and while a stage runs longer than the
    interval, ``  <stage>  running 0:00:15 (stage 4/5)`` lines.
    """

    def __init__(self, stages=STAGES):
        super().__init__()
        self.stages = stages
        self._stage = None
        self._stage_t0 = 0.0
        self._done = 0

    def _make_progress(self):
        return Progress(SpinnerColumn(), TextColumn("[bold]{task.description}"), BarColumn(),
                        TextColumn("{task.completed}/{task.total}"), TimeElapsedColumn(),
                        console=_err, transient=False)

    def _add_task(self):
        return self.progress.add_task("starting", total=len(self.stages))

    def _status(self):
        if self._stage is None:
            return None
        return (f"  {self._stage:<11} running {_clock(time.perf_counter() - self._stage_t0)} "
                f"(stage {min(self._done + 1, len(self.stages))}/{len(self.stages)})")

    def _final(self):
        return None

    def callback(self, stage: str, event: str, seconds: float) -> None:
        with self._lock:
            if event == "start":
                self._stage, self._stage_t0 = stage, time.perf_counter()
                if not self.plain:
                    self.progress.update(self.task, description=stage)
            else:
                self._stage = None
                self._done += 1
                if not self.plain:
                    self.progress.advance(self.task)
                self._print(f"  {stage:<11} {seconds:6.2f} s")


class _Counted(_Display):
    """A display of ``done`` out of ``total`` items: plain lines at the first update, every
    interval, at ``done == total`` and, if it was not printed yet, the last state on close."""

    def __init__(self, label: str):
        super().__init__()
        self.label = label
        self.done = None
        self.total = None
        self._rate = _Rate()
        self._printed = None

    def _middle(self) -> str:
        """What a plain line shows between ``label done/total`` and ``elapsed``."""
        raise NotImplementedError

    def _status(self):
        elapsed = _clock(time.perf_counter() - self._t0)
        if self.done is None:
            return f"{self.label} starting  elapsed {elapsed}"
        r = self._rate.per_second()
        eta = _clock((self.total - self.done) / r) if r and self.total else "-"
        self._printed = self.done
        return (f"{self.label} {self.done}/{self.total if self.total is not None else '?'}  {self._middle()}  "
                f"elapsed {elapsed}  ETA {eta}")

    def _final(self):
        return None if self.done is None or self.done == self._printed else self._status()

    def _update(self, done, total) -> bool:
        """Record an update; in plain mode print it when due. Returns whether a bar should be updated."""
        first = self.done is None
        self.done, self.total = done, total
        self._rate.add(done)
        if self.plain:
            self._maybe_status(force=first or (total is not None and done >= total))
            return False
        return True


class CountProgress(_Counted):
    """A progress bar over counted items (``callback(done, total)``), with the rate and time left.

    Plain output: ``samples 120/10000  2.70/s  elapsed 0:00:44  ETA 1:01:00``.
    """

    def __init__(self, label: str = "samples"):
        super().__init__(label)

    def _make_progress(self):
        from rich.progress import MofNCompleteColumn, TimeRemainingColumn

        return Progress(SpinnerColumn(), TextColumn(f"[bold]{self.label}"), BarColumn(), MofNCompleteColumn(),
                        TextColumn("{task.fields[rate]}"), TimeElapsedColumn(), TimeRemainingColumn(),
                        console=_err, transient=False)

    def _add_task(self):
        return self.progress.add_task(self.label, total=None, rate="")

    def _rate_text(self) -> str:
        r = self._rate.per_second()
        return f"{r:.2f}/s" if r else ""

    def _middle(self):
        return self._rate_text() or "-/s"

    def callback(self, done: int, total: int) -> None:
        with self._lock:
            if self._update(done, total):
                self.progress.update(self.task, completed=done, total=total, rate=self._rate_text())


def print_summary(res) -> None:
    """One table of the key metrics and the written files."""
    m = res.metrics
    t = Table(show_header=False, box=None)
    t.add_row("reprojection error", f"{100 * m['reprojection_error']:.1f} %")
    t.add_row("IoU", f"{m['iou']:.3f}")
    t.add_row("depth / width", f"{m['depth_width_ratio']:.2f}")
    if "form" in m:  # the envelope route's growth form (--form; auto: from the silhouette)
        t.add_row("growth form", m["form"] + (" (one leader, needles)" if m["form"] == "conifer" else ""))
    if "species_probabilities" in m:
        t.add_row("species", f"{m['species']} (predicted {m['species_predicted']}, "
                             f"p = {m['species_probabilities'][m['species_predicted']]:.2f})")
    t.add_row("nodes / leaves / triangles", f"{m['nodes']} / {m['leaves']} / {m['triangles']}")
    if "crown_width_m" in m:  # treeform.metrics' definitions, as `treeform metrics` reports them
        t.add_row("height / crown", f"{m['tree_height_m']:.1f} m tall, crown {m['crown_extent_x_m']:.1f} x "
                                    f"{m['crown_extent_z_m']:.1f} m (width {m['crown_width_m']:.1f} m)")
    t.add_row("total", f"{m['total_seconds']:.2f} s")
    for name, path in sorted(res.files.items()):
        t.add_row(name, str(path))
    _out.print(t)


def print_scene_summary(res) -> None:
    """One table of the trees found in a photo, where each stands, and the written files."""
    t = Table(show_header=False, box=None)
    for row in res.metrics["trees"]:
        x, _, z = row["position_m"]
        state = row["error"] if row["error"] else f"{row['height_m']:.1f} m tall at x {x:+.1f} m, z {z:+.1f} m"
        t.add_row(f"tree {row['tree']}", state)
    t.add_row("camera", f"{res.placement.camera_height:.2f} m above the ground")
    for name, path in sorted(res.files.items()):
        t.add_row(name, str(path))
    _out.print(t)


class TrainProgress(_Counted):
    """A progress bar over training steps with the running loss, images/s and time left.

    Plain output: ``seg 120/3200  loss 0.345  85.2 img/s  elapsed 0:01:10  ETA 0:30:00``.
    """

    def __init__(self, label: str = "train"):
        super().__init__(label)
        self.info: dict = {}

    def _make_progress(self):
        from rich.progress import MofNCompleteColumn, TimeRemainingColumn

        return Progress(SpinnerColumn(), TextColumn(f"[bold]{self.label}"), BarColumn(), MofNCompleteColumn(),
                        TextColumn("loss {task.fields[loss]}  {task.fields[rate]} img/s"),
                        TimeElapsedColumn(), TimeRemainingColumn(), console=_err, transient=False)

    def _add_task(self):
        return self.progress.add_task(self.label, total=None, loss="-", rate="-")

    def _middle(self):
        return (f"loss {self.info.get('loss', float('nan')):.3f}  "
                f"{self.info.get('images_per_s', 0.0):.1f} img/s")

    def callback(self, done: int, total: int, info: dict | None = None) -> None:
        with self._lock:
            self.info = dict(info or {})
            if self._update(done, total):
                self.progress.update(self.task, completed=done, total=total,
                                     loss=f"{self.info.get('loss', float('nan')):.3f}",
                                     rate=f"{self.info.get('images_per_s', 0.0):.1f}")
