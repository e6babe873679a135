"""Generate a synthetic dataset on Dask distributed: resumable per sample, retries, a failures list.

:func:`generate_dataset` splits ``n`` samples into shards of ``shard_size``, skips shards a
previous run finished (listed in the manifest, file present with the recorded size), and
runs one Dask task per sample on a :class:`distributed.LocalCluster` (``workers``
processes, one thread each) or on an existing scheduler (``scheduler="tcp://host:port"``,
workers started with ``dask worker`` in an environment where treeform is installed). A task
that raises is retried once by Dask; if it fails again the sample is recorded in
``failures.json`` and left out of its shard; the run goes on.

Resuming: the manifest (with the settings) is written before the first sample; each sample
is stored the moment it arrives, atomically, as ``partial/<index>.tar``; a shard is written
(atomically, from those files) as soon as all its samples are resolved, then the manifest is
updated and the shard's partial files deleted. A killed run (even ``SIGKILL``) therefore
loses only the samples being computed at that moment (a few seconds of work); a rerun with
the same options keeps every stored sample, makes the rest, and writes byte-identical
shards (sample i depends only on (seed, i)).
"""

from __future__ import annotations

import functools
import logging
import math
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

from treeform._shared.checks import check_int
from treeform._shared.errors import InputError, OutputError, TreeformError
from treeform.dataset.storage import (
    FORMAT,
    PARTIAL,
    encode_sample,
    partial_indices,
    partial_path,
    read_manifest,
    read_partial,
    shard_name,
    write_manifest,
    write_partial,
    write_shard,
)
from treeform._shared.cluster import dask_client
from treeform.dataset.synthetic import SampleOptions, make_sample

__all__ = ["GenerateResult", "generate_dataset", "parse_species", "sample_members"]

log = logging.getLogger(__name__)

@dataclass
class GenerateResult:
    """What a :func:`generate_dataset` run did."""

    out: Path
    n: int
    generated: int = 0
    """Samples made (and stored) by this run."""
    kept: int = 0
    """Samples an interrupted run had made and stored (``partial/``), reused by this run."""
    failed: list = field(default_factory=list)
    """Indices that failed twice in this run."""
    shards_written: list = field(default_factory=list)
    shards_skipped: list = field(default_factory=list)
    """Shards a previous run had finished."""
    seconds: float = 0.0
    workers: int = 0

    @property
    def samples_per_second(self) -> float:
        return self.generated / self.seconds if self.seconds > 0 else 0.0


def parse_species(species) -> tuple:
    """``"all"``, ``"oak,pine"`` or a sequence of names -> tuple of preset names (checked)."""
    from treeform.growth.species import SPECIES

    if species is None or (isinstance(species, str) and species.strip().lower() in ("", "all")):
        return SPECIES
    names = [s.strip() for s in species.split(",")] if isinstance(species, str) else [str(s) for s in species]
    names = [s for s in names if s]
    unknown = [s for s in names if s not in SPECIES]
    if unknown or not names:
        raise InputError(f"species: unknown {', '.join(map(repr, unknown)) or 'empty list'}; "
                         f"known: all, {', '.join(SPECIES)}")
    return tuple(dict.fromkeys(names))


@functools.lru_cache(maxsize=4)
def _pool(folder, photo_fraction: float):
    from treeform.dataset.backgrounds import BackgroundPool

    return BackgroundPool(folder, photo_fraction=photo_fraction)


def sample_members(seed: int, index: int, options: dict, backgrounds: str | None = None,
                   photo_fraction: float = 0.5) -> dict:
    """Make and encode one sample: ``{member name: bytes}`` (the Dask task; also for checks).

    Parameters
    ----------
    seed, index : int
    options : dict
        :class:`SampleOptions` fields.
    backgrounds : str, optional
        Folder of background photos.
    photo_fraction : float
    """
    opts = SampleOptions(**{**options, "species": tuple(options.get("species", ()))})
    return encode_sample(make_sample(seed, index, opts, backgrounds=_pool(backgrounds, photo_fraction)))


