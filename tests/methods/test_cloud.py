"""Billboard cloud pipeline (seed 000 §6): front view against the picture, GLB (Khronos
validator), JSON sidecar, determinism and bad inputs."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import cv2
import numpy as np
import pytest

from treeform._shared.errors import InputError, NoTreeFoundError, OutputError
from treeform.geometry.billboard_cloud import CloudFrame
from treeform.io import read_glb
from treeform.methods.variations.cloud import cloud

ROOT = Path(__file__).resolve().parents[2]
CESIUM = ROOT.parent / "shared" / "data" / "billboards" / "cesium_tree_billboard.png"
VALIDATOR = ROOT / "tools" / "gltf_validate.mjs"
FAST = dict(size=256, segments=96)


@pytest.fixture(scope="module")
def real(tmp_path_factory, gl):
    """The CC0 Cesium tree (a real RGBA picture), written with its sidecar and strip."""
    if not CESIUM.is_file():
        pytest.skip("../shared/data/billboards/cesium_tree_billboard.png is not available")
    d = tmp_path_factory.mktemp("cloud")
    return cloud(CESIUM, out=d / "cloud.glb", views=d / "strip.png", **FAST), d


@pytest.fixture(scope="module")
def dense(dense_tree_rgba, tmp_path_factory, gl):
    d = tmp_path_factory.mktemp("dense")
    return cloud(dense_tree_rgba, out=d / "cloud.glb", evaluate=True, **FAST), d


@pytest.mark.parametrize("which", ["real", "dense"])
def test_front_view_reproduces_the_picture(which, request):
    res, _ = request.getfixturevalue(which)
    m = res.metrics
    assert m["psnr"] >= 25 or m["ssim"] >= 0.9, m
    assert m["iou"] >= 0.95, m
    assert m["front"] == m["superpixels"] and m["trunk"] == 1 and m["rear"] > 0 and m["interior"] > 0


def test_files_and_glb_structure(real):
    res, d = real
    assert sorted(p.name for p in d.iterdir()) == ["cloud.glb", "cloud.json", "strip.png"]
    gltf, _ = read_glb(d / "cloud.glb")
    (mat,) = gltf["materials"]
    assert mat["alphaMode"] == "MASK" and mat["alphaCutoff"] == 0.5 and mat["doubleSided"]
    assert len(gltf["images"]) == 1 and len(gltf["meshes"][0]["primitives"]) == 1  # one atlas, one draw call
    assert res.mesh.n_triangles >= 2 * res.metrics["billboards"]
    strip = cv2.imread(str(d / "strip.png"))
    assert strip.shape[0] > 100 and strip.shape[1] > 4 * strip.shape[0]  # picture + 4 views


@pytest.mark.skipif(not shutil.which("node") or not (ROOT / "tools" / "node_modules" / "gltf-validator").is_dir(),
                    reason="node or the npm gltf-validator is not installed (make validator)")
def test_glb_passes_khronos_validator(real):
    _, d = real
    proc = subprocess.run(["node", str(VALIDATOR), str(d / "cloud.glb")], capture_output=True, text=True, timeout=120)
    report = json.loads(proc.stdout)
    assert proc.returncode == 0 and report["numErrors"] == 0 and report["numWarnings"] == 0, report["messages"]


def test_sidecar_describes_the_cloud(real):
    res, d = real
    side = json.loads((d / "cloud.json").read_text())
    assert side == json.loads(json.dumps(res.sidecar))
    assert side["format"] == "treeform.billboard_cloud" and side["source"]["kind"] == "rgba"
    assert side["source"]["file"] == CESIUM.name and len(side["source"]["sha256"]) == 64
    # segmentation: run-length encoded labels
    runs = np.array(side["segmentation"]["runs"]).reshape(-1, 2)
    assert np.array_equal(np.repeat(runs[:, 0], runs[:, 1]).reshape(res.labels.shape), res.labels)
    # superpixel contours give each billboard's alpha in the atlas
    tree = res.labels > 0
    regions = [s for s in side["sprites"] if s["kind"] == "region"]
    assert len(regions) == res.metrics["superpixels"] and side["sprites"][-1]["kind"] == "trunk"
    for s in regions[::7]:
        canvas = np.zeros(tree.shape, np.uint8)
        cv2.drawContours(canvas, [np.array(c, np.int32).reshape(-1, 1, 2) for c in s["contours"]], -1, 1,
                         thickness=cv2.FILLED)
        x0, y0, w, h = s["box"]
        u0, v0, _, _ = s["atlas"]
        alpha = (canvas.astype(bool) & tree)[y0:y0 + h, x0:x0 + w]
        assert np.array_equal(res.atlas[v0:v0 + h, u0:u0 + w, 3] == 255, alpha)
    # billboard positions: pixels and metres agree through the frame
    cols = side["billboards"]["columns"]
    rows = np.array(side["billboards"]["rows"])
    assert len(rows) == res.metrics["billboards"]
    f = side["frame"]
    frame = CloudFrame(*res.picture.shape[1::-1], f["metres_per_pixel"], tuple(f["origin_px"]), f["fov_y"])
    px = rows[:, [cols.index("x_px"), cols.index("y_px"), cols.index("z_px")]]
    world = rows[:, [cols.index("x"), cols.index("y"), cols.index("z")]]
    assert np.allclose(frame.to_world(px[:, 0], px[:, 1], px[:, 2]), world, atol=2e-3)


def test_same_seed_same_bytes_other_seed_differs(real, tmp_path):
    _, d = real
    cloud(CESIUM, out=tmp_path / "a.glb", **FAST)
    cloud(CESIUM, out=tmp_path / "b.glb", seed=1, **FAST)
    assert (tmp_path / "a.glb").read_bytes() == (d / "cloud.glb").read_bytes()
    assert (tmp_path / "a.json").read_bytes() == (d / "cloud.json").read_bytes()
    assert (tmp_path / "b.glb").read_bytes() != (d / "cloud.glb").read_bytes()


@pytest.mark.parametrize("kwargs, error, match", [
    (dict(image=np.zeros((64, 64, 4), np.uint8)), NoTreeFoundError, "no opaque"),
    (dict(image=np.zeros((64, 64), np.uint8)), InputError, "image"),
    (dict(out="cloud.gltf"), InputError, "glb"),
    (dict(views="strip.jpg"), InputError, "png"),
    (dict(out="cloud.glb/cloud.glb"), OutputError, "not a directory"),  # a folder under a file
    (dict(segments=0), InputError, "segments"),
    (dict(compactness=-1.0), InputError, "compactness"),
    (dict(colour="red"), InputError, "unknown option"),
])
def test_bad_inputs_raise_one_clear_error_and_write_nothing(kwargs, error, match, dense_tree_rgba, tmp_path,
                                                             monkeypatch):
    monkeypatch.chdir(tmp_path)
    if kwargs.get("out", "").startswith("cloud.glb/"):
        (tmp_path / "cloud.glb").write_bytes(b"")
    kwargs = {"image": dense_tree_rgba, "out": "cloud.glb", **FAST, **kwargs}
    before = sorted(tmp_path.iterdir())
    with pytest.raises(error, match=match):
        cloud(kwargs.pop("image"), **kwargs)
    assert sorted(tmp_path.iterdir()) == before
