"""Throughput of ``treeform batch`` on 1 and 2 workers, with a share of bad photos.

A folder of N photos: the real photos of ../shared/data/photos (reduced to 400 px, cycled),
of which about 5 % are replaced by bad files (empty, truncated). Each worker count runs the
whole folder into a fresh output folder; reports photos/s end to end (cluster start
included), the done / failed counts and whether every bad file, and only those, failed.

Run: `python benchmarks/bench_batch.py [N]`
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PHOTOS = ROOT.parent / "shared" / "data" / "photos"


def make_folder(n: int, dest: Path) -> set:
    from PIL import Image

    src = sorted(PHOTOS.glob("*.jpg"))
    bad = set()
    for i in range(n):
        name = f"p{i:04d}.jpg"
        if i % 20 == 7:  # ~5 % bad: empty or truncated
            data = b"" if (i // 20) % 2 == 0 else src[i % len(src)].read_bytes()[:300]
            (dest / name).write_bytes(data)
            bad.add(name)
            continue
        im = Image.open(src[i % len(src)]).convert("RGB")
        im.thumbnail((400, 400))
        im.save(dest / name, quality=90)
    return bad


def main(n: int = 24):
    from treeform.batch import run_batch

    tmp = Path(tempfile.mkdtemp(prefix="treeform-bench-batch-"))
    folder = tmp / "photos"
    folder.mkdir()
    bad = make_folder(n, folder)
    print(f"{n} photos ({len(bad)} bad), 400 px, envelope route")
    print("| workers | photos/s (end to end) | seconds | done | failed | failures = the bad files |")
    print("|---|---|---|---|---|---|")
    for workers in (1, 2):
        out = tmp / f"out{workers}"
        t0 = time.perf_counter()
        res = run_batch(folder, out, workers=workers, timeout=300)
        dt = time.perf_counter() - t0
        failed = {f["photo"] for f in json.loads((out / "failures.json").read_text())}
        print(f"| {workers} | {n / dt:.3f} | {dt:.1f} | {res['done']} | {res['failed']} | {failed == bad} |",
              flush=True)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 24)
