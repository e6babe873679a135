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


MULTIVIEW = "multiview"
"""The method that needs several photos of a case (``captures:N`` cases only)."""


def parse_methods(methods, *, cases: str | None = None) -> list[str]:
    """Registered tree-reconstruction methods named in ``methods`` ("envelope,learned" or a list).

    The single-photo methods score on every kind of case; ``multiview`` needs the photos
    around a tree that only ``captures:N`` cases have (checked when ``cases`` is given).
    """
    from treeform.methods import METHODS

    names = [m.strip() for m in (methods.split(",") if isinstance(methods, str) else methods) if m.strip()]
    if not names:
        raise InputError("--methods: name at least one method")
    known = [k for k, v in METHODS.items() if v[2].endswith(":reconstruct")] + [MULTIVIEW]
    for m in names:
        if m not in known:
            raise InputError(f"--methods {m}: not a tree-reconstruction method (known: {', '.join(known)})")
    if MULTIVIEW in names and cases is not None and not str(cases).startswith("captures:"):
        raise InputError(f"--methods {MULTIVIEW}: needs photos all around each tree: use --cases captures:N")
    return list(dict.fromkeys(names))


def _entry(method: str):
    from treeform.methods import METHODS

    module, func = METHODS[method][2].split(":")
    return getattr(importlib.import_module(module), func)


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return f"{type(exc).__name__}: {text}"[:300]


def _save_image(path: Path, img) -> str:
    from PIL import Image

    Image.fromarray(img).save(path, quality=88) if path.suffix == ".jpg" else Image.fromarray(img).save(path)
    return path.name


def _over_white(rgba):
    a = rgba[..., 3:4].astype(np.float32) / 255.0
    return np.clip(rgba[..., :3] * a + 255.0 * (1.0 - a), 0, 255).astype(np.uint8)


def _thumbs(rec, folder: Path, method: str) -> dict:
    """The method's front view (the photo's frame) and side view as PNGs over white."""
    from treeform.report import photo_window

    front = rec.renders["front"]
    win = photo_window(front.camera, rec.camera)
    return {"front": _save_image(folder / f"{method}_front.png", _over_white(front.color[win])),
            "side": _save_image(folder / f"{method}_side.png", _over_white(rec.renders["side"].color))}


def _multiview_pictures(rec, case, folder: Path, method: str, glb: bool) -> dict:
    """The multi-view tree, aligned to the truth: drawn by the first photo's true camera (front)
    and from 90° in that camera's frame (side), and its viewer GLB in the same frame as the truth's."""
    from treeform.evaluation.scores import align_multiview, aligned_view_mesh
    from treeform.render import Renderer
    from treeform.sfm.result import render_camera
    from treeform.structures.camera import box_camera

    tree, _ = align_multiview(rec, case.cameras)
    first = case.cameras[min(case.cameras)]
    turned = aligned_view_mesh(tree, case)
    lo, hi = turned.bounds()
    renderer = Renderer(render_camera(first["K"], first["cam_to_world"], first["size"]))
    try:
        front = renderer.render(tree.mesh).color
        renderer.camera = box_camera(np.asarray(lo, np.float64), np.asarray(hi, np.float64), 90.0, 0.0, 320)
        side = renderer.render(turned).color
    finally:
        renderer.release()
    out = {"front": _save_image(folder / f"{method}_front.png", _over_white(front)),
           "side": _save_image(folder / f"{method}_side.png", _over_white(side))}
    if glb:
        out["glb"] = _viewer_glb(turned, folder / f"{method}.glb")
    return out


def _viewer_glb(mesh, path: Path, *, texture_size: int = 256) -> str:
    """A light GLB for the report's viewer: textures at most ``texture_size`` px, no normal maps."""
    from dataclasses import replace

    import cv2

    from treeform.io.gltf import write_glb
    from treeform.structures import Mesh

    def small(tex):
        if tex is None or max(tex.shape[:2]) <= texture_size:
            return tex
        s = texture_size / max(tex.shape[:2])
        return cv2.resize(tex, (max(1, round(tex.shape[1] * s)), max(1, round(tex.shape[0] * s))),
                          interpolation=cv2.INTER_AREA)

    parts = [replace(p, material=replace(p.material, texture=small(p.material.texture), normal_texture=None))
             for p in mesh.parts]
    write_glb(Mesh(parts), path)
    return path.name


