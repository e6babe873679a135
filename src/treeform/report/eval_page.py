"""``report.html`` of an evaluation: summary table, box plots, per-case rows, a 3D viewer.

The page opens offline from the file system (or any static server): the viewer is three.js
vendored as classic scripts (``assets/three-modules.js``, made by ``scripts/vendor_three.py``)
and each GLB travels as a small script that sets its base64 bytes, loaded when its case is
shown — a page from ``file://`` may not fetch files or load ES modules.
"""

from __future__ import annotations

import base64
import html
import json
import shutil
from pathlib import Path

import numpy as np

__all__ = ["write_eval_report", "ASSETS"]

ASSETS = Path(__file__).resolve().parent / "assets"
"""The viewer's files shipped in the package (three-modules.js, viewer.js, THREE_LICENSE)."""

_CSS = """
body{font:14px/1.4 system-ui,sans-serif;margin:24px;color:#222;max-width:1400px}
h1{font-size:22px} h2{font-size:18px;margin-top:28px}
table{border-collapse:collapse;margin:8px 0} td,th{border:1px solid #ccd;padding:4px 8px;text-align:right;vertical-align:middle}
th{background:#eef1f5} td.l,th.l{text-align:left} td.err{color:#a00;text-align:left;max-width:260px}
img.t{height:96px;border:1px solid #dde;background:#fff} .ci{color:#778;font-size:12px}
#tf-viewer{width:100%;height:440px;border:1px solid #ccd;display:block;background:#f3f5f7}
button{font:inherit;padding:2px 10px;cursor:pointer} .note{color:#556}
"""


def _fmt(v) -> str:
    return "–" if v is None else (f"{v:.3g}" if isinstance(v, float) else html.escape(str(v)))


def _glb_script(glb: Path, key: str, folder: Path | None = None) -> str:
    """Write ``glb``'s bytes as a script ``NAME.glb.js`` in ``folder`` (default: beside it); returns its file name."""
    b64 = base64.b64encode(glb.read_bytes()).decode("ascii")
    js = (glb.parent if folder is None else Path(folder)) / (glb.name + ".js")
    js.write_text(f"(window.__tf_glb = window.__tf_glb || {{}})[{json.dumps(key)}] = \"{b64}\";\n")
    return js.name


def _box_plot_png(res: dict, columns, out_dir: Path) -> str | None:
    from PIL import Image

    from treeform.report.plots import box_plots

    methods = list(res["aggregate"])
    keys = [(k, t) for k, t in columns if k != "seconds" and k != "species_correct"
            and any(k in res["aggregate"][m]["scores"] for m in methods)]
    if not keys:
        return None
    data = {m: {k: np.array([c["methods"][m][k] for c in res["cases"]
                             if isinstance(c.get("methods", {}).get(m, {}).get(k), (int, float))], float)
                for k, _ in keys} for m in methods}
    img = box_plots(data, [k for k, _ in keys], titles=dict(keys), cols=4)
    Image.fromarray(img).save(out_dir / "boxplots.png")
    return "boxplots.png"


_FORM = (("rel_err_height", "height rel. err."), ("rel_err_trunk_diameter", "trunk diam. rel. err."),
         ("rel_err_biomass", "biomass rel. err."), ("abs_err_branching_angle_deg", "branch angle err. °"),
         ("rel_err_lai", "LAI rel. err."), ("mrt_err_pct", "MRT err. % of height"))


def _species_box_plots(res: dict, out_dir: Path) -> list:
    """Per method, the tree-form metric errors grouped by species (seed 003 Fig. 18 style)."""
    from PIL import Image

    from treeform.report.plots import box_plots

    out = []
    for m in res["aggregate"]:
        data: dict = {}
        for c in res["cases"]:
            s = c.get("methods", {}).get(m, {})
            if c.get("species") is None or "error" in s:
                continue
            for k, _ in _FORM:
                if isinstance(s.get(k), (int, float)):
                    data.setdefault(c["species"], {}).setdefault(k, []).append(float(s[k]))
        keys = [(k, t) for k, t in _FORM if any(k in d for d in data.values())]
        if not keys:
            continue
        data = {sp: {k: np.array(d.get(k, []), float) for k, _ in keys} for sp, d in sorted(data.items())}
        name = f"species_{m}.png"
        Image.fromarray(box_plots(data, [k for k, _ in keys], titles=dict(keys), cols=4)).save(out_dir / name)
        out.append((m, name))
    return out


