"""A fixed evaluation: synthetic cases, 3 per species by default, every single-photo method.

    python benchmarks/bench_eval.py [--cases 21] [--methods envelope,learned] [--workers 2] [--write]
    python benchmarks/bench_eval.py --captures 7 --methods envelope,learned,abs,multiview [--write]

Runs :func:`treeform.evaluation.evaluate` (the same as ``treeform eval``) into a fresh
folder and prints the methods x scores table (median [95 % interval of the median]) with
the wall-clock time; ``--write`` puts it into BENCHMARKS.md between ``<!-- eval:begin -->``
and ``<!-- eval:end -->`` and into the README's evaluation section. Scores, not timings,
are the point: every later change to a method shows its effect here.

``--captures N`` scores N trees photographed all around instead (``--cases captures:N``:
the multi-view method beside the single-photo ones, which see the first photo); ``--write``
then puts its table into BENCHMARKS.md between ``<!-- eval-captures:begin -->`` and
``<!-- eval-captures:end -->``.
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import tempfile
import time
from pathlib import Path

from _common import machine, write_section  # benchmarks/ is on sys.path when a script runs

ROOT = Path(__file__).resolve().parents[1]


def screenshot(page_path: Path, dest: Path) -> None:
    """The report's summary table beside its 3D viewer, as headless Chromium shows them."""
    import shutil

    from PIL import Image
    from playwright.sync_api import sync_playwright

    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=exe, args=["--use-gl=swiftshader", "--enable-unsafe-swiftshader",
                                                               "--no-sandbox"])
        page = browser.new_page(viewport={"width": 1280, "height": 900})
        page.goto(page_path.as_uri())
        page.wait_for_function("window.treeformViewerState && window.treeformViewerState.done", timeout=180_000)
        tmp = dest.with_suffix(".parts")
        tmp.mkdir(exist_ok=True)
        page.locator("#summary").screenshot(path=str(tmp / "summary.png"))
        page.locator("#tf-viewer").screenshot(path=str(tmp / "viewer.png"))
        browser.close()
    # the summary table beside the 3D viewer (truth, then each method), on one white canvas
    table, viewer = Image.open(tmp / "summary.png").convert("RGB"), Image.open(tmp / "viewer.png").convert("RGB")
    scale = table.height / viewer.height
    viewer = viewer.resize((round(viewer.width * scale), table.height), Image.LANCZOS)
    canvas = Image.new("RGB", (table.width + 16 + viewer.width, table.height), "white")
    canvas.paste(table, (0, 0))
    canvas.paste(viewer, (table.width + 16, 0))
    if canvas.width > 1400:
        canvas = canvas.resize((1400, round(canvas.height * 1400 / canvas.width)), Image.LANCZOS)
    canvas.save(dest, quality=88)
    shutil.rmtree(tmp)
    print(f"screenshot: {dest}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cases", type=int, default=21)
    ap.add_argument("--captures", type=int, default=0, help="score N capture cases instead (for multiview)")
    ap.add_argument("--methods", default="envelope,learned")
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, default=None, help="keep the results here (default: a temporary folder)")
    ap.add_argument("--write", action="store_true", help="put the table into BENCHMARKS.md and the README")
    ap.add_argument("--screenshot", type=Path, default=None,
                    help="save a picture of report.html here (headless Chromium; e.g. docs/images/eval_report.jpg)")
    a = ap.parse_args()
    from treeform.evaluation import evaluate
    from treeform.evaluation.cases import CAPTURE_SIZE, CAPTURE_VIEWS
    from treeform.evaluation.tables import markdown_table

    with tempfile.TemporaryDirectory() as tmp:
        out = a.out or Path(tmp) / "eval"
        t0 = time.perf_counter()
        spec = f"captures:{a.captures}" if a.captures else f"synthetic:{a.cases}"
        res = evaluate(spec, a.methods, out, seed=a.seed, workers=a.workers)
        wall = time.perf_counter() - t0
        if a.screenshot is not None:
            screenshot(out / "report.html", a.screenshot)
    table = markdown_table(res)
    per_method = ", ".join(f"{m} {s['scores']['seconds']['median']:.2f} s" for m, s in res["aggregate"].items()
                           if "seconds" in s["scores"])
    kind = f"--captures {a.captures}" if a.captures else f"--cases {a.cases}"
    what = (f"{a.captures} capture cases ({CAPTURE_VIEWS} photos of {CAPTURE_SIZE} px around each tree)" if a.captures
            else f"{a.cases} synthetic cases")
    text = (f"{what} (seed {a.seed}), methods {a.methods}: {wall:.0f} s wall-clock on "
            f"{a.workers} Dask worker(s), cluster start included (median reconstruction per case: {per_method}).\n"
            f"Machine: {machine()}. Command: `python benchmarks/bench_eval.py {kind} "
            f"--methods {a.methods} --workers {a.workers}`.\n\n{table}")
    print(text)
    if a.write and a.captures:
        write_section(ROOT / "BENCHMARKS.md", "eval-captures",
                      "## Evaluation on captures: several photos against one (`treeform eval --cases captures:N`)\n\n"
                      + text)
        print("wrote the eval-captures section of BENCHMARKS.md")
    elif a.write:
        write_section(ROOT / "BENCHMARKS.md", "eval", "## Evaluation against ground truth (`treeform eval`)\n\n" + text)
        readme = ROOT / "README.md"
        md = readme.read_text()
        new = re.sub(r"(<!-- eval:begin -->\n).*?(<!-- eval:end -->)", lambda m: m.group(1) + table + m.group(2), md,
                     flags=re.S)
        if new == md and "EVAL_TABLE" in md:
            new = md.replace("EVAL_TABLE", f"<!-- eval:begin -->\n{table}<!-- eval:end -->")
        readme.write_text(new)
        print("wrote the eval sections of BENCHMARKS.md and README.md")
    return 0


if __name__ == "__main__":
    sys.exit(main())
