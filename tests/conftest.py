from pathlib import Path

import pytest

from treeform._shared.errors import RenderError

ROOT = Path(__file__).resolve().parents[1]
SHARED = ROOT.parent / "shared" / "data"
PHOTOS = SHARED / "photos"


@pytest.fixture
def khronos_report():
    """``report(path)``: the Khronos glTF validator's report of a GLB (tools/gltf_validate.mjs); skips
    without node or the validator."""
    return _khronos_report


def _khronos_report(path) -> dict:
    import json
    import shutil
    import subprocess

    if shutil.which("node") is None or not (ROOT / "tools" / "node_modules" / "gltf-validator").is_dir():
        pytest.skip("node or tools/node_modules/gltf-validator missing (make validator)")
    proc = subprocess.run(["node", str(ROOT / "tools" / "gltf_validate.mjs"), str(path)], capture_output=True,
                          text=True, timeout=120, check=False)
    assert proc.returncode in (0, 1), proc.stderr
    return json.loads(proc.stdout)


@pytest.fixture
def browser():
    """Headless Chromium (WebGL by SwiftShader) through playwright; skips where either is missing."""
    import shutil

    exe = next((p for p in (shutil.which(n) for n in ("chromium", "chromium-browser", "google-chrome")) if p), None)
    if exe is None:
        pytest.skip("no Chromium here (Debian: apt-get install chromium)")
    sync_playwright = pytest.importorskip("playwright.sync_api", reason="playwright not installed").sync_playwright
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=exe,
                              args=["--use-gl=swiftshader", "--enable-unsafe-swiftshader", "--no-sandbox"])
        try:
            yield b
        finally:
            b.close()


@pytest.fixture
def photos_dir():
    if not PHOTOS.exists():
        pytest.skip("../shared/data/photos is not available")
    return PHOTOS


@pytest.fixture(scope="session")
def gl():
    """The shared OpenGL context; skips the test if none can be created on this machine."""
    from treeform.render import get_context

    try:
        return get_context()
    except RenderError as exc:
        pytest.skip(str(exc))


@pytest.fixture(scope="session")
def dense_tree_rgba():
    """A 256² RGBA tree with a dense, bumpy crown of mottled greens (dark patches) on a brown trunk."""
    import numpy as np
    import scipy.ndimage as ndi

    rng = np.random.default_rng(7)
    n = 256
    yy, xx = np.mgrid[:n, :n] / n
    ang = np.arctan2(yy - 0.4, xx - 0.5)
    crown = np.hypot((xx - 0.5) / 0.36, (yy - 0.4) / 0.3) < 1 + 0.08 * np.sin(7 * ang) + 0.05 * np.sin(13 * ang + 1)
    trunk = (np.abs(xx - 0.5) < 0.025) & (yy > 0.5) & (yy < 0.95)
    field = ndi.gaussian_filter(rng.normal(size=(n, n)), 6)
    field = (field - field.min()) / np.ptp(field)
    fine = ndi.gaussian_filter(rng.normal(size=(n, n)), 1.2)
    shade = np.clip(0.35 + 0.9 * field + 0.6 * fine, 0.15, 1.4)
    rgba = np.zeros((n, n, 4), np.uint8)
    rgba[trunk, :3] = (112, 78, 48)
    rgba[crown, :3] = np.clip(np.array([62, 118, 40]) * shade[crown, None], 0, 255)
    rgba[..., 3] = np.where(crown | trunk, 255, 0)
    return rgba


@pytest.fixture
def dask_cluster_processes(tmp_path):
    """Start ``dask scheduler`` and ``dask worker`` as their own processes; yields ``start(nworkers) -> address``.

    Everything started is killed (with its process group) when the test ends.
    """
    import json
    import os
    import signal
    import subprocess
    import sys
    import time

    procs = []
    dask = [sys.executable, "-m", "dask"]

    def start(nworkers: int = 1) -> str:
        sched_file = tmp_path / "scheduler.json"
        procs.append(subprocess.Popen(dask + ["scheduler", "--scheduler-file", str(sched_file), "--port", "0",
                                              "--dashboard-address", ":0", "--host", "127.0.0.1"],
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True))
        deadline = time.time() + 60
        while not sched_file.exists() and time.time() < deadline:
            time.sleep(0.1)
        assert sched_file.exists(), "the scheduler did not start"
        time.sleep(0.2)
        address = json.loads(sched_file.read_text())["address"]
        procs.append(subprocess.Popen(dask + ["worker", address, "--nworkers", str(nworkers), "--nthreads", "1",
                                              "--no-dashboard"],
                                      stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True))
        return address

    yield start
    for p in procs:
        try:
            os.killpg(p.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        p.wait()
