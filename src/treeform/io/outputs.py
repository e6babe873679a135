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


def write_staged(out_dir, writers: Iterable[Callable[[Path], object]]) -> dict:
    """Run ``writer(staging_dir)`` for each writer, then move every file made into ``out_dir``.

    Writers must make distinct files and not share mutable state: on a multi-core machine
    they run concurrently (threads). The staging folder sits beside ``out_dir`` (same file system, so the moves are
    renames) and is removed in any case: on failure no output file appears.

    Returns
    -------
    dict
        File name -> final path.

    Raises
    ------
    OutputError
        One line naming ``out_dir`` when anything cannot be written.
    """
    out_dir = Path(out_dir)
    parent = out_dir if out_dir.exists() else out_dir.parent
    try:
        stage = Path(tempfile.mkdtemp(prefix=".treeform-", dir=parent))
    except OSError as exc:
        raise OutputError(f"--out {out_dir}: cannot write ({exc.strerror})") from None
    try:
        writers = list(writers)
        if len(writers) > 1 and (os.cpu_count() or 1) > 1:
            # the writers make distinct files; PNG and zlib encoding release the GIL, so the
            # big textures (OBJ leaf atlas, GLB images, preview) encode side by side
            from concurrent.futures import ThreadPoolExecutor

            with ThreadPoolExecutor(max_workers=min(4, os.cpu_count() or 1)) as pool:
                for fut in [pool.submit(w, stage) for w in writers]:
                    fut.result()  # the first failure, in writer order
        else:
            for writer in writers:
                writer(stage)
        try:
            out_dir.mkdir(exist_ok=True)
        except OSError as exc:
            raise OutputError(f"--out {out_dir}: cannot create ({exc.strerror})") from None
        files = {}
        for f in sorted(stage.iterdir()):
            os.replace(f, out_dir / f.name)
            files[f.name] = out_dir / f.name
        return files
    except OSError as exc:
        raise OutputError(f"--out {out_dir}: write failed ({exc.strerror or exc})") from None
    finally:
        shutil.rmtree(stage, ignore_errors=True)


def write_tree_outputs(out_dir, *, mesh, skeleton, preview, config: dict, metrics: dict, extra=()) -> dict:
    """Write a tree's standard outputs all-or-nothing.

    tree.glb, tree.obj (+ .mtl and textures), skeleton.json, skeleton.ply, preview.png,
    config.json and metrics.json, plus any ``extra`` writers (``writer(staging_dir)``), via
    :func:`write_staged`.
    """
    from treeform.io.gltf import write_glb
    from treeform.io.images import shared_textures, texture_png, write_png
    from treeform.io.obj import write_obj
    from treeform.io.ply import write_skeleton_ply

    # every texture encoded once, the biggest first and side by side; GLB and OBJ share the bytes
    textures = {}
    for part in mesh.parts:
        for tex in (part.material.texture, part.material.normal_texture):
            if tex is not None:
                textures[id(tex)] = tex
    encode = [lambda d, t=t: texture_png(t) for t in sorted(textures.values(), key=lambda t: -t.size)]
    with shared_textures():
        return write_staged(out_dir, [
            *encode,
            lambda d: write_glb(mesh, d / "tree.glb"),
            lambda d: write_obj(mesh, d / "tree.obj"),
            lambda d: skeleton.save(d / "skeleton.json"),
            lambda d: write_skeleton_ply(skeleton, d / "skeleton.ply"),
            lambda d: write_png(preview, d / "preview.png"),
            lambda d: write_json(d / "config.json", config),
            lambda d: write_json(d / "metrics.json", metrics),
            *extra,
        ])
