"""``treeform batch``: one task per photo, bad photos recorded, reruns skip done photos, kills by time and memory."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from treeform._shared.errors import InputError
from treeform.batch import list_photos, parse_memory, run_batch

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = ROOT / "src" / "treeform" / "data" / "Celtis_occidentalis_1.jpg"


@pytest.fixture
def folder(tmp_path):
    """A small good photo, an empty one, a truncated one and a text file."""
    from PIL import Image

    d = tmp_path / "photos"
    d.mkdir()
    im = Image.open(SAMPLE)
    im.thumbnail((200, 200))
    im.save(d / "good.jpg")
    (d / "empty.jpg").write_bytes(b"")
    (d / "truncated.jpg").write_bytes((d / "good.jpg").read_bytes()[:400])
    (d / "notes.txt").write_text("not a photo")
    return d


def test_memory_sizes_and_photo_listing(tmp_path, folder):
    assert parse_memory("4GB") == 4 * 10**9 and parse_memory("1.5 GiB") == int(1.5 * 2**30)
    assert parse_memory("none") == 0 and parse_memory(0) == 0
    for bad in ("lots", "-1GB", "4XB"):
        with pytest.raises(InputError, match="memory limit"):
            parse_memory(bad)
    assert [p.name for p in list_photos(folder)] == ["empty.jpg", "good.jpg", "truncated.jpg"]
    with pytest.raises(InputError, match="no photos"):
        list_photos(_empty(tmp_path))


def _empty(tmp_path):
    d = tmp_path / "nothing"
    d.mkdir()
    (d / "readme.md").write_text("x")
    return d


def test_a_batch_records_bad_photos_skips_done_ones_on_rerun_and_kills_slow_ones(tmp_path, folder):
    out = tmp_path / "out"
    seen = []
    res = run_batch(folder, out, workers=0, timeout=120, progress=lambda d, t: seen.append((d, t)))
    assert (res["total"], res["done"], res["failed"], res["skipped"]) == (3, 1, 2, 0)
    assert seen[0] == (0, 3) and seen[-1] == (3, 3)
    assert {"tree.glb", "metrics.json", "preview.png"} <= {p.name for p in (out / "good").iterdir()}
    assert not list(out.glob("*.partial"))  # no half-written result folder
    fails = {f["photo"]: f["reason"] for f in json.loads((out / "failures.json").read_text())}
    assert set(fails) == {"empty.jpg", "truncated.jpg"} and "empty file" in fails["empty.jpg"]
    assert all("\n" not in r and "Traceback" not in r for r in fails.values())
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["good"]["status"] == "done" and 0 <= manifest["good"]["metrics"]["reprojection_error"] < 0.3
    page = (out / "summary.html").read_text()
    assert "good/preview.png" in page and "empty.jpg" in page

    # a rerun does not redo the done photo, retries the failed ones
    stamp = (out / "good" / "tree.glb").stat().st_mtime_ns
    again = run_batch(folder, out, workers=0, timeout=120)
    assert (again["skipped"], again["done"], again["failed"]) == (1, 1, 2)
    assert (out / "good" / "tree.glb").stat().st_mtime_ns == stamp

    # a photo past its time is killed and recorded; nothing of it is left behind
    slow = run_batch(folder, tmp_path / "slow", workers=0, timeout=0.5)
    reasons = {f["photo"]: f["reason"] for f in json.loads((tmp_path / "slow" / "failures.json").read_text())}
    assert reasons["good.jpg"] == "timed out after 0.5 s" and slow["done"] == 0
    assert not (tmp_path / "slow" / "good").exists() and not list((tmp_path / "slow").glob("*.partial"))


def test_bad_arguments_give_one_line_and_no_output(tmp_path, folder):
    for args in (["--timeout", "0"], ["--memory-limit", "lots"], ["--min-free", "lots"], ["--min-free", "1000TB"]):
        run = subprocess.run([sys.executable, "-m", "treeform", "batch", str(folder), "--out", str(tmp_path / "o")]
                             + args, capture_output=True, text=True, timeout=120)
        assert run.returncode != 0 and run.stderr.strip().count("\n") == 0, (args, run.stderr)
        assert run.stderr.startswith("error:"), run.stderr
        assert not (tmp_path / "o").exists()
    run = subprocess.run([sys.executable, "-m", "treeform", "batch", str(tmp_path / "missing"), "--out",
                          str(tmp_path / "o")], capture_output=True, text=True, timeout=120)
    assert run.returncode == 2 and run.stderr.strip() == f"error: {tmp_path / 'missing'}: no such file"


def test_a_batch_on_a_separately_started_scheduler_and_workers(tmp_path, folder, dask_cluster_processes):
    """``dask scheduler`` and ``dask worker`` as their own processes, the CLI as a client."""
    (folder / "empty.jpg").unlink()
    address = dask_cluster_processes(1)
    out = tmp_path / "out"
    run = subprocess.run([sys.executable, "-m", "treeform", "batch", str(folder), "--out", str(out),
                          "--scheduler", address, "--timeout", "120"], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    assert "1 of 2 photos reconstructed" in run.stdout and "1 failed" in run.stdout
    assert (out / "good" / "tree.glb").is_file()
    assert [f["photo"] for f in json.loads((out / "failures.json").read_text())] == ["truncated.jpg"]


@pytest.mark.parametrize("crashes, status", [(1, "done"), (2, "failed")])
def test_a_crashed_child_is_run_once_more(tmp_path, monkeypatch, crashes, status):
    """A reconstruction that dies by a signal the watch did not send (a native crash) is retried
    once: one crash is the machine's, two are the photo's. A kill by the watch is not retried."""
    from treeform.batch import run as run_mod

    calls = []

    def fake(cmd, tmp, deadline, timeout, memory_limit):
        calls.append(cmd)
        if len(calls) <= crashes:
            return "killed by signal 11", -11, False
        tmp.mkdir(parents=True)
        (tmp / "metrics.json").write_text(json.dumps({"iou": 0.9}))
        return None, 0, False

    monkeypatch.setattr(run_mod, "_attempt", fake)
    res = run_mod.reconstruct_one(str(SAMPLE), str(tmp_path / "t"))
    assert res["status"] == status and res["attempts"] == 2 and len(calls) == 2
    if status == "done":
        assert res["metrics"] == {"iou": 0.9} and (tmp_path / "t" / "metrics.json").is_file()
    else:
        assert res["reason"] == "killed by signal 11 (twice)" and not (tmp_path / "t").exists()
    calls.clear()
    monkeypatch.setattr(run_mod, "_attempt", lambda *a: (calls.append(a), ("timed out after 1 s", -9, True))[1])
    assert run_mod.reconstruct_one(str(SAMPLE), str(tmp_path / "u"))["attempts"] == 1 and len(calls) == 1


def test_a_full_output_disk_stops_the_batch_cleanly_and_a_rerun_finishes_it(tmp_path, monkeypatch):
    """Below --min-free the batch does not start (one line, no output); when the disk fills during
    a batch, the photos not yet started are recorded as failed and not run, and a rerun once there
    is space again does them and skips the ones already done."""
    import shutil as _shutil

    from treeform.batch import run as run_mod

    photos = tmp_path / "photos"
    photos.mkdir()
    for k in range(3):
        (photos / f"p{k}.jpg").write_bytes(b"x")
    ran = []

    def fake(cmd, tmp, deadline, timeout, memory_limit):  # a reconstruction that writes its metrics
        ran.append(Path(cmd[4]).name)
        tmp.mkdir(parents=True)
        (tmp / "metrics.json").write_text(json.dumps({"iou": 0.9}))
        return None, 0, False

    free = {"bytes": 10**6}
    real = _shutil.disk_usage
    monkeypatch.setattr(run_mod, "_attempt", fake)
    monkeypatch.setattr(run_mod.shutil, "disk_usage", lambda p: real(p)._replace(free=free["bytes"]))
    with pytest.raises(InputError, match=r"^out: 1 MB free on the output disk, under the minimum of 500 MB"):
        run_batch(photos, tmp_path / "o", workers=0)
    assert not (tmp_path / "o").exists()

    free["bytes"] = 10**9  # room for one photo: the disk "fills" as soon as the first is written
    res = run_batch(photos, tmp_path / "o", workers=0, min_free="500MB",
                    progress=lambda d, t: free.update(bytes=10**6) if d == 1 else None)
    assert (res["done"], res["failed"]) == (1, 2) and ran == ["p0.jpg"]
    fails = json.loads((tmp_path / "o" / "failures.json").read_text())
    assert [f["photo"] for f in fails] == ["p1.jpg", "p2.jpg"]
    assert all(f["reason"].startswith("not run: 1 MB free") for f in fails)
    assert not any((tmp_path / "o" / n).exists() for n in ("p1", "p2", "p1.partial", "p2.partial"))

    free["bytes"] = 10**10
    res = run_batch(photos, tmp_path / "o", workers=0)
    assert (res["done"], res["failed"], res["skipped"]) == (3, 0, 1) and ran == ["p0.jpg", "p1.jpg", "p2.jpg"]
    assert parse_memory("none", what="min free") == 0
    with pytest.raises(InputError, match="^min free: expected a size"):
        run_batch(photos, tmp_path / "o", workers=0, min_free="plenty")
