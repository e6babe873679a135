"""``treeform batch``: reconstruct every photo of a folder, one Dask task per photo.

Each photo runs ``treeform reconstruct`` in a child process of its Dask worker, watched by
the worker: past ``timeout`` seconds, or once the child's resident memory passes
``memory_limit``, the child is killed and the photo recorded as failed with that reason — the
worker and its other photos go on. A photo's outputs are written to ``NAME.partial/`` and
renamed to ``NAME/`` when complete, so a folder is never half a result. ``manifest.json``
holds every photo's state (done / failed, reason, seconds, key metrics), rewritten after each
photo: a rerun (after a kill too) skips the done photos and retries the failed ones.
``failures.json`` lists the failures with their one-line reasons; ``summary.html`` is a
contact sheet of the previews with their metrics.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

from treeform._shared.errors import InputError
from treeform.io.images import PHOTO_SUFFIXES

__all__ = ["PHOTO_SUFFIXES", "parse_memory", "free_space", "list_photos", "reconstruct_one", "run_batch"]

MANIFEST, FAILURES, SUMMARY = "manifest.json", "failures.json", "summary.html"
MIN_FREE = "500MB"
"""Default free space a batch keeps on its output disk (a tree's folder takes a few MB)."""
KEY_METRICS = ("reprojection_error", "iou", "front_ssim", "tree_height_m", "leaves", "triangles", "total_seconds")
"""The metrics.json figures the manifest and the contact sheet keep per photo."""
_UNITS = {"": 1, "B": 1, "KB": 10**3, "MB": 10**6, "GB": 10**9, "TB": 10**12, "KIB": 2**10, "MIB": 2**20,
          "GIB": 2**30, "TIB": 2**40}


def parse_memory(text, *, what: str = "memory limit") -> int:
    """Bytes from ``"4GB"``, ``"512MiB"``, ``"2e9"``; 0 or ``"none"`` for no limit.

    ``what`` names the option in the error message.

    Examples
    --------
    >>> parse_memory("4GB"), parse_memory("512MiB"), parse_memory("none")
    (4000000000, 536870912, 0)
    """
    s = str(text).strip().upper().replace(" ", "")
    if s in ("", "0", "NONE"):
        return 0
    num = s.rstrip("KMGTIB")
    unit = s[len(num):]
    try:
        value = float(num)
    except ValueError:
        value = -1.0
    if unit not in _UNITS or not value > 0:
        raise InputError(f"{what}: expected a size like 4GB or 512MiB (or none), got {text!r}")
    return int(value * _UNITS[unit])


def free_space(path) -> int:
    """Bytes free on the disk that holds ``path`` (or its nearest existing parent folder)."""
    p = Path(path).absolute()
    while not p.exists() and p != p.parent:
        p = p.parent
    return shutil.disk_usage(p).free


def _low_disk(folder, min_free: int) -> str | None:
    """What is wrong when ``folder``'s disk has under ``min_free`` bytes free, else None."""
    if not min_free:
        return None
    free = free_space(folder)
    if free >= min_free:
        return None
    return (f"{free / 1e6:.0f} MB free on the output disk, under the minimum of {min_free / 1e6:.0f} MB "
            "(free some space or lower --min-free, then rerun)")


def list_photos(input_dir) -> list[Path]:
    """The photos of a folder (by suffix, not recursive), sorted by name; InputError when there is none."""
    d = Path(input_dir)
    if not d.is_dir():
        raise InputError(f"{d}: not a folder")
    photos = sorted(p for p in d.iterdir() if p.is_file() and p.suffix.lower() in PHOTO_SUFFIXES)
    if not photos:
        raise InputError(f"{d}: no photos in it (looked for {', '.join(PHOTO_SUFFIXES)})")
    return photos


def _folder_names(photos: list[Path]) -> list[str]:
    """Each photo's output folder: its stem, or stem_ext where two photos share a stem."""
    stems = [p.stem for p in photos]
    return [p.stem if stems.count(p.stem) == 1 else f"{p.stem}_{p.suffix[1:].lower()}" for p in photos]


def _reason(stderr: str, returncode: int) -> str:
    """The child's own one-line error, else what ended it."""
    lines = [ln.strip() for ln in stderr.splitlines() if ln.strip()]
    err = [ln for ln in lines if ln.lower().startswith("error:")]
    if err:
        return err[-1][len("error:"):].strip()
    if returncode < 0:
        return f"killed by signal {-returncode}"
    return lines[-1][:300] if lines else f"exit status {returncode}"


def _rss(proc) -> int:
    """Resident memory of a process and its children, bytes (0 once it is gone)."""
    import psutil

    try:
        p = psutil.Process(proc.pid)
        return p.memory_info().rss + sum(c.memory_info().rss for c in p.children(recursive=True))
    except psutil.Error:
        return 0


def _kill_tree(proc) -> None:
    """Kill a process and every process it started, and reap it."""
    import psutil

    try:
        for c in psutil.Process(proc.pid).children(recursive=True):
            c.kill()
    except psutil.Error:
        pass
    proc.kill()
    proc.wait()


def _attempt(cmd: list, tmp: Path, deadline: float, timeout: float, memory_limit: int) -> tuple:
    """Run ``cmd`` once, killed at ``deadline`` (``time.perf_counter()``) or past ``memory_limit``
    bytes; returns ``(reason or None, returncode, killed_by_this_watch)``."""
    shutil.rmtree(tmp, ignore_errors=True)
    reason = None
    with subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                          env=dict(os.environ, TERM="dumb")) as proc:
        err: list = []
        reader = threading.Thread(target=lambda: err.append(proc.stderr.read()), daemon=True)
        reader.start()
        while proc.poll() is None:
            if time.perf_counter() > deadline:
                reason = f"timed out after {timeout:g} s"
            elif memory_limit and _rss(proc) > memory_limit:
                reason = f"out of memory: over the {memory_limit / 1e9:.3g} GB limit"
            if reason is not None:
                _kill_tree(proc)
                break
            time.sleep(0.05)
        reader.join(timeout=5)
    if reason is not None:
        return reason, proc.returncode, True
    if proc.returncode != 0:
        return _reason("".join(e for e in err if e), proc.returncode), proc.returncode, False
    if not (tmp / "metrics.json").is_file():
        return "the reconstruction wrote no metrics.json", proc.returncode, False
    return None, 0, False


