"""The evaluation's report.html in a real browser (headless Chromium through playwright)."""

import shutil

import numpy as np
import pytest

CHROMIUM = next((p for p in (shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome")) if p), None)


@pytest.fixture(scope="module")
def report(tmp_path_factory, gl):
    from treeform.evaluation import evaluate

    out = tmp_path_factory.mktemp("eval")
    res = evaluate("synthetic:2", "envelope", out, workers=0, size=128, viewer=1)
    return out, res


def test_the_page_holds_the_numbers_and_pictures_of_the_results(report):
    out, res = report
    page = (out / "report.html").read_text()
    med = res["aggregate"]["envelope"]["scores"]["iou_side"]["median"]
    assert f"data-key='iou_side' data-method='envelope'>{med:.4g}" in page
    for c in res["cases"]:
        for f in (c["files"]["photo"], c["files"]["envelope"]["front"], c["files"]["envelope"]["side"]):
            assert f"cases/{c['case']}/{f}" in page and (out / "cases" / c["case"] / f).exists()
    assert (out / "assets" / "three-modules.js").stat().st_size > 1_000_000 and (out / "boxplots.png").exists()
    first, second = res["cases"]
    assert "gt_glb" in first["files"] and "gt_glb" not in second["files"]  # viewer=1: GLBs for the first case only


@pytest.mark.skipif(CHROMIUM is None, reason="no Chromium here (Debian: apt-get install chromium)")
def test_report_opens_in_headless_chromium_without_errors_and_the_viewer_draws(report, tmp_path):
    sync_playwright = pytest.importorskip("playwright.sync_api", reason="playwright not installed").sync_playwright
    from PIL import Image

    out, res = report
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM,
                                    args=["--use-gl=swiftshader", "--enable-unsafe-swiftshader", "--no-sandbox"])
        try:
            page = browser.new_page(viewport={"width": 1200, "height": 900})
            errors = []
            page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            page.on("pageerror", lambda e: errors.append(str(e)))
            page.goto((out / "report.html").as_uri())  # from the file system: no server
            page.wait_for_function("window.treeformViewerState && (window.treeformViewerState.done"
                                   " || window.treeformViewerState.error)", timeout=120_000)
            state = page.evaluate("window.treeformViewerState")
            page.locator("#tf-viewer").screenshot(path=str(tmp_path / "viewer.png"))
            cell = page.locator("td[data-key='front_iou'][data-method='envelope']").inner_text()
        finally:
            browser.close()
    assert errors == []
    assert state["error"] is None and state["loaded"] == state["expected"] == 2  # truth + envelope GLBs
    shot = np.asarray(Image.open(tmp_path / "viewer.png").convert("L"), float)
    assert shot.std() > 8.0  # trees drawn, not a blank canvas
    assert cell.split()[0] == f"{res['aggregate']['envelope']['scores']['front_iou']['median']:.4g}"
