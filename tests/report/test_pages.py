"""report.html pages (evaluation, single run) in a real browser (headless Chromium through playwright)."""


import numpy as np
import pytest



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
    assert "species_envelope.png" in page and (out / "species_envelope.png").exists()  # form errors per species
    first, second = res["cases"]
    assert "gt_glb" in first["files"] and "gt_glb" not in second["files"]  # viewer=1: GLBs for the first case only


def _open(browser, page_path, shot_path):
    """Open a page from the file system in headless Chromium; (console errors, viewer state, canvas pixels)."""
    from PIL import Image

    page = browser.new_page(viewport={"width": 1200, "height": 900})
    errors = []
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto(page_path.as_uri())  # from the file system: no server
    page.wait_for_function("window.treeformViewerState && (window.treeformViewerState.done"
                           " || window.treeformViewerState.error)", timeout=120_000)
    state = page.evaluate("window.treeformViewerState")
    # the last draw reaches the screen at the next frames (a busy machine delays them)
    page.evaluate("() => new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
    page.wait_for_timeout(200)
    page.locator("#tf-viewer").screenshot(path=str(shot_path))
    cells = {k: page.locator(f"td[data-key='{k}']").first.inner_text()
             for k in page.eval_on_selector_all("td[data-key]", "els => els.map(e => e.dataset.key)")}
    page.close()
    return errors, state, np.asarray(Image.open(shot_path).convert("L"), float), cells


def test_eval_report_opens_in_headless_chromium_without_errors_and_the_viewer_draws(report, tmp_path, browser):
    out, res = report
    errors, state, shot, cells = _open(browser, out / "report.html", tmp_path / "viewer.png")
    assert errors == []
    assert state["error"] is None and state["loaded"] == state["expected"] == 2  # truth + envelope GLBs
    assert shot.std() > 8.0  # trees drawn, not a blank canvas
    assert cells["front_iou"].split()[0] == f"{res['aggregate']['envelope']['scores']['front_iou']['median']:.4g}"


def test_grow_report_shows_the_tree_and_its_metrics(tmp_path, gl, browser):
    from treeform.methods.learned.grow import grow_tree
    from treeform.report import write_run_report

    res = grow_tree("birch", seed=1, out=tmp_path / "t", lod="low")
    page = write_run_report(tmp_path / "t", title="grow birch")
    text = page.read_text()
    assert "preview.png" in text and (tmp_path / "t" / "tree.glb.js").exists()
    errors, state, shot, cells = _open(browser, page, tmp_path / "viewer.png")
    assert errors == [] and state["loaded"] == 1 and shot.std() > 8.0
    assert cells["nodes"] == str(res.metrics["nodes"])
    assert cells["tree_form.biomass_m3"] == f"{res.metrics['tree_form']['biomass_m3']:.4g}"


def test_cloud_report_shows_the_billboard_cloud_and_its_metrics(tmp_path, gl, browser):
    from pathlib import Path

    from treeform.methods.variations.cloud import cloud

    oak = Path(__file__).resolve().parents[2] / "src" / "treeform" / "data" / "library" / "oak_1.png"
    res = cloud(oak, out=tmp_path / "oak.glb", report=tmp_path / "oak_report", size=256, segments=48)
    page = res.files["report"]
    assert page == tmp_path / "oak_report" / "report.html" and (tmp_path / "oak_report" / "oak.glb.js").exists()
    errors, state, shot, cells = _open(browser, page, tmp_path / "viewer.png")
    assert errors == [] and state["error"] is None and state["loaded"] == 1
    assert shot.std() > 8.0  # billboards drawn, not a blank canvas
    assert cells["billboards"] == str(res.metrics["billboards"]) and cells["iou"] == f"{res.metrics['iou']:.4g}"


def test_a_run_report_needs_the_runs_metrics(tmp_path):
    from treeform._shared.errors import InputError
    from treeform.report import write_run_report

    with pytest.raises(InputError, match="metrics.json"):
        write_run_report(tmp_path, title="nothing here")
