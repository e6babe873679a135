"""Synthetic dataset generation (seed 003 §4.2.1): throughput on Dask, stage times, mask agreement.

- **throughput**: ``generate_dataset`` of N samples at 256² on a LocalCluster of 1 and of 2
  workers; end to end (cluster start, worker warm-up, shard writing included) and steady
  state (from the moment every worker has finished two samples to the last sample);
- **stages**: median seconds of each step of one sample in-process;
- **mask agreement**: for K samples, the stored mask (decoded from its shard) against a fresh,
  background-free render of the same scene at the same sampling (IoU), and against an
  independent 4x-MSAA render at the image size (a different sampling pattern, for scale).

Run: ``python benchmarks/bench_dataset.py [N] [K]`` (defaults 120 and 30).
"""

from __future__ import annotations

import shutil
import statistics
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import machine  # noqa: E402


def throughput(n: int, workers: int) -> tuple[float, float]:
    from treeform.dataset import generate_dataset

    stamps = []
    tmp = Path(tempfile.mkdtemp())
    try:
        t0 = time.perf_counter()
        res = generate_dataset(tmp / "ds", n=n, workers=workers, seed=0, shard_size=1000,
                               progress=lambda done, total: stamps.append((done, time.perf_counter())))
        total = time.perf_counter() - t0
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    assert res.generated == n, res
    k = min(2 * workers, n - 2)
    steady = (stamps[-1][0] - stamps[k][0]) / (stamps[-1][1] - stamps[k][1])
    return n / total, steady


def stages(repeat: int = 8) -> dict:
    """Median seconds per stage of one sample, in-process with one rasterizer thread (as a worker runs it).

    Stages: grow, leaves, mesh, render, labels (down-sampling), background (composite and
    sensor noise), rbv, and encode (the PNG / JSON members a worker sends to be written).
    """
    import os

    os.environ["LP_NUM_THREADS"] = "1"  # before the GL context exists: the workers' setting
    from treeform.dataset.storage import encode_sample
    from treeform.dataset.synthetic import SampleOptions, make_sample

    make_sample(0, 0, SampleOptions())  # warm-up: GL context, texture variants, compiled kernels
    rows = []
    for i in range(1, repeat + 1):
        times = {}
        t0 = time.perf_counter()
        s = make_sample(0, i, SampleOptions(),
                        progress=lambda stage, event, sec: times.update({stage: sec}) if event == "end" else None)
        t1 = time.perf_counter()
        encode_sample(s)
        times["encode"] = time.perf_counter() - t1
        times["total"] = time.perf_counter() - t0
        rows.append(times)
    return {k: statistics.median(r[k] for r in rows) for k in rows[0]}


def agreement(k: int) -> tuple[list, list]:
    from treeform.dataset import generate_dataset
    from treeform.dataset.loader import SyntheticDataset
    from treeform.dataset.synthetic import SampleOptions, make_sample
    from treeform.render import Renderer

    tmp = Path(tempfile.mkdtemp())
    same, msaa = [], []
    try:
        generate_dataset(tmp / "ds", n=k, workers=2, seed=1)
        ds = SyntheticDataset(tmp / "ds")
        for i in range(k):
            stored = ds[i]["mask"] > 0
            s = make_sample(1, i, SampleOptions())  # the scene again, in this process
            f, size = 2, stored.shape[0]
            res = Renderer(replace(s.camera, width=size * f, height=size * f), samples=1,
                           lighting=s.lighting).render(s.mesh)
            alpha = 2 * res.mask.reshape(size, f, size, f).sum(axis=(1, 3)) >= f * f
            same.append((alpha & stored).sum() / (alpha | stored).sum())
            ms = Renderer(s.camera, samples=4, lighting=s.lighting).render(s.mesh).color[..., 3] >= 128
            msaa.append((ms & stored).sum() / (ms | stored).sum())
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return same, msaa


def main():
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 120
    k = int(sys.argv[2]) if len(sys.argv) > 2 else 30
    print(f"machine: {machine()}")
    st = stages()
    print("one sample in-process, one rasterizer thread (256², medium LOD, 2x supersampling), medians of 8 (ms):")
    print("| " + " | ".join(st) + " |")
    print("|" + "---|" * len(st))
    print("| " + " | ".join(f"{v * 1000:.1f}" for v in st.values()) + " |")
    print("| workers | samples | end to end (samples/s) | steady state (samples/s) |")
    print("|---|---|---|---|")
    rates = {}
    for w in (1, 2):
        e2e, steady = throughput(n, w)
        rates[w] = steady
        print(f"| {w} | {n} | {e2e:.2f} | {steady:.2f} |")
    print(f"speed-up 2 vs 1 worker (steady state): {rates[2] / rates[1]:.2f}x")
    same, msaa = agreement(k)
    print(f"mask vs fresh background-free render, same sampling, {k} samples: min IoU {min(same):.4f}, "
          f"median {np.median(same):.4f}")
    print(f"mask vs independent 4x-MSAA render at 256²: median IoU {np.median(msaa):.3f}, min {min(msaa):.3f}")


if __name__ == "__main__":
    main()
