"""``report.html`` for one run (``reconstruct`` / ``grow`` / ``multiview`` / ``cloud`` with ``--report``).

Reads what the run wrote — ``preview.png``, ``metrics.json`` (with its stage ``timings``),
``tree.glb`` — or what the caller hands over (the metrics, a GLB elsewhere, pictures) and
lays it out: the pictures, the metrics, the seconds per stage, and the model in the 3D
viewer (the same vendored three.js viewer as the evaluation's page; opens offline from the
file system).
"""

from __future__ import annotations

import html
import json
import shutil
from pathlib import Path

import numpy as np

from treeform._shared.errors import InputError

__all__ = ["write_run_report"]

PREVIEW_CAPTION = "preview: photo, segmentation, front / side / top renders"


def _flat(d: dict, prefix: str = "") -> list:
    rows = []
    for k, v in d.items():
        if k in ("timings",):
            continue
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            rows.extend(_flat(v, key + "."))
        elif isinstance(v, (list, tuple)) and all(isinstance(x, (int, float)) for x in v):
            rows.append((key, ", ".join(f"{x:.4g}" if isinstance(x, float) else str(x) for x in v)))
        elif isinstance(v, float):
            rows.append((key, f"{v:.4g}"))
        elif v is None or isinstance(v, (int, str, bool)):
            rows.append((key, str(v)))
    return rows


def write_run_report(out_dir, *, title: str, pictures=(), progress=None, metrics: dict | None = None,
                     glb=None, preview_caption: str = PREVIEW_CAPTION) -> Path:
    """Write ``out_dir/report.html`` for the outputs of a finished run.

    Parameters
    ----------
    out_dir : path
        The run's output folder (``metrics.json`` must exist unless ``metrics`` is given;
        ``preview.png`` and ``tree.glb`` are shown when present).
    title : str
    pictures : sequence of (caption, ndarray (H, W, 3 or 4) uint8)
        Extra pictures (e.g. the predicted RBV), saved beside the page as ``report_N.png``.
    progress : callable, optional
        ``progress(stage, event, seconds)`` for the stage ``report``.
    metrics : dict, optional
        The run's metrics (with their stage ``timings``), instead of ``out_dir/metrics.json``.
    glb : path, optional
        The model for the 3D viewer, instead of ``out_dir/tree.glb``; it may lie elsewhere:
        its bytes go into ``out_dir`` as ``NAME.glb.js``.
    preview_caption : str
        The caption of ``preview.png`` (what the run's preview shows).

    Returns
    -------
    Path
    """
    from PIL import Image

    from treeform._shared.timing import StageTimer
    from treeform.report.eval_page import _CSS, ASSETS, _glb_script

    out_dir = Path(out_dir)
    source = "metrics.json" if metrics is None else None
    if metrics is None:
        try:
            metrics = json.loads((out_dir / "metrics.json").read_text())
        except (OSError, ValueError) as exc:
            raise InputError(f"{out_dir}: no readable metrics.json for the report ({exc})") from None
    glb = out_dir / "tree.glb" if glb is None else Path(glb)
    if not glb.is_file() and glb != out_dir / "tree.glb":
        raise InputError(f"{glb}: no such GLB for the report")
    timer = StageTimer(progress)
    with timer.stage("report"):
        pics = []
        if (out_dir / "preview.png").exists():
            pics.append((preview_caption, "preview.png"))
        for i, (caption, img) in enumerate(pictures):
            name = f"report_{i}.png"
            Image.fromarray(np.asarray(img, np.uint8)).save(out_dir / name)
            pics.append((caption, name))
        h = ["<!doctype html><html><head><meta charset='utf-8'>",
             f"<title>{html.escape(title)}</title><style>{_CSS}</style></head><body>",
             f"<h1>{html.escape(title)}</h1>"]
        for caption, name in pics:
            h.append(f"<h2>{html.escape(caption)}</h2><img src='{name}' style='max-width:100%'>")
        if glb.exists():
            assets = out_dir / "assets"
            assets.mkdir(exist_ok=True)
            for name in ("three-modules.js", "viewer.js", "THREE_LICENSE"):
                shutil.copyfile(ASSETS / name, assets / name)
            item = [{"key": "tree", "src": _glb_script(glb, "tree", out_dir), "label": glb.name}]
            h.append("<h2>3D</h2><p id='tf-viewer-title' class='note'>loading…</p><canvas id='tf-viewer'></canvas>")
        h.append(f"<h2>Metrics{f' ({source})' if source else ''}</h2><table id='metrics'>")
        h.extend(f"<tr><td class='l'>{html.escape(k)}</td><td data-key='{html.escape(k)}'>{html.escape(v)}</td></tr>"
                 for k, v in _flat(metrics))
        h.append("</table>")
        t = metrics.get("timings") or {}
        if t:
            h.append("<h2>Seconds per stage</h2><table id='timings'>"
                     + "".join(f"<tr><td class='l'>{html.escape(k)}</td><td>{v:.3f}</td></tr>" for k, v in t.items())
                     + f"<tr><th class='l'>total</th><th>{sum(t.values()):.3f}</th></tr></table>")
        if glb.exists():
            h.append("<script src='assets/three-modules.js'></script><script src='assets/viewer.js'></script>")
            h.append(f"<script>treeformShow({json.dumps(title)}, {json.dumps(item)});</script>")
        h.append("</body></html>\n")
        page = out_dir / "report.html"
        tmp = page.with_name(page.name + ".tmp")
        tmp.write_text("\n".join(h), encoding="utf-8")
        tmp.replace(page)
    return page