def generate_dataset(out, *, n: int, size: int = 256, species="all", workers: int | None = None,
                     scheduler: str | None = None, seed: int = 0, shard_size: int = 1000, mesh: bool = False,
                     backgrounds=None, photo_fraction: float = 0.5, supersample: int = 2, lod: str = "medium",
                     bare: float = 0.0, progress=None) -> GenerateResult:
    """Generate (or finish) a synthetic dataset of grown, rendered trees (seed 003 §4.2.1).

    Parameters
    ----------
    out : path
        Dataset directory (created). Rerunning with the same options skips finished shards;
        a larger ``n`` extends the dataset.
    n : int
        Number of samples (indices 0 .. n-1).
    size : int
        Image edge in pixels.
    species : "all", comma-separated names or a sequence
    workers : int, optional
        LocalCluster worker processes (default: the machine's cores). Ignored with ``scheduler``.
    scheduler : str, optional
        Address of a running Dask scheduler, e.g. ``"tcp://127.0.0.1:8786"``.
    seed : int
        Global seed: sample i depends only on (seed, i) and the options.
    shard_size : int
        Samples per tar shard (samples are stored one by one until their shard is complete,
        so the shard size does not change how much work a kill loses).
    mesh : bool
        Also store each tree's GLB.
    backgrounds : path, optional
        Folder of the user's photos, used for ``photo_fraction`` of the samples.
    supersample : int
        Render at this multiple of ``size`` (anti-aliasing; 1 = fastest).
    lod : str
        Mesh triangle budget (see :data:`treeform.geometry.LOD_PRESETS`).
    bare : float
        Share of leafless samples (:attr:`SampleOptions.bare`); 0 leaves every sample as before.
    progress : callable, optional
        ``progress(done, total)`` once at the start (``done``: samples of unfinished shards an
        interrupted run already stored) and after every resolved sample; ``total``: the
        samples of the unfinished shards.

    Returns
    -------
    GenerateResult

    Raises
    ------
    InputError
        Bad options, an unreachable scheduler, or ``out`` holding a dataset made with other
        options (seed, size, species, shard size, ...).
    OutputError
        ``out`` cannot be written.
    """
    from treeform._shared.cluster import check_cluster
    from treeform.io.outputs import check_out_dir

    n = check_int(n, "n", 1, 100_000_000)
    shard_size = check_int(shard_size, "shard_size", 1, 1_000_000)
    seed = check_int(seed, "seed", 0, 2**63 - 1)
    check_cluster(workers, scheduler, allow_zero=False)
    names = parse_species(species)
    opts = SampleOptions(size=size, species=names, supersample=supersample, lod=lod, mesh=bool(mesh),
                         bare=bare).validate()
    if backgrounds is not None:
        backgrounds = str(Path(backgrounds).resolve())
    _pool(backgrounds, float(photo_fraction))  # checks the folder and the fraction up front
    out = check_out_dir(out)
    try:
        out.mkdir(exist_ok=True)
    except OSError as exc:
        raise OutputError(f"--out {out}: cannot create ({exc.strerror or exc})") from None

    options = {"size": opts.size, "species": list(opts.species), "supersample": opts.supersample, "lod": opts.lod,
               "mesh": opts.mesh, **({"bare": opts.bare} if opts.bare else {})}  # (datasets without it: as they were)
    identity = {"format": FORMAT, "seed": seed, "shard_size": shard_size, "options": options,
                "backgrounds": backgrounds, "photo_fraction": float(photo_fraction)}
    manifest = read_manifest(out)
    if manifest is not None:
        theirs = {k: manifest.get(k) for k in identity}
        if theirs != identity:
            diff = ", ".join(k for k in identity if theirs[k] != identity[k])
            raise InputError(f"{out} holds a dataset made with other settings ({diff}); use another --out")
    else:
        from treeform import __version__
        from treeform.growth.species import SPECIES

        manifest = {**identity, "species_names": list(SPECIES), "treeform": __version__, "shards": {},
                    "labels": {"background": 0, "foliage": 1, "branch": 2}}
        _clear_partial(out)  # no manifest: any partial samples were made with unknown settings
    manifest["n"] = max(n, int(manifest.get("n", 0)))
    failures = read_failures(out)
    for tmp in ("manifest.json.tmp", "failures.json.tmp", *(p.name for p in out.glob("shard-*.tar.tmp"))):
        (out / tmp).unlink(missing_ok=True)  # leftovers of a killed write

    res = GenerateResult(out=out, n=n)
    stored = partial_indices(out, clean=True)
    pending: dict[str, dict] = {}
    for k in range(math.ceil(n / shard_size)):
        first, count = k * shard_size, min(shard_size, n - k * shard_size)
        name = shard_name(k)
        done = manifest["shards"].get(name)
        indices = range(first, first + count)
        if (done and done["first"] == first and done["count"] == count and (out / name).exists()
                and (out / name).stat().st_size == done["bytes"]):
            res.shards_skipped.append(name)
            for i in stored.intersection(indices):  # killed after the manifest, before the clean-up
                partial_path(out, i).unlink(missing_ok=True)
        else:
            kept = stored.intersection(indices)
            res.kept += len(kept)
            pending[name] = {"first": first, "count": count, "kept": kept, "failed": []}
    if not pending:
        _clear_partial(out, only_if_empty=True)
        return res

    total = sum(s["count"] for s in pending.values())
    if progress is not None:
        progress(res.kept, total)
    t0 = time.perf_counter()
    for name, shard in list(pending.items()):  # killed after its last sample: nothing left to make
        if len(shard["kept"]) == shard["count"]:
            _finish_shard(name, pending.pop(name), out, manifest, failures, res)
    if pending:
        client, cluster = dask_client(workers or os.cpu_count() or 1, scheduler)
        try:
            write_manifest(out, manifest)  # the settings before any sample: stored samples are attributable
            res.workers = len(client.scheduler_info().get("workers", {}))
            _run(client, sample_members, pending, seed, options, backgrounds, float(photo_fraction), out, manifest,
                 failures, res, total, progress, done=res.kept)
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    _clear_partial(out, only_if_empty=True)
    res.seconds = time.perf_counter() - t0
    res.failed.sort()
    return res


