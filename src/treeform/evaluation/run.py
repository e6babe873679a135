""":func:`evaluate`: methods x cases, one Dask task per case, resumable, ``results.json``."""

from __future__ import annotations

import importlib
import json
import math
import os
import time
from pathlib import Path

import numpy as np

from treeform._shared.errors import InputError

__all__ = ["evaluate", "parse_methods", "aggregate"]

CASE_DIR = "cases"


def parse_methods(methods) -> list[str]:
    """Registered single-photo methods named in ``methods`` ("envelope,learned" or a list)."""
    from treeform.methods import METHODS

    names = [m.strip() for m in (methods.split(",") if isinstance(methods, str) else methods) if m.strip()]
    if not names:
        raise InputError("--methods: name at least one method")
    photo = [k for k, v in METHODS.items() if v[2].endswith(":reconstruct")]
    for m in names:
        if m not in photo:
            raise InputError(f"--methods {m}: not a single-photo method (known: {', '.join(photo)})")
    return list(dict.fromkeys(names))


def _entry(method: str):
    from treeform.methods import METHODS

    module, func = METHODS[method][2].split(":")
    return getattr(importlib.import_module(module), func)


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return f"{type(exc).__name__}: {text}"[:300]


def run_case(name: str, methods: list, *, seed: int = 0, size: int = 256, view_size: int = 160) -> dict:
    """Load case ``name``, reconstruct it with each method and score it; never raises.

    Returns
    -------
    dict
        ``{"case", "mask_source", "species", "methods": {method: scores | {"error": line}}}``;
        an ``"error"`` at the top when the case itself could not be made. Each method's
        scores carry ``seconds`` (total) and ``stages`` (seconds per pipeline stage).
    """
    from treeform.evaluation.cases import display_name, load_case
    from treeform.evaluation.scores import score_reconstruction

    res = {"case": display_name(name), "source": name}
    try:
        case = load_case(name, size=size)
    except Exception as exc:  # a corrupt case costs only this case
        res["error"] = _one_line(exc)
        return res
    res.update(mask_source=case.mask_source, species=case.species, methods={})
    for m in methods:
        stages = {}

        def progress(stage, event, seconds, _st=stages):
            if event == "end":
                _st[stage] = round(_st.get(stage, 0.0) + float(seconds), 4)

        t0 = time.perf_counter()
        try:
            rec = _entry(m)(case.image, seed=seed, progress=progress)
            seconds = time.perf_counter() - t0
            scores = score_reconstruction(rec, case, view_size=view_size)
        except Exception as exc:  # a method that raises on one case costs only that case
            res["methods"][m] = {"error": _one_line(exc)}
            continue
        res["methods"][m] = {**scores, "seconds": round(seconds, 3), "stages": stages}
    return res


def _bootstrap_ci(values: np.ndarray, rng, n: int = 1000) -> list:
    if len(values) < 2:
        return [float(values[0])] * 2 if len(values) else [math.nan, math.nan]
    meds = np.median(values[rng.integers(0, len(values), (n, len(values)))], axis=1)
    return [round(float(x), 4) for x in np.percentile(meds, [2.5, 97.5])]


def aggregate(cases: list, methods: list, *, seed: int = 0) -> dict:
    """Median, 95 % bootstrap interval of the median, mean and n of every score per method."""
    out = {}
    for m in methods:
        rows = [c["methods"][m] for c in cases if "methods" in c and m in c["methods"]]
        ok = [r for r in rows if "error" not in r]
        keys = sorted({k for r in ok for k, v in r.items() if isinstance(v, (int, float))})
        rng = np.random.default_rng([int(seed), 17])
        stats = {}
        for k in keys:
            v = np.array([r[k] for r in ok if isinstance(r.get(k), (int, float)) and math.isfinite(r[k])], float)
            if len(v):
                stats[k] = {"median": round(float(np.median(v)), 4), "ci95": _bootstrap_ci(v, rng),
                            "mean": round(float(v.mean()), 4), "n": int(len(v))}
        out[m] = {"cases": len(rows), "failed": len(rows) - len(ok), "scores": stats}
    return out


