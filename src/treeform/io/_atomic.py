"""Atomic file output: write to a temporary name beside the target, then ``os.replace``.

No writer in :mod:`treeform.io` ever leaves a partial output file behind: on any error the
temporary files are removed and the previous file (if any) is left untouched.
"""

from __future__ import annotations

import os
import tempfile
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator, Sequence

from treeform._shared.errors import OutputError

# mkstemp creates files with mode 0600; give outputs the usual 0666 & ~umask instead.
_UMASK = os.umask(0o022)
os.umask(_UMASK)
_FILE_MODE = 0o666 & ~_UMASK


def _output_error(path: Path, exc: OSError) -> OutputError:
    """One-line :class:`OutputError` for an ``OSError`` raised while writing ``path``."""
    parent = path.parent
    if isinstance(exc, FileNotFoundError) and not parent.is_dir():
        return OutputError(f"{path}: cannot write, directory {parent} does not exist")
    if isinstance(exc, IsADirectoryError) or path.is_dir():
        return OutputError(f"{path}: cannot write, it is a directory")
    if isinstance(exc, PermissionError):
        return OutputError(f"{path}: cannot write, permission denied")
    reason = exc.strerror or type(exc).__name__
    return OutputError(f"{path}: cannot write ({reason})")


@contextmanager
def atomic_paths(paths: Sequence[str | os.PathLike]) -> Iterator[list[Path]]:
    """Yield temporary paths for ``paths``; on success rename them onto ``paths`` in order.

    Parameters
    ----------
    paths : sequence of path-like
        Final output paths. They are renamed in the order given, so put the "main" file
        (the one that references the others, e.g. the ``.obj``) last.

    Yields
    ------
    list of Path
        One temporary path per output, in the same directory (so the rename is atomic).

    Raises
    ------
    OutputError
        The directory does not exist, is not writable, or the target is a directory.
    """
    finals = [Path(p) for p in paths]
    temps: list[Path] = []
    try:
        for p in finals:
            if p.is_dir():
                raise OutputError(f"{p}: cannot write, it is a directory")
            try:
                fd, name = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".tmp", dir=p.parent)
            except OSError as exc:
                raise _output_error(p, exc) from None
            os.close(fd)
            temps.append(Path(name))
            try:
                os.chmod(name, _FILE_MODE)
            except OSError:  # pragma: no cover - e.g. file systems without modes
                pass
        try:
            yield temps
        except OSError as exc:
            raise _output_error(finals[-1], exc) from None
        for tmp, final in zip(temps, finals):
            try:
                os.replace(tmp, final)
            except OSError as exc:
                raise _output_error(final, exc) from None
    finally:
        for tmp in temps:
            try:
                tmp.unlink()
            except FileNotFoundError:
                pass
            except OSError:  # pragma: no cover - best effort clean-up
                pass


@contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield one temporary path for ``path``; on success rename it onto ``path``.

    See :func:`atomic_paths`.
    """
    with atomic_paths([path]) as temps:
        yield temps[0]