def _clear_partial(out: Path, *, only_if_empty: bool = False) -> None:
    """Delete ``out/partial`` (all of it, or only the empty folder)."""
    folder = out / PARTIAL
    if not folder.is_dir():
        return
    try:
        if not only_if_empty:
            for p in folder.iterdir():
                p.unlink(missing_ok=True)
        folder.rmdir()
    except OSError:
        pass  # not empty (only_if_empty) or not ours to remove: harmless


def read_failures(directory) -> dict:
    """``{index: {"index", "error", "attempts"}}`` from a dataset's ``failures.json`` (empty if none)."""
    import json

    path = Path(directory) / "failures.json"
    if not path.exists():
        return {}
    try:
        return {int(f["index"]): f for f in json.loads(path.read_text())}
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise InputError(f"{path}: not a readable failures list ({exc})") from None


def _run(client, task, pending, seed, options, backgrounds, photo_fraction, out, manifest, failures, res, total,
         progress, done: int = 0):
    """Run ``task(seed, index, options, backgrounds, photo_fraction) -> members`` for every pending
    index not yet stored (a sliding window of futures, one Dask retry each); store each sample
    the moment it arrives and write each shard when all its samples are resolved.

    ``pending``: ``{shard name: {"first", "count", "kept": set of stored indices, "failed": []}}``;
    ``done``: the count ``progress(done, total)`` starts from.
    """
    from distributed import as_completed

    by_index = {}
    for name, shard in pending.items():
        for i in range(shard["first"], shard["first"] + shard["count"]):
            if i not in shard["kept"]:
                by_index[i] = name
    queue = iter(sorted(by_index))
    window = max(32, 8 * max(res.workers, 1))

    def submit(i):
        return client.submit(task, seed, i, options, backgrounds, photo_fraction, key=f"sample-{seed}-{i}",
                             retries=1, pure=False)

    futures = {}
    for i in queue:
        futures[submit(i)] = i
        if len(futures) >= window:
            break
    ac = as_completed(list(futures))
    for fut in ac:
        i = futures.pop(fut)
        shard = pending[by_index[i]]
        if fut.status == "finished":
            write_partial(out, i, fut.result())
            shard["kept"].add(i)
            res.generated += 1
            if failures.pop(i, None) is not None:
                _write_failures(out, failures)
        else:
            exc = fut.exception()
            msg = f"{type(exc).__name__}: {exc}" if not isinstance(exc, TreeformError) else str(exc)
            log.warning("sample %d failed twice: %s", i, msg)
            shard["failed"].append(i)
            failures[i] = {"index": i, "error": msg, "attempts": 2}
            res.failed.append(i)
            _write_failures(out, failures)
        fut.release()
        done += 1
        if progress is not None:
            progress(done, total)
        if len(shard["kept"]) + len(shard["failed"]) == shard["count"]:
            _finish_shard(by_index[i], shard, out, manifest, failures, res)
        nxt = next(queue, None)
        if nxt is not None:
            f = submit(nxt)
            futures[f] = nxt
            ac.add(f)


def _write_failures(out, failures):
    write_manifest(out, [failures[k] for k in sorted(failures)], "failures.json")


def _finish_shard(name, shard, out, manifest, failures, res):
    """Write a shard from its stored samples, record it in the manifest, then delete those samples."""
    indices = sorted(shard["kept"])
    facts = write_shard(out / name, (read_partial(out, i) for i in indices))
    res.shards_written.append(name)
    manifest["shards"][name] = {"first": shard["first"], "count": shard["count"], "samples": len(indices),
                                "failed": sorted(shard["failed"]), **facts}
    _write_failures(out, failures)
    write_manifest(out, manifest)
    for i in indices:
        partial_path(out, i).unlink(missing_ok=True)