def reconstruct_one(photo: str, folder: str, *, method: str = "envelope", seed: int = 0, timeout: float = 600.0,
                    memory_limit: int = 0, min_free: int = 0, options=()) -> dict:
    """Reconstruct one photo into ``folder`` in a child process, killed past ``timeout`` s or ``memory_limit`` bytes.

    With ``min_free`` > 0, a photo whose output disk has fewer bytes free is not started and
    is recorded as failed with that reason (a rerun retries it): a batch that fills its disk
    stops writing instead of leaving every later photo to fail on a half-written file.

    A child that crashes (ends by a signal it was not sent by this watch, e.g. a segmentation
    fault in a native library under load) is run once more before the photo is recorded as
    failed: one crash is the machine's, two are the photo's.

    Returns
    -------
    dict
        ``status`` ("done" or "failed"), ``seconds``, ``attempts``, and ``reason`` (failed)
        or ``metrics`` (done: :data:`KEY_METRICS` from the photo's metrics.json).
    """
    out, tmp = Path(folder), Path(str(folder) + ".partial")
    low = _low_disk(out.parent, min_free)
    if low is not None:
        return {"status": "failed", "reason": f"not run: {low}", "seconds": 0.0, "attempts": 0}
    cmd = [sys.executable, "-m", "treeform", "reconstruct", str(photo), "--out", str(tmp), "--method", method,
           "--seed", str(int(seed)), *map(str, options)]
    t0 = time.perf_counter()
    attempts = 0
    while True:
        attempts += 1
        reason, code, ours = _attempt(cmd, tmp, t0 + timeout, timeout, memory_limit)
        if reason is None or ours or code >= 0 or attempts == 2:
            break
    seconds = round(time.perf_counter() - t0, 3)
    if reason is not None:
        shutil.rmtree(tmp, ignore_errors=True)
        if attempts == 2:
            reason += " (twice)"
        return {"status": "failed", "reason": reason, "seconds": seconds, "attempts": attempts}
    shutil.rmtree(out, ignore_errors=True)
    tmp.rename(out)
    m = json.loads((out / "metrics.json").read_text())
    return {"status": "done", "seconds": seconds, "attempts": attempts,
            "metrics": {k: m[k] for k in KEY_METRICS if k in m}}


def _failures(manifest: dict) -> list:
    return [{"photo": e["photo"], "reason": e["reason"]} for e in manifest.values() if e.get("status") == "failed"]


def _write_json(path: Path, data) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=1))
    tmp.replace(path)


