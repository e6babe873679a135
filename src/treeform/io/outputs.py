"""Output folders written all-or-nothing: check first, stage, then rename into place."""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path
from typing import Callable, Iterable

from treeform._shared.errors import OutputError


def _make_parents(directory: Path, what: str) -> None:
    """Create ``directory`` and its missing parents (``mkdir -p``) below a writable ancestor.

    Raises :class:`OutputError` (one line) when the nearest existing ancestor is a file or
    is not writable, or the folders cannot be made.
    """
    if directory.is_dir():
        return
    anc = directory
    while not anc.exists() and anc != anc.parent:
        anc = anc.parent
    if not anc.is_dir():
        raise OutputError(f"{what}: {anc} exists and is not a directory")
    if not os.access(anc, os.W_OK | os.X_OK):
        raise OutputError(f"{what}: directory {anc} is not writable")
    try:
        directory.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise OutputError(f"{what}: cannot create {directory} ({exc.strerror or exc})") from None


def check_out_dir(out, what: str = "--out") -> Path:
    """Fail early, with one line, if ``out`` cannot become an output folder.

    ``out`` may exist (a folder) or not; its missing parent folders are created (as
    ``mkdir -p`` would) when the nearest existing one is writable. ``out`` itself appears
    only when the outputs are written. ``what`` names the option in the error line.

    Examples
    --------
    >>> import tempfile
    >>> check_out_dir(Path(tempfile.gettempdir()) / "new-treeform-folder").name
    'new-treeform-folder'
    """
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise OutputError(f"{what} {out}: exists and is not a directory")
    if out.exists():
        if not os.access(out, os.W_OK | os.X_OK):
            raise OutputError(f"{what} {out}: directory is not writable")
        return out
    _make_parents(out.parent, f"{what} {out}")
    return out


def check_out_file(path, what: str = "-o", *, suffix: str | None = ".png") -> Path:
    """Fail early, with one line, if ``path`` cannot be written as an output file.

    Missing parent folders are created (as ``mkdir -p`` would). Raises
    :class:`OutputError` for a directory or an unwritable parent, and :class:`InputError`
    for a wrong file extension (``suffix``; None accepts any).
    """
    from treeform._shared.errors import InputError

    path = Path(path)
    if path.is_dir():
        raise OutputError(f"{what} {path}: is a directory")
    if suffix is not None and path.suffix.lower() != suffix:
        raise InputError(f"{what} {path}: expected a {suffix} file name")
    _make_parents(path.parent, f"{what} {path}")
    if not os.access(path.parent, os.W_OK | os.X_OK):
        raise OutputError(f"{what} {path}: directory is not writable")
    return path


def write_json(path, data) -> Path:
    """Write indented, key-sorted JSON atomically (temporary name, then rename)."""
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=1, sort_keys=True))
    os.replace(tmp, path)
    return path


class StagedOutputs:
    """An output folder written all-or-nothing by writers that may start before the last output exists.

    Each ``writer(staging_dir)`` runs in a thread as soon as it is submitted (PNG, zlib and
    file writing release the GIL), so a method can start writing its mesh while it still
    renders the preview. :meth:`commit` waits for every writer and moves the files into
    ``out_dir``; :meth:`abort` (also on leaving a ``with`` block without a commit, e.g. on
    an error) waits for the running writers and removes the staging folder: no output file
    appears. Writers must make distinct files and not share mutable state. Inside, each
    texture array is PNG-encoded once (:func:`treeform.io.images.shared_textures`).

    Parameters
    ----------
    out_dir : path
        The output folder (it may exist); the staging folder is made beside it, on the same
        file system, so the moves are renames.

    Examples
    --------
    >>> import tempfile
    >>> out = Path(tempfile.mkdtemp()) / "run"
    >>> with StagedOutputs(out) as staged:
    ...     _ = staged.submit(lambda d: (d / "a.txt").write_text("a"))
    ...     # ... more work while a.txt is written ...
    ...     files = staged.commit()
    >>> sorted(files), sorted(p.name for p in out.iterdir())
    (['a.txt'], ['a.txt'])
    """

    def __init__(self, out_dir):
        from contextlib import ExitStack

        from treeform.io.images import shared_textures

        self.out_dir = Path(out_dir)
        parent = self.out_dir if self.out_dir.exists() else self.out_dir.parent
        try:
            self._stage = Path(tempfile.mkdtemp(prefix=".treeform-", dir=parent))
        except OSError as exc:
            raise OutputError(f"--out {self.out_dir}: cannot write ({exc.strerror})") from None
        self._futures = []
        self._pool = None
        self._done = False
        self._stack = ExitStack()
        self._stack.enter_context(shared_textures())

    @property
    def staging_dir(self) -> Path:
        """The staging folder: a caller may write whole sub-folders into it from its own thread (e.g. the
        folders of several runs of a method, each all-or-nothing itself); they move with the commit."""
        return self._stage

    def submit(self, *writers: Callable[[Path], object]) -> "StagedOutputs":
        """Start ``writer(staging_dir)`` for each writer (in a background thread)."""
        if self._done:
            raise RuntimeError("StagedOutputs: already committed or aborted")
        if self._pool is None:
            from concurrent.futures import ThreadPoolExecutor

            self._pool = ThreadPoolExecutor(max_workers=min(4, os.cpu_count() or 1),
                                            thread_name_prefix="treeform-write")
        self._futures += [self._pool.submit(w, self._stage) for w in writers]
        return self

    def commit(self) -> dict:
        """Wait for every writer, then move the files into ``out_dir``.

        Returns
        -------
        dict
            File name -> final path.

        Raises
        ------
        OutputError
            One line naming ``out_dir`` when anything cannot be written (the first
            failure in submission order); nothing is left behind.
        """
        if self._done:
            raise RuntimeError("StagedOutputs: already committed or aborted")
        try:
            for fut in self._futures:
                fut.result()  # the first failure, in writer order
            try:
                self.out_dir.mkdir(exist_ok=True)
            except OSError as exc:
                raise OutputError(f"--out {self.out_dir}: cannot create ({exc.strerror})") from None
            files = {}
            for f in sorted(self._stage.iterdir()):
                dest = self.out_dir / f.name
                if f.is_dir() and dest.is_dir():  # a sub-folder written again: the new one replaces the old
                    old = Path(tempfile.mkdtemp(prefix=f".{f.name}-old-", dir=self.out_dir))
                    os.replace(dest, old / f.name)
                    os.replace(f, dest)
                    shutil.rmtree(old, ignore_errors=True)
                else:
                    os.replace(f, dest)
                files[f.name] = dest
            return files
        except OSError as exc:
            raise OutputError(f"--out {self.out_dir}: write failed ({exc.strerror or exc})") from None
        finally:
            self.abort()  # the pool and the staging folder go, whatever happened

    def abort(self) -> None:
        """Stop: cancel the writers not yet started, wait for the running ones, remove the staging folder."""
        if self._done:
            return
        self._done = True
        try:
            if self._pool is not None:
                self._pool.shutdown(wait=True, cancel_futures=True)
        finally:
            shutil.rmtree(self._stage, ignore_errors=True)
            self._stack.close()

    def __enter__(self) -> "StagedOutputs":
        return self

    def __exit__(self, *exc) -> None:
        self.abort()


