"""Throughput of ``treeform batch`` on 1 and 2 workers, with a share of bad photos; kill and rerun.

A folder of N photos of which about 5 % are bad. Two sources:

* real (default): the real photos of ../shared/data/photos (reduced to 400 px, cycled);
  the bad ones are empty or truncated files.
* synthetic: the photos of a dataset made by ``treeform dataset generate`` (``--dataset
  DIR``: grown trees of the seven species rendered over procedural backgrounds, saved as JPEG);
  the bad ones cycle through six kinds: an empty file, a truncated JPEG, a text file named
  .jpg, a 300-megapixel PNG (over the loader's limit), random noise and a cloudless sky (no
  tree).

Each worker count runs the whole folder into a fresh output folder and reports photos/s end to
end (cluster start included), the done / failed counts and whether every bad file, and only
those, failed. With ``--kill-at F`` the last run is the ``treeform batch`` command itself,
killed (SIGKILL to its whole process group: the command, its Dask workers and their
reconstructions) once a fraction F of the photos are in the manifest, then run again: the
rerun must skip every photo done before the kill and end with every good photo done.

Run: `python benchmarks/bench_batch.py [N] [--dataset DIR] [--workers 1,2] [--kill-at 0.4]`, e.g.
`treeform dataset generate -n 950 --size 400 --seed 7 --out DS` then
`python benchmarks/bench_batch.py 1000 --dataset DS --workers 2 --kill-at 0.4`
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from _common import machine

ROOT = Path(__file__).resolve().parents[1]
PHOTOS = ROOT.parent / "shared" / "data" / "photos"
BAD_KINDS = ("empty", "truncated", "text", "huge", "noise", "sky")


def _bad_file(path: Path, kind: str, good_jpeg: bytes) -> Path:
    """Write one bad photo of ``kind``; returns its path (a PNG for the image kinds)."""
    from PIL import Image

    rng = np.random.default_rng(len(path.name))
    if kind == "empty":
        path.write_bytes(b"")
    elif kind == "truncated":
        path.write_bytes(good_jpeg[:300])
    elif kind == "text":
        path.write_text("this is not a photo\n")
    else:
        path = path.with_suffix(".png")
        if kind == "huge":
            Image.new("RGB", (20000, 15000), (90, 140, 60)).save(path)
        elif kind == "noise":
            Image.fromarray(rng.integers(0, 256, (400, 400, 3), dtype=np.uint8)).save(path)
        else:  # a cloudless sky: a vertical gradient
            t = np.linspace(0, 1, 300)[:, None, None]
            sky = (np.array([70, 120, 200]) * (1 - t) + np.array([170, 200, 235]) * t) * np.ones((1, 400, 1))
            Image.fromarray(sky.astype(np.uint8)).save(path)
    return path


def make_folder(n: int, dest: Path, dataset: Path | None = None) -> set:
    """Fill ``dest`` with ``n`` photos, about 5 % of them bad; returns the bad files' names.

    The good photos are ``dataset``'s samples (a ``treeform dataset generate`` folder) when
    given, else the real photos cycled."""
    from io import BytesIO

    from PIL import Image

    if dataset is not None:
        from treeform.dataset.loader import SyntheticDataset

        samples = SyntheticDataset(dataset)
        if len(samples) < n - n // 20:
            raise SystemExit(f"{dataset}: {len(samples)} samples, need {n - n // 20}")
        j = 0
    else:
        src = sorted(PHOTOS.glob("*.jpg"))
    bad, good_jpeg = set(), None
    for i in range(n):
        name = f"p{i:04d}.jpg"
        if i % 20 == 7 and good_jpeg is not None:  # ~5 % bad
            kinds = BAD_KINDS if dataset is not None else BAD_KINDS[:2]
            bad.add(_bad_file(dest / name, kinds[(i // 20) % len(kinds)], good_jpeg).name)
            continue
        if dataset is not None:
            im = Image.open(BytesIO(samples.members(j, ("image.png",))["sample.image.png"])).convert("RGB")
            j += 1
        else:
            im = Image.open(src[i % len(src)]).convert("RGB")
            im.thumbnail((400, 400))
        buf = BytesIO()
        im.save(buf, format="JPEG", quality=90)
        good_jpeg = buf.getvalue()
        (dest / name).write_bytes(good_jpeg)
    return bad


def _failed(out: Path) -> set:
    return {f["photo"] for f in json.loads((out / "failures.json").read_text())}


def kill_and_rerun(folder: Path, out: Path, workers: int, at: float, n: int) -> dict:
    """Run the ``treeform batch`` command, SIGKILL its process group once ``at`` of the photos are
    in the manifest, then run it again to the end; returns what each run did."""
    cmd = [sys.executable, "-m", "treeform", "batch", str(folder), "--out", str(out), "--workers", str(workers),
           "--timeout", "300"]
    env = dict(os.environ, TERM="dumb")
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env,
                            start_new_session=True)
    manifest = out / "manifest.json"
    in_manifest = 0
    while proc.poll() is None:
        try:
            in_manifest = len(json.loads(manifest.read_text()))
        except (OSError, ValueError):
            pass
        if in_manifest >= at * n:
            os.killpg(proc.pid, signal.SIGKILL)
            break
        time.sleep(0.5)
    proc.wait()
    first = time.perf_counter() - t0
    time.sleep(1.0)
    before = json.loads(manifest.read_text())
    done_before = sum(e.get("status") == "done" for e in before.values())
    t1 = time.perf_counter()
    res = subprocess.run(cmd, capture_output=True, text=True, env=env)
    second = time.perf_counter() - t1
    m = re.search(r"(\d+) of (\d+) photos reconstructed \((\d+) done before\), (\d+) failed", res.stdout)
    done, total, skipped, failed = (int(x) for x in m.groups()) if m else (None,) * 4
    return {"killed_after_s": round(first, 1), "in_manifest_at_kill": len(before), "done_at_kill": done_before,
            "rerun_s": round(second, 1), "rerun_rc": res.returncode, "done": done, "total": total,
            "skipped": skipped, "failed": failed}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("n", nargs="?", type=int, default=24)
    ap.add_argument("--dataset", type=Path, default=None,
                    help="a `treeform dataset generate` folder: its renders are the good photos")
    ap.add_argument("--workers", default="1,2", help="comma-separated worker counts")
    ap.add_argument("--table-photos", type=int, default=None,
                    help="the throughput table on the first M photos only (default: all N)")
    ap.add_argument("--kill-at", type=float, default=None,
                    help="also run the command on all N photos with the last worker count, kill it at this "
                         "fraction, rerun")
    ap.add_argument("--keep", type=Path, default=None, help="work folder (default: a new temporary one)")
    args = ap.parse_args()
    from treeform.batch import run_batch

    tmp = args.keep or Path(tempfile.mkdtemp(prefix="treeform-bench-batch-"))
    folder = tmp / "photos"
    folder.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    bad = make_folder(args.n, folder, args.dataset)
    print(f"# {machine()}\n{args.n} photos ({len(bad)} bad), {'synthetic' if args.dataset else 'real'}, 400 px, envelope route "
          f"(made in {time.perf_counter() - t0:.0f} s, in {folder})")
    print("| workers | photos/s (end to end) | seconds | done | failed | failures = the bad files |")
    print("|---|---|---|---|---|---|")
    counts = [int(w) for w in args.workers.split(",") if w]
    table, table_bad = folder, bad
    if args.table_photos:
        table = tmp / "table"
        table.mkdir(exist_ok=True)
        table_bad = make_folder(args.table_photos, table, args.dataset)
        print(f"(the table: the first {args.table_photos} photos, {len(table_bad)} bad)")
    for workers in counts:
        out = tmp / f"out{workers}"
        t0 = time.perf_counter()
        res = run_batch(table, out, workers=workers, timeout=300)
        dt = time.perf_counter() - t0
        print(f"| {workers} | {res['total'] / dt:.3f} | {dt:.1f} | {res['done']} | {res['failed']} | "
              f"{_failed(out) == table_bad} |", flush=True)
    if args.kill_at is not None:
        out = tmp / "out_killed"
        r = kill_and_rerun(folder, out, counts[-1], args.kill_at, args.n)
        ok = (r["skipped"] == r["done_at_kill"] and r["done"] == args.n - len(bad) and _failed(out) == bad)
        print(f"all {args.n} photos, kill and rerun ({counts[-1]} workers): killed after {r['killed_after_s']} s with "
              f"{r['in_manifest_at_kill']} photos in the manifest ({r['done_at_kill']} done); the rerun "
              f"({r['rerun_s']} s, exit {r['rerun_rc']}) skipped {r['skipped']}, ended with {r['done']} done and "
              f"{r['failed']} failed of {r['total']}; failures = the bad files and nothing redone: {ok}; "
              f"{args.n / (r['killed_after_s'] + r['rerun_s']):.3f} photos/s over both runs")


if __name__ == "__main__":
    main()
