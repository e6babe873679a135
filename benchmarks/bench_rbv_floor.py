"""How well can any single-view RBV predictor do on our trees? Baselines and an observability floor.

The cascaded RBV network (seed 003 §4.2.3) reads one front mask. The sectors that face the
camera's left and right (within 45° of the image plane's X axis) are seen edge-on in the
silhouette; the sectors facing toward and away from the camera are not seen at all. This
script measures, on the test split of a dataset of ``treeform dataset generate``, the mean
absolute error (height-normalised radii, the paper's Table 1 unit) of:

- **species mean**: every sector predicted as the training split's mean for the species
  (what a network that only recognised the species would achieve);
- **visible oracle**: the X-facing sectors copied from the truth, each hidden sector
  predicted as the mean of the visible ones in its layer — a predictor that reads the
  silhouette perfectly and knows nothing else; its error is a floor for mask-only methods
  up to what can be learned of the hidden half from the visible one.

Run: `.venv/bin/python benchmarks/bench_rbv_floor.py --train out/data/train --test out/data/test`
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def load_rbv(directory) -> tuple[list, np.ndarray]:
    """The five RBV levels (list of (N, n, n) arrays) and the species ids (N,) of a dataset."""
    from treeform.dataset.loader import SyntheticDataset
    from treeform.dataset.storage import decode_sample

    ds = SyntheticDataset(directory)
    levels, species = [[] for _ in range(5)], []
    for i in range(len(ds)):
        s = decode_sample(ds.members(i, ("json",)))
        for lv in range(5):
            levels[lv].append(np.asarray(s["rbv"][lv], np.float64))
        species.append(int(s["species_id"]))
    return [np.stack(v) for v in levels], np.asarray(species)


def visible_sectors(n: int) -> np.ndarray:
    """Sectors (of ``n``) whose centre lies within 45° of the ±X axis (seen edge-on from the front)."""
    centre = (np.arange(n) + 0.5) * 2 * np.pi / n
    return np.abs(np.cos(centre)) >= np.cos(np.pi / 4) - 1e-9


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--train", default=str(ROOT / "out" / "data" / "train"))
    ap.add_argument("--test", default=str(ROOT / "out" / "data" / "test"))
    args = ap.parse_args()
    tr, s_tr = load_rbv(args.train)
    te, s_te = load_rbv(args.test)
    rows = []
    print("| level | LxS | species mean | visible oracle | visible oracle, hidden sectors only |\n|---|---|---|---|---|")
    for lv in range(5):
        n = te[lv].shape[-1]
        mean_pred = np.empty_like(te[lv])
        for sp in np.unique(s_te):
            pool = tr[lv][s_tr == sp] if (s_tr == sp).any() else tr[lv]
            mean_pred[s_te == sp] = pool.mean(0)
        e_mean = float(np.abs(mean_pred - te[lv]).mean())
        vis = visible_sectors(n)
        if vis.all() or not vis.any():
            e_or = e_hid = float("nan")
        else:
            est = te[lv].copy()
            est[:, :, ~vis] = te[lv][:, :, vis].mean(2, keepdims=True)
            err = np.abs(est - te[lv])
            e_or, e_hid = float(err.mean()), float(err[:, :, ~vis].mean())
        rows.append({"level": lv + 1, "n": n, "species_mean": e_mean, "visible_oracle": e_or, "hidden_only": e_hid})
        fmt = lambda v: "—" if np.isnan(v) else f"{100 * v:.2f} %"  # noqa: E731
        print(f"| {lv + 1} | {n}x{n} | {fmt(e_mean)} | {fmt(e_or)} | {fmt(e_hid)} |")
    (ROOT / "out").mkdir(exist_ok=True)
    (ROOT / "out" / "bench_rbv_floor.json").write_text(json.dumps(rows, indent=2))


if __name__ == "__main__":
    main()