def run_batch(input_dir, out, *, method: str = "envelope", seed: int = 0, workers: int | None = None,
              scheduler: str | None = None, timeout: float = 600.0, memory_limit="4GB", min_free=MIN_FREE,
              options=(), progress=None) -> dict:
    """Reconstruct every photo of ``input_dir`` into ``out/NAME/``, one Dask task per photo.

    Parameters
    ----------
    input_dir : path
        Folder of photos (:data:`PHOTO_SUFFIXES`).
    out : path
        Output folder: a subfolder per photo with the method's outputs, ``manifest.json``,
        ``failures.json`` and ``summary.html``. A rerun skips the photos done and retries
        the failed ones.
    method : str
        A single-photo method of the registry (envelope, learned, abs).
    seed : int
    workers : int, optional
        LocalCluster worker processes (default: the machine's cores); 0 runs the photos one
        after the other from this process. Ignored with ``scheduler``.
    scheduler : str, optional
        Address of a running Dask scheduler (``tcp://HOST:PORT``); its workers need treeform.
    timeout : float
        Seconds a photo may take before it is killed and recorded as failed.
    memory_limit : str or int
        Resident memory a photo's process may use ("4GB"; 0 or "none": no limit).
    min_free : str or int
        Free space the output disk must keep ("500MB"; 0 or "none": no check). Below it the
        batch does not start (an InputError), and photos reached once the disk has filled are
        recorded as failed, not run, and retried by a rerun.
    options : sequence of str
        Further ``treeform reconstruct`` options, e.g. ``("--leaves", "4000")``.
    progress : callable, optional
        ``progress(done, total)`` after each photo.

    Returns
    -------
    dict
        ``total``, ``done``, ``failed``, ``skipped`` (done before this run), ``seconds``,
        ``photos_per_second`` and the ``manifest``.
    """
    from treeform.io.outputs import check_out_dir
    from treeform.methods import METHODS

    if method not in METHODS or method in ("variations",):
        known = ", ".join(k for k in METHODS if k != "variations")
        raise InputError(f"method: expected one of {known}, got {method!r}")
    from treeform._shared.checks import check_range
    from treeform._shared.cluster import check_cluster
    from treeform._shared.rng import check_seed

    photos = list_photos(input_dir)
    check_cluster(workers, scheduler)
    check_seed(seed)
    if timeout is None or check_range(timeout, "timeout", 0, 1e7) == 0:  # at most 1e7 s (116 days)
        raise InputError(f"timeout: expected a positive number of seconds, got {timeout!r}")
    mem = parse_memory(memory_limit) if not isinstance(memory_limit, int) else int(memory_limit)
    if mem < 0:
        raise InputError(f"memory limit: expected 0 (none) or more bytes, got {mem}")
    need = parse_memory(min_free, what="min free") if not isinstance(min_free, int) else int(min_free)
    if need < 0:
        raise InputError(f"min free: expected 0 (none) or more bytes, got {need}")
    out_dir = check_out_dir(out)
    low = _low_disk(out_dir, need)
    if low is not None:
        raise InputError(f"out: {low}")
    out_dir.mkdir(parents=True, exist_ok=True)
    names = _folder_names(photos)
    mpath = out_dir / MANIFEST
    manifest = json.loads(mpath.read_text()) if mpath.is_file() else {}
    done_before = {n for n, e in manifest.items()
                   if e.get("status") == "done" and (out_dir / e.get("folder", n) / "metrics.json").is_file()}
    todo = [(p, n) for p, n in zip(photos, names) if n not in done_before]
    kw = dict(method=method, seed=int(seed), timeout=float(timeout), memory_limit=mem, min_free=need,
              options=tuple(options))
    t0 = time.perf_counter()
    state = {"n": len(done_before)}

    def finish(photo: Path, name: str, res: dict) -> None:
        manifest[name] = {"photo": photo.name, "folder": name, **res}
        _write_json(mpath, manifest)
        _write_json(out_dir / FAILURES, _failures(manifest))
        state["n"] += 1
        if progress is not None:
            progress(state["n"], len(photos))

    if progress is not None:
        progress(state["n"], len(photos))
    if todo and workers == 0:
        for p, n in todo:
            finish(p, n, reconstruct_one(str(p), str(out_dir / n), **kw))
    elif todo:
        from distributed import as_completed

        from treeform._shared.cluster import dask_client

        client, cluster = dask_client(workers or os.cpu_count() or 1, scheduler)
        try:
            futs = {client.submit(reconstruct_one, str(p), str(out_dir / n), **kw, key=f"batch-{n}-{seed}-{t0}",
                                  pure=False): (p, n) for p, n in todo}
            for fut in as_completed(futs):
                p, n = futs[fut]
                try:
                    res = fut.result()
                except Exception as exc:  # the worker itself was lost
                    res = {"status": "failed", "reason": f"worker lost: {type(exc).__name__}: {exc}"[:300],
                           "seconds": None}
                finish(p, n, res)
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    _write_json(out_dir / FAILURES, _failures(manifest))
    from treeform.report import write_batch_summary

    these = {n: manifest[n] for n in names if n in manifest}  # this folder's photos (a manifest may hold old ones)
    write_batch_summary(out_dir, these, title=f"treeform batch ({method})")
    seconds = time.perf_counter() - t0
    ran = len(todo)
    statuses = [e.get("status") for e in these.values()]
    return {"total": len(photos), "done": statuses.count("done"), "failed": statuses.count("failed"),
            "skipped": len(done_before), "seconds": round(seconds, 2),
            "photos_per_second": round(ran / seconds, 3) if ran and seconds > 0 else None, "manifest": manifest}