def write_eval_report(res: dict, out_dir, *, columns) -> Path:
    """Write ``out_dir/report.html`` for the results of an evaluation.

    Parameters
    ----------
    res : dict
        ``results.json`` of :func:`treeform.evaluation.evaluate` (its ``cases`` carry the
        ``files`` the cases wrote under ``out_dir/cases/NAME/``).
    out_dir : path
    columns : sequence of (score key, title)
        The scores of the summary table and box plots, in order.

    Returns
    -------
    Path
        The page.
    """
    out_dir = Path(out_dir)
    assets = out_dir / "assets"
    assets.mkdir(parents=True, exist_ok=True)
    for name in ("three-modules.js", "viewer.js", "THREE_LICENSE"):
        shutil.copyfile(ASSETS / name, assets / name)
    methods = list(res["aggregate"])
    agg = res["aggregate"]
    cols = [(k, t) for k, t in columns if any(k in agg[m]["scores"] for m in methods)]

    h = ["<!doctype html><html><head><meta charset='utf-8'><title>treeform eval</title>",
         f"<style>{_CSS}</style></head><body>",
         "<h1>treeform eval</h1>",
         f"<p class='note'>cases <b>{html.escape(str(res['config']['cases']))}</b>, methods "
         f"<b>{html.escape(', '.join(methods))}</b>, seed {res['config']['seed']}; {len(res['cases'])} cases "
         f"({res['evaluated']} evaluated, {res['resumed']} resumed) in {res['seconds']:.1f} s. Medians over the "
         "cases with the 95 % bootstrap interval of the median.</p>",
         "<h2>Summary</h2><table id='summary'><tr><th class='l'>score</th>"
         + "".join(f"<th>{html.escape(m)}</th>" for m in methods) + "</tr>"]
    for k, t in cols:
        cells = []
        for m in methods:
            st = agg[m]["scores"].get(k)
            cells.append("<td>–</td>" if not st else
                         f"<td data-key='{k}' data-method='{html.escape(m)}'>{st['median']:.4g}"
                         f"<br><span class='ci'>[{st['ci95'][0]:.3g}, {st['ci95'][1]:.3g}]</span></td>")
        h.append(f"<tr><td class='l'>{html.escape(t)}</td>{''.join(cells)}</tr>")
    h.append("<tr><td class='l'>cases (failed)</td>" + "".join(f"<td>{agg[m]['cases']} ({agg[m]['failed']})</td>"
                                                             for m in methods) + "</tr></table>")
    box = _box_plot_png(res, cols, out_dir)
    if box:
        h.append(f"<h2>Per-case distributions</h2><img src='{box}' alt='box plots' style='max-width:100%'>")
    for m, name in _species_box_plots(res, out_dir):
        h.append(f"<h2>{html.escape(m)}: tree-form errors per species</h2>"
                 f"<img src='{name}' alt='{html.escape(m)} per species' style='max-width:100%'>")

    viewer_cases = []
    rows = []
    for c in res["cases"]:
        name = c["case"]
        files = c.get("files", {})
        base = f"cases/{name}/"
        pics = ""
        if "photo" in files:
            pics += f"<img class='t' src='{base}{files['photo']}' title='photo'>"
        if "gt_mask" in files:
            pics += f"<img class='t' src='{base}{files['gt_mask']}' title='true mask'>"
        items = []
        if "gt_glb" in files:
            items.append({"key": f"{name}/gt", "src": base + _glb_script(out_dir / base / files["gt_glb"], f"{name}/gt"),
                          "label": "ground truth"})
        cells = []
        for m in methods:
            s = c.get("methods", {}).get(m)
            f = files.get(m, {})
            if s is None or "error" in s:
                err = (s or {}).get("error") or c.get("error", "not run")
                cells.append(f"<td class='err' colspan='2'>{html.escape(err)}</td>")
                continue
            nums = " / ".join(_fmt(s.get(k)) for k in ("front_iou", "iou_side", "iou_top") if k in s) or \
                _fmt(s.get("front_iou_own"))
            thumbs = "".join(f"<img class='t' src='{base}{f[v]}' title='{html.escape(m)} {v}'>" for v in ("front", "side")
                             if v in f)
            cells.append(f"<td>{nums}</td><td class='l'>{thumbs}</td>")
            if "glb" in f:
                key = f"{name}/{m}"
                items.append({"key": key, "src": base + _glb_script(out_dir / base / f["glb"], key), "label": m})
        button = ""
        if len(items) > 1:
            viewer_cases.append((name, items))
            button = f"<button onclick='treeformShow({json.dumps(name)}, {html.escape(json.dumps(items))})'>3D</button>"
        if "error" in c:
            cells = [f"<td class='err' colspan='{2 * len(methods)}'>{html.escape(c['error'])}</td>"]
        rows.append(f"<tr><td class='l'>{html.escape(name)}<br>{_fmt(c.get('species'))} {button}</td>"
                    f"<td class='l'>{pics}</td>{''.join(cells)}</tr>")
    if viewer_cases:
        h.append("<h2>3D: ground truth beside each reconstruction</h2>"
                 "<p id='tf-viewer-title' class='note'>loading…</p><canvas id='tf-viewer'></canvas>")
    h.append("<h2>Cases</h2><table id='cases'><tr><th class='l'>case</th><th class='l'>photo, true mask</th>"
             + "".join(f"<th>{html.escape(m)}<br><span class='ci'>IoU front / side / top</span></th>"
                       f"<th class='l'>{html.escape(m)}: front, side</th>" for m in methods) + "</tr>")
    h.extend(rows)
    h.append("</table><p class='note'>three.js (MIT, assets/THREE_LICENSE) draws the 3D view.</p>")
    if viewer_cases:
        first = viewer_cases[0]
        h.append("<script src='assets/three-modules.js'></script><script src='assets/viewer.js'></script>")
        h.append(f"<script>treeformShow({json.dumps(first[0])}, {json.dumps(first[1])});</script>")
    h.append("</body></html>\n")
    page = out_dir / "report.html"
    tmp = page.with_name(page.name + ".tmp")
    tmp.write_text("\n".join(h), encoding="utf-8")
    tmp.replace(page)
    return page
