"""Rich progress display driven by the library's stage callbacks."""

from __future__ import annotations

from rich.console import Console
from rich.progress import BarColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn
from rich.table import Table

from treeform.methods.envelope.pipeline import STAGES

_err = Console(stderr=True)
_out = Console()


class StageProgress:
    """A progress bar over the pipeline stages, with each finished stage's time."""

    def __init__(self, stages=STAGES):
        self.stages = stages
        self.progress = Progress(SpinnerColumn(), TextColumn("[bold]{task.description}"), BarColumn(),
                                 TextColumn("{task.completed}/{task.total}"), TimeElapsedColumn(),
                                 console=_err, transient=False)
        self.task = None

    def __enter__(self):
        self.progress.__enter__()
        self.task = self.progress.add_task("starting", total=len(self.stages))
        return self

    def __exit__(self, *exc):
        return self.progress.__exit__(*exc)

    def callback(self, stage: str, event: str, seconds: float) -> None:
        if event == "start":
            self.progress.update(self.task, description=stage)
        else:
            self.progress.advance(self.task)
            self.progress.console.print(f"  {stage:<11} {seconds:6.2f} s", highlight=False)


class CountProgress:
    """A progress bar over counted items (``callback(done, total)``), with the rate and time left."""

    def __init__(self, label: str = "samples"):
        from rich.progress import MofNCompleteColumn, TimeRemainingColumn

        self.label = label
        self.progress = Progress(SpinnerColumn(), TextColumn(f"[bold]{label}"), BarColumn(), MofNCompleteColumn(),
                                 TextColumn("{task.fields[rate]}"), TimeElapsedColumn(), TimeRemainingColumn(),
                                 console=_err, transient=False)
        self.task = None
        self._start = None

    def __enter__(self):
        import time

        self.progress.__enter__()
        self.task = self.progress.add_task(self.label, total=None, rate="")
        self._start = time.perf_counter()
        return self

    def __exit__(self, *exc):
        return self.progress.__exit__(*exc)

    def callback(self, done: int, total: int) -> None:
        import time

        dt = time.perf_counter() - self._start
        self.progress.update(self.task, completed=done, total=total, rate=f"{done / dt:.2f}/s" if dt > 0 else "")


def print_summary(res) -> None:
    """One table of the key metrics and the written files."""
    m = res.metrics
    t = Table(show_header=False, box=None)
    t.add_row("reprojection error", f"{100 * m['reprojection_error']:.1f} %")
    t.add_row("IoU", f"{m['iou']:.3f}")
    t.add_row("depth / width", f"{m['depth_width_ratio']:.2f}")
    if "species_probabilities" in m:
        t.add_row("species", f"{m['species']} (predicted {m['species_predicted']}, "
                             f"p = {m['species_probabilities'][m['species_predicted']]:.2f})")
    t.add_row("nodes / leaves / triangles", f"{m['nodes']} / {m['leaves']} / {m['triangles']}")
    t.add_row("total", f"{m['total_seconds']:.2f} s")
    for name, path in sorted(res.files.items()):
        t.add_row(name, str(path))
    _out.print(t)


class TrainProgress:
    """A progress bar over training steps with the running loss, images/s and time left."""

    def __init__(self, label: str = "train"):
        from rich.progress import MofNCompleteColumn, TimeRemainingColumn

        self.label = label
        self.progress = Progress(SpinnerColumn(), TextColumn(f"[bold]{label}"), BarColumn(), MofNCompleteColumn(),
                                 TextColumn("loss {task.fields[loss]}  {task.fields[rate]} img/s"),
                                 TimeElapsedColumn(), TimeRemainingColumn(), console=_err, transient=False)
        self.task = None

    def __enter__(self):
        self.progress.__enter__()
        self.task = self.progress.add_task(self.label, total=None, loss="-", rate="-")
        return self

    def __exit__(self, *exc):
        return self.progress.__exit__(*exc)

    def callback(self, done: int, total: int, info: dict | None = None) -> None:
        info = info or {}
        self.progress.update(self.task, completed=done, total=total, loss=f"{info.get('loss', float('nan')):.3f}",
                             rate=f"{info.get('images_per_s', 0.0):.1f}")