def write_staged(out_dir, writers: Iterable[Callable[[Path], object]]) -> dict:
    """Run ``writer(staging_dir)`` for each writer, then move every file made into ``out_dir``.

    :class:`StagedOutputs` with every writer submitted at once: they run concurrently
    (threads), so they must make distinct files and not share mutable state; on failure no
    output file appears. Returns the file name -> path dict of :meth:`StagedOutputs.commit`
    and raises its one-line :class:`OutputError`.
    """
    with StagedOutputs(out_dir) as staged:
        return staged.submit(*writers).commit()


def start_tree_outputs(out_dir, *, mesh, skeleton) -> StagedOutputs:
    """Start writing a tree's mesh and skeleton outputs (tree.glb, tree.obj + .mtl and
    textures, skeleton.json, skeleton.ply) into a :class:`StagedOutputs` of ``out_dir``.

    A method calls it as soon as its mesh exists and goes on (rendering its preview) while
    the files are written; :func:`write_tree_outputs` with ``staged=`` adds the rest and
    commits. Every texture is encoded once, the biggest first; the GLB and the OBJ share the
    bytes. ``mesh`` and ``skeleton`` must not change until the commit.
    """
    from treeform.io.gltf import write_glb
    from treeform.io.images import texture_png
    from treeform.io.obj import write_obj
    from treeform.io.ply import write_skeleton_ply

    textures = {}
    for part in mesh.parts:
        for tex in (part.material.texture, part.material.normal_texture):
            if tex is not None:
                textures[id(tex)] = tex
    staged = StagedOutputs(out_dir)
    try:
        return staged.submit(
            *[lambda d, t=t: texture_png(t) for t in sorted(textures.values(), key=lambda t: -t.size)],
            lambda d: write_glb(mesh, d / "tree.glb"),
            lambda d: write_obj(mesh, d / "tree.obj"),
            lambda d: skeleton.save(d / "skeleton.json"),
            lambda d: write_skeleton_ply(skeleton, d / "skeleton.ply"),
        )
    except BaseException:
        staged.abort()
        raise


def write_tree_outputs(out_dir, *, mesh, skeleton, preview, config: dict, metrics: dict, extra=(),
                       staged: StagedOutputs | None = None) -> dict:
    """Write a tree's standard outputs all-or-nothing.

    tree.glb, tree.obj (+ .mtl and textures), skeleton.json, skeleton.ply, preview.png,
    config.json and metrics.json, plus any ``extra`` writers (``writer(staging_dir)``).
    With ``staged`` (from :func:`start_tree_outputs` of the same mesh and skeleton) the mesh
    files are already being written: only the rest is added before the commit.
    """
    from treeform.io.images import write_png

    if staged is None:
        staged = start_tree_outputs(out_dir, mesh=mesh, skeleton=skeleton)
    with staged:
        staged.submit(
            lambda d: write_png(preview, d / "preview.png"),
            lambda d: write_json(d / "config.json", config),
            lambda d: write_json(d / "metrics.json", metrics),
            *extra,
        )
        return staged.commit()