def run_case(name: str, methods: list, *, seed: int = 0, size: int = 256, view_size: int = 160, folder=None,
             glb: bool = False) -> dict:
    """Load case ``name``, reconstruct it with each method and score it; never raises.

    ``folder``: where the case's pictures go (photo, true mask, each method's front and side
    view) and, with ``glb``, the true tree and each reconstruction as GLBs in the photo
    camera's frame as they are scored (a single-photo tree at the true height, a multi-view tree
    as its cameras place it; what the report's 3D viewer shows side by side).

    Returns
    -------
    dict
        ``{"case", "mask_source", "species", "methods": {method: scores | {"error": line}}}``;
        an ``"error"`` at the top when the case itself could not be made. Each method's
        scores carry ``seconds`` (total) and ``stages`` (seconds per pipeline stage).
    """
    from treeform.evaluation.cases import display_name, load_case
    from treeform.evaluation.scores import score_multiview, score_reconstruction

    res = {"case": display_name(name), "source": name, "size": int(size)}
    try:
        case = load_case(name, size=size)
    except Exception as exc:  # a corrupt case costs only this case
        res["error"] = _one_line(exc)
        return res
    try:
        res.update(mask_source=case.mask_source, species=case.species, methods={})
        files = {}
        if folder is not None:
            folder = Path(folder)
            folder.mkdir(parents=True, exist_ok=True)
            files["photo"] = _save_image(folder / "photo.jpg", case.image)
            if case.gt_mask is not None:
                files["gt_mask"] = _save_image(folder / "gt_mask.png", (np.asarray(case.gt_mask) * 255).astype(np.uint8))
            if glb and case.gt_mesh is not None:
                from treeform.evaluation.scores import canonical_mesh

                gt = canonical_mesh(case.gt_mesh, case.gt_skeleton.positions[0], azimuth_deg=case.azimuth_deg)
                files["gt_glb"] = _viewer_glb(gt, folder / "gt.glb")
        for m in methods:
            stages = {}

            def progress(stage, event, seconds, _st=stages):
                if event == "end":
                    _st[stage] = round(_st.get(stage, 0.0) + float(seconds), 4)

            t0 = time.perf_counter()
            try:
                if m == MULTIVIEW:
                    if case.photos is None:
                        raise InputError("the multi-view method needs a capture case (--cases captures:N)")
                    rec = _entry(m)(case.photos, seed=seed, progress=progress)
                    seconds = time.perf_counter() - t0
                    scores = score_multiview(rec, case, view_size=view_size)
                else:
                    rec = _entry(m)(case.image, seed=seed, progress=progress)
                    seconds = time.perf_counter() - t0
                    scores = score_reconstruction(rec, case, view_size=view_size)
            except Exception as exc:  # a method that raises on one case costs only that case
                res["methods"][m] = {"error": _one_line(exc)}
                continue
            res["methods"][m] = {**scores, "seconds": round(seconds, 3), "stages": stages}
            if folder is not None:
                try:
                    if m == MULTIVIEW:
                        files[m] = _multiview_pictures(rec, case, folder, m, glb)
                        continue
                    files[m] = _thumbs(rec, folder, m)
                    if glb and case.gt_mesh is not None:
                        from treeform.evaluation.scores import canonical_mesh, reconstruction_scale

                        root = rec.skeleton.positions[0]
                        files[m]["glb"] = _viewer_glb(canonical_mesh(rec.mesh, root, scale=reconstruction_scale(rec, case)),
                                                      folder / f"{m}.glb")
                except Exception as exc:  # pictures are extras: their failure is noted, the scores stay
                    files[m] = {"error": _one_line(exc)}
        if files:
            res["files"] = files
    finally:
        case.close()  # a capture's photos
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
             workers: int | None = None, scheduler: str | None = None, viewer: int = 4, report: bool = True,
             progress=None) -> dict:
    """Score tree-reconstruction methods on the same cases (``treeform eval``).

    Parameters
    ----------
    cases : str
        ``synthetic:N`` (N trees with full 3D ground truth, seeded by ``seed``), ``captures:N``
        (N trees photographed all around, for ``multiview`` beside the single-photo methods) or
        ``photos:DIR``.
    methods : str or list
        Registered methods, e.g. ``"envelope,learned"``; ``multiview`` with ``captures:N``.
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
    viewer : int
        The first ``viewer`` cases keep GLBs of the true tree and each reconstruction for
        the report's 3D viewer (about 15 MB a case: GLBs and their viewer scripts); the others keep
        pictures only.
    report : bool
        Write ``report.html`` (with ``out``): :func:`treeform.report.write_eval_report`.
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

    from treeform._shared.checks import check_int
    from treeform._shared.cluster import check_cluster
    from treeform._shared.rng import check_seed
    from treeform.io.outputs import check_out_dir

    check_seed(seed)
    check_cluster(workers, scheduler)
    check_int(viewer, "viewer", 0, 1000)
    names = case_names(cases, seed=seed)
    meths = parse_methods(methods, cases=cases)
    if int(size) < 64:
        raise InputError(f"--size {size}: expected >= 64")
    out_dir = check_out_dir(out) if out is not None else None
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
                if ("error" not in r and r.get("size") == int(size)
                        and all(m in r.get("methods", {}) and "error" not in r["methods"][m] for m in meths)):
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

    def task_args(n):
        folder = out_dir / CASE_DIR / display_name(n) if out_dir is not None else None
        return dict(seed=seed, size=size, folder=folder, glb=names.index(n) < int(viewer))

    if todo and workers == 0:
        for n in todo:
            finish(n, run_case(n, meths, **task_args(n)))
    elif todo:
        from distributed import as_completed

        from treeform._shared.cluster import dask_client

        client, cluster = dask_client(workers or os.cpu_count() or 1, scheduler)
        try:
            futs = {client.submit(run_case, n, meths, **task_args(n), key=f"eval-{display_name(n)}-{seed}",
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
        if report:
            from treeform.evaluation.tables import SUMMARY_SCORES
            from treeform.report import write_eval_report

            write_eval_report(res, out_dir, columns=SUMMARY_SCORES)
    return res