def _write_json(path: Path, obj) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(obj, indent=1))
    os.replace(tmp, path)


def evaluate(cases: str = "synthetic:21", methods="envelope", out=None, *, seed: int = 0, size: int = 256,
             workers: int | None = None, scheduler: str | None = None, progress=None) -> dict:
    """Score single-photo methods on the same cases (``treeform eval``).

    Parameters
    ----------
    cases : str
        ``synthetic:N`` (N trees with full 3D ground truth, seeded by ``seed``) or ``photos:DIR``.
    methods : str or list
        Registered single-photo methods, e.g. ``"envelope,learned"``.
    out : path, optional
        Output folder: ``cases/NAME.json`` per finished case (a rerun skips them) and
        ``results.json`` (config, per-case scores, aggregate).
    seed : int
        Seed of the synthetic cases and of every method.
    size : int
        Edge of the synthetic photos in pixels.
    workers : int, optional
        Local Dask worker processes; 0 runs in this process (no Dask). Default: the cores.
    scheduler : str, optional
        A running Dask scheduler (``tcp://HOST:PORT``) instead of a local cluster.
    progress : callable, optional
        ``progress(done, total)`` after each case.

    Returns
    -------
    dict
        The content of ``results.json``.

    Examples
    --------
    >>> r = evaluate("synthetic:2", "envelope", workers=0)  # doctest: +SKIP
    >>> r["aggregate"]["envelope"]["scores"]["iou_side"]["median"]  # doctest: +SKIP
    """
    from treeform.evaluation.cases import case_names, display_name

    names = case_names(cases, seed=seed)
    meths = parse_methods(methods)
    if int(size) < 64:
        raise InputError(f"--size {size}: expected >= 64")
    out_dir = Path(out) if out is not None else None
    done: dict = {}
    if out_dir is not None:
        (out_dir / CASE_DIR).mkdir(parents=True, exist_ok=True)
        for n in names:
            f = out_dir / CASE_DIR / f"{display_name(n)}.json"
            if f.exists():
                try:
                    r = json.loads(f.read_text())
                except ValueError:
                    continue
                if "error" not in r and all(m in r.get("methods", {}) and "error" not in r["methods"][m] for m in meths):
                    done[n] = r
    todo = [n for n in names if n not in done]
    results = dict(done)
    t0 = time.perf_counter()

    def finish(name, r):
        results[name] = r
        if out_dir is not None:
            _write_json(out_dir / CASE_DIR / f"{display_name(name)}.json", r)
        if progress is not None:
            progress(len(results), len(names))

    if progress is not None:
        progress(len(results), len(names))
    if todo and workers == 0:
        for n in todo:
            finish(n, run_case(n, meths, seed=seed, size=size))
    elif todo:
        from distributed import as_completed

        from treeform._shared.cluster import dask_client

        client, cluster = dask_client(workers or os.cpu_count() or 1, scheduler)
        try:
            futs = {client.submit(run_case, n, meths, seed=seed, size=size, key=f"eval-{display_name(n)}-{seed}",
                                  pure=False): n for n in todo}
            for fut in as_completed(futs):
                n = futs[fut]
                try:
                    r = fut.result()
                except Exception as exc:  # a worker lost on one case (killed, out of memory)
                    r = {"case": display_name(n), "source": n, "error": _one_line(exc)}
                finish(n, r)
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    ordered = [results[n] for n in names]
    res = {"config": {"cases": cases, "methods": meths, "seed": seed, "size": size},
           "seconds": round(time.perf_counter() - t0, 2), "evaluated": len(todo), "resumed": len(done),
           "aggregate": aggregate(ordered, meths, seed=seed), "cases": ordered}
    if out_dir is not None:
        _write_json(out_dir / "results.json", res)
    return res
