"""Dataset generation on Dask: shards, manifest, reproducibility, resuming (per shard and per sample),
failures, retries, remote scheduler."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from treeform._shared.errors import InputError
from treeform.dataset import SyntheticDataset, generate_dataset, sample_members
from treeform.dataset.storage import partial_indices, partial_path, read_partial, read_shard, write_partial

SMALL = dict(size=48, lod="low", supersample=1)
OPTIONS = {"size": 48, "species": [], "supersample": 1, "lod": "low", "mesh": False}


@pytest.fixture(scope="module")
def dataset(tmp_path_factory, gl):
    out = tmp_path_factory.mktemp("ds") / "data"
    res = generate_dataset(out, n=5, workers=2, seed=11, shard_size=2, **SMALL)
    return out, res


def _stamps(out: Path) -> dict:
    return {p.name: (p.stat().st_ino, p.stat().st_mtime_ns) for p in sorted(out.glob("shard-*.tar"))}


def test_shards_and_manifest(dataset):
    out, res = dataset
    assert res.generated == 5 and res.failed == [] and res.workers == 2
    assert res.shards_written and sorted(res.shards_written) == ["shard-00000.tar", "shard-00001.tar", "shard-00002.tar"]
    m = json.loads((out / "manifest.json").read_text())
    assert m["seed"] == 11 and m["n"] == 5 and m["shard_size"] == 2
    assert [m["shards"][k]["samples"] for k in sorted(m["shards"])] == [2, 2, 1]
    assert json.loads((out / "failures.json").read_text()) == []
    ds = SyntheticDataset(out)
    assert len(ds) == 5 and [ds[i]["index"] for i in range(5)] == [0, 1, 2, 3, 4]
    assert not list(out.glob("*.tmp"))


def test_a_sample_regenerated_alone_is_byte_identical(dataset):
    out, _ = dataset
    stored = read_shard(out / "shard-00001.tar")[1]  # index 3
    again = sample_members(11, 3, OPTIONS)
    assert stored.keys() == again.keys()
    assert all(stored[k] == again[k] for k in stored)


def test_rerun_skips_finished_shards_and_extends(dataset, tmp_path):
    out, _ = dataset
    before = _stamps(out)
    res = generate_dataset(out, n=5, workers=1, seed=11, shard_size=2, **SMALL)
    assert res.generated == 0 and len(res.shards_skipped) == 3 and _stamps(out) == before
    with pytest.raises(InputError, match="other settings"):
        generate_dataset(out, n=5, workers=1, seed=12, shard_size=2, **SMALL)


def test_interrupted_run_resumes_without_redoing_shards(tmp_path, gl):
    out = tmp_path / "ds"
    cmd = [sys.executable, "-m", "treeform", "dataset", "generate", "-n", "10", "-o", str(out), "--size", "48",
           "--shard-size", "2", "--workers", "1", "--seed", "3"]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        deadline = time.time() + 120
        while time.time() < deadline:
            m = out / "manifest.json"
            if m.exists() and len(json.loads(m.read_text())["shards"]) >= 1:
                break
            time.sleep(0.05)
        else:
            pytest.fail("no shard finished within 120 s")
    finally:
        os.killpg(proc.pid, signal.SIGKILL)  # a crash: no clean-up of any kind
        proc.wait()
    done = json.loads((out / "manifest.json").read_text())["shards"]
    assert 1 <= len(done) < 5
    before = {k: v for k, v in _stamps(out).items() if k in done}
    rerun = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert rerun.returncode == 0, rerun.stderr
    assert f"{len(done)} shard(s) already done" in rerun.stdout
    after = _stamps(out)
    assert len(after) == 5 and all(after[k] == before[k] for k in before)
    assert len(SyntheticDataset(out)) == 10


def test_partial_samples_survive_only_whole(tmp_path):
    """Stored samples are whole tars; a killed write (``.tmp``) or a cut file is dropped, not used."""
    members = {"00000007.json": b'{"index":7}', "00000007.image.png": bytes(range(256)) * 5}
    write_partial(tmp_path, 7, members)
    assert read_partial(tmp_path, 7) == members
    (tmp_path / "partial" / "00000008.tar.tmp").write_bytes(b"x" * 700)  # killed mid-write
    partial_path(tmp_path, 9).write_bytes(partial_path(tmp_path, 7).read_bytes()[:1000])  # cut short
    assert partial_indices(tmp_path) == {7}
    assert len(list((tmp_path / "partial").iterdir())) == 3  # watching a run deletes nothing of it
    assert partial_indices(tmp_path, clean=True) == {7}
    assert sorted(p.name for p in (tmp_path / "partial").iterdir()) == ["00000007.tar"]


def _newest_sample_time(out: Path) -> float:
    return max(p.stat().st_mtime for p in (out / "partial").glob("*.tar"))


def test_a_killed_run_loses_only_the_samples_in_progress(tmp_path, gl):
    """SIGKILL in the middle of a shard: every finished sample is kept, the rerun makes only the
    rest, and the shard is byte-identical to an uninterrupted run's."""
    n = 8
    out, ref = tmp_path / "killed", tmp_path / "uninterrupted"
    args = ["-n", str(n), "--size", "48", "--workers", "1", "--seed", "3"]  # one shard of 1000: all of it in flight
    cmd = [sys.executable, "-m", "treeform", "dataset", "generate", *args, "-o"]
    proc = subprocess.Popen(cmd + [str(out)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            start_new_session=True)
    try:
        deadline = time.time() + 180
        while time.time() < deadline and len(partial_indices(out)) < 3:
            time.sleep(0.02)
    finally:
        os.killpg(proc.pid, signal.SIGKILL)  # a crash: no clean-up of any kind
        killed_at = time.time()
        proc.wait()
    kept = partial_indices(out)
    assert 3 <= len(kept) < n, "the run finished before the kill (or stored nothing in 180 s)"
    assert not list(out.glob("shard-*.tar"))  # no shard yet: the old scheme would have lost all of it
    lost = killed_at - _newest_sample_time(out)  # wall time of work since the last stored sample
    assert lost < 10, lost
    rerun = subprocess.run(cmd + [str(out)], capture_output=True, text=True, timeout=300)
    assert rerun.returncode == 0, rerun.stderr
    assert f"{n - len(kept)} samples in 1 new shard(s)" in rerun.stdout
    assert f"{len(kept)} sample(s) kept from an interrupted run" in rerun.stdout
    assert f"samples {len(kept)}/{n}" in rerun.stderr  # the progress starts from the kept samples
    assert not (out / "partial").exists() and not list(out.glob("*.tmp"))
    whole = subprocess.run(cmd + [str(ref)], capture_output=True, text=True, timeout=300)
    assert whole.returncode == 0, whole.stderr
    assert (out / "shard-00000.tar").read_bytes() == (ref / "shard-00000.tar").read_bytes()
    shards = lambda d: json.loads((d / "manifest.json").read_text())["shards"]  # noqa: E731
    assert shards(out) == shards(ref)
    assert [s["index"] for s in SyntheticDataset(out)] == list(range(n))


def test_stale_partial_samples_without_a_manifest_are_not_used(tmp_path, gl):
    """Stored samples count only under the manifest that records their settings."""
    out = tmp_path / "ds"
    out.mkdir()
    write_partial(out, 0, {"00000000.json": b'{"index":0}'})  # left by a run whose manifest is gone
    res = generate_dataset(out, n=1, workers=1, seed=11, **SMALL)
    assert res.kept == 0 and res.generated == 1
    stored = read_shard(out / "shard-00000.tar")[0]
    assert stored == sample_members(11, 0, OPTIONS) and not (out / "partial").exists()


def test_a_failing_sample_is_recorded_and_skipped(tmp_path, gl):
    photos = tmp_path / "photos"
    photos.mkdir()
    Image.fromarray(np.full((40, 40, 3), (90, 140, 200), np.uint8)).save(photos / "a_good.png")
    (photos / "b_broken.jpg").write_bytes(b"not an image")
    out = tmp_path / "ds"
    res = generate_dataset(out, n=6, workers=2, seed=0, shard_size=3, backgrounds=photos, photo_fraction=1.0,
                           **SMALL)
    failures = json.loads((out / "failures.json").read_text())
    assert 1 <= len(res.failed) < 6 and res.generated + len(res.failed) == 6
    assert [f["index"] for f in failures] == res.failed
    assert all(f["attempts"] == 2 and "b_broken.jpg" in f["error"] for f in failures)
    stored = [json.loads(v)["index"] for shard in sorted(out.glob("shard-*.tar"))
              for s in read_shard(shard) for k, v in s.items() if k.endswith(".json") and "skeleton" not in k]
    assert sorted(stored + res.failed) == list(range(6))


_CALLS: dict = {}


def _flaky(seed, index, options, backgrounds, photo_fraction):
    """Fails the first attempt of index 1 and every attempt of index 2."""
    _CALLS[index] = _CALLS.get(index, 0) + 1
    if index == 2 or (index == 1 and _CALLS[index] == 1):
        raise RuntimeError(f"boom {index}")
    return {f"{index:08d}.json": json.dumps({"index": index}).encode()}


def test_dask_retries_once_then_records(tmp_path):
    from distributed import Client, LocalCluster

    from treeform.dataset.generate import GenerateResult, _run

    _CALLS.clear()
    pending = {"shard-00000.tar": {"first": 0, "count": 4, "kept": set(), "failed": []}}
    manifest = {"shards": {}}
    failures: dict = {}
    res = GenerateResult(out=tmp_path, n=4, workers=1)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0") as cluster, \
            Client(cluster) as client:
        _run(client, _flaky, pending, 0, {}, None, 0.5, tmp_path, manifest, failures, res, 4, None)
    assert _CALLS == {0: 1, 1: 2, 2: 2, 3: 1}
    assert res.failed == [2] and res.generated == 3
    assert manifest["shards"]["shard-00000.tar"]["failed"] == [2]
    assert [len(s) for s in read_shard(tmp_path / "shard-00000.tar")] == [1, 1, 1]
    assert [f["index"] for f in json.loads((tmp_path / "failures.json").read_text())] == [2]
    assert partial_indices(tmp_path) == set()  # the shard is written: its stored samples are gone


def test_generation_on_a_separately_started_scheduler_and_workers(tmp_path, gl, dask_cluster_processes):
    """``dask scheduler`` and ``dask worker`` as their own processes, the CLI as a client."""
    address = dask_cluster_processes(2)
    out = tmp_path / "ds"
    run = subprocess.run([sys.executable, "-m", "treeform", "dataset", "generate", "-n", "4", "-o", str(out),
                          "--size", "48", "--shard-size", "2", "--scheduler", address, "--seed", "5"],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    assert "4 samples in 2 new shard(s)" in run.stdout
    stored = read_shard(out / "shard-00001.tar")[0]
    again = sample_members(5, 2, {**OPTIONS, "supersample": 2, "lod": "medium"})
    assert all(stored[k] == again[k] for k in stored)  # same bytes as a local, in-process sample
