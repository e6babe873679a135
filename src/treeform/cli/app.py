"""``treeform`` command: thin handlers over the Python API."""

from __future__ import annotations

import sys
from enum import Enum
from pathlib import Path
from typing import Optional

import typer

from treeform import __version__
from treeform._shared.errors import TreeformError

app = typer.Typer(add_completion=False, no_args_is_help=True, pretty_exceptions_enable=False,
                  help="treeform: photographs of real trees -> 3D tree assets.")


class Crown(str, Enum):
    round = "round"
    conical = "conical"


class Lod(str, Enum):
    low = "low"
    medium = "medium"
    high = "high"
    full = "full"


def _version(value: bool):
    if value:
        typer.echo(f"treeform {__version__}")
        raise typer.Exit()


@app.callback()
def _main(version: bool = typer.Option(False, "--version", callback=_version, is_eager=True,
                                       help="Print the version and exit.")):
    """treeform: photographs of real trees -> 3D tree assets."""


def run_api(func, *args, stages=None, display=None, **kwargs):
    """Run an API call with a rich progress display; TreeformError -> one line, non-zero exit.

    ``func`` must accept ``progress=callback(stage, event, seconds)``; ``stages`` names its
    stages (for the bar's total; default: the single-photo pipeline's). ``display`` replaces
    the stage bar by another context manager with a ``callback`` (e.g. a
    :class:`~treeform.cli.progress.CountProgress` for ``progress(done, total)``).
    """
    from treeform.cli.progress import StageProgress

    if display is None:
        display = StageProgress(stages) if stages else StageProgress()
    try:
        with display as prog:
            return func(*args, progress=prog.callback, **kwargs)
    except TreeformError as exc:
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(exc.exit_code)
    except MemoryError:
        typer.echo("error: out of memory (try a smaller --lod or photo)", err=True)
        raise typer.Exit(1)


@app.command()
def reconstruct(
    photo: Path = typer.Argument(..., help="Photo of a tree (JPEG, PNG, ...)."),
    mask: Optional[Path] = typer.Option(None, "--mask", help="Tree mask image, white = tree (skips segmentation)."),
    out: Path = typer.Option(Path("out"), "--out", "-o", help="Output directory."),
    seed: int = typer.Option(0, "--seed", help="Random seed."),
    crown: Crown = typer.Option(Crown.round, "--crown", help="Crown envelope shape."),
    leaves: int = typer.Option(8000, "--leaves", help="Number of leaf clusters."),
    lod: Lod = typer.Option(Lod.medium, "--lod", help="Level of detail (triangle budget)."),
    height: float = typer.Option(10.0, "--height", help="Tree height in metres."),
):
    """Single photo -> 3D tree (crown envelope + radial distance map + space colonization)."""
    from treeform.cli.progress import print_summary
    from treeform.methods.envelope.pipeline import reconstruct as api

    res = run_api(api, photo, mask=mask, out=out, seed=seed, crown=crown.value, leaves=leaves, lod=lod.value,
               tree_height=height)
    print_summary(res)


@app.command()
def demo(out: Path = typer.Option(Path("out/demo"), "--out", "-o", help="Output directory.")):
    """Reconstruct the bundled sample photo (Celtis occidentalis, public domain) into OUT."""
    from importlib.resources import files

    from treeform.cli.progress import print_summary
    from treeform.methods.envelope.pipeline import reconstruct as api

    sample = Path(str(files("treeform") / "data" / "Celtis_occidentalis_1.jpg"))
    out.parent.mkdir(parents=True, exist_ok=True)
    res = run_api(api, sample, out=out)
    print_summary(res)


def _register_commands() -> None:
    """Import every ``treeform/cli/cmd_*.py``; each adds its verbs with ``@app.command()``."""
    import importlib
    import pkgutil

    import treeform.cli as pkg

    for m in sorted(pkgutil.iter_modules(pkg.__path__), key=lambda m: m.name):
        if m.name.startswith("cmd_"):
            importlib.import_module(f"treeform.cli.{m.name}")


_register_commands()


def main():
    try:
        app()
    except KeyboardInterrupt:
        typer.echo("interrupted", err=True)
        sys.exit(130)


if __name__ == "__main__":
    main()
