"""Tests of treeform.dataset.capture: a synthetic multi-view capture of a tree with ground truth."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from treeform._shared.errors import InputError
from treeform.dataset.capture import FOCAL_35MM, FOCAL_MM, STAGES, synthetic_capture

SMALL = dict(views=4, size=160, species="oak", seed=3)


@pytest.fixture(scope="module")
def capture(gl, tmp_path_factory):
    events = []
    out = tmp_path_factory.mktemp("cap") / "capture"
    res = synthetic_capture(out, progress=lambda stage, event, s: events.append((stage, event)), **SMALL)
    return res, events


def _project(cam: dict, points: np.ndarray) -> np.ndarray:
    """World points (N, 3) -> pixel (N, 2) with a cameras.json entry (OpenCV axes, corner-origin pixels)."""
    K, c2w = np.array(cam["K"]), np.array(cam["cam_to_world"])
    w2c = np.linalg.inv(c2w)
    pc = points @ w2c[:3, :3].T + w2c[:3, 3]
    assert np.all(pc[:, 2] > 0)
    return (pc @ K.T)[:, :2] / pc[:, 2:3]


def test_files_exif_and_meta(capture):
    res, events = capture
    out = res.out
    names = [f"view_{k:02d}" for k in range(4)]
    assert [p.name for p in res.images] == [f"{n}.jpg" for n in names]
    assert sorted(p.name for p in (out / "images").iterdir()) == [f"{n}.jpg" for n in names]
    assert sorted(p.name for p in (out / "truth").iterdir()) == ["cameras.json", "labels", "meta.json",
                                                                 "skeleton.json", "tree.glb"]
    assert all(p.exists() for p in res.truth["labels"]) and res.truth["skeleton"].exists()
    assert not [p for p in out.parent.iterdir() if p.name.startswith(".")]  # no staging folder left
    with Image.open(res.images[0]) as im:
        assert im.format == "JPEG" and im.size == (160, 120)
        exif = im.getexif()
        ifd = exif.get_ifd(0x8769)
    assert exif[0x0112] == 1 and exif[0x010F] and exif[0x0110]
    assert float(ifd[0x920A]) == pytest.approx(FOCAL_MM) and int(ifd[0xA405]) == round(FOCAL_35MM)
    cams = json.loads(res.truth["cameras"].read_text())
    K = np.array(cams["view_00.jpg"]["K"])
    # the 35 mm equivalent in EXIF is the true focal length, by the frame's diagonal as phones
    # write it: what the photo reader (and so the SfM's focal prior) takes from it is the truth's K
    from treeform.sfm.photos import exif_focal_px

    with Image.open(res.images[0]) as im:
        f, source = exif_focal_px(im.getexif(), im.size)
    assert source == "exif_35mm" and f == pytest.approx(K[0, 0], rel=2e-3)
    meta = json.loads(res.truth["meta"].read_text())
    assert meta["species"] == "oak" and meta["seed"] == 3 and meta["views"] == 4 and meta["skeleton"] is True
    assert meta["height"] == pytest.approx(res.height, abs=1e-3) and 50 < meta["fov_y_deg"] < 60
    assert 2 <= len(meta["scene"]["background_trees"]) <= 4
    assert all(b["species"] != "oak" for b in meta["scene"]["background_trees"])
    assert [s for s, e in events if e == "end"] == list(STAGES)


def test_cameras_circle_the_tree_and_project_its_base_onto_wood(capture):
    from treeform.structures import TreeSkeleton

    res, _ = capture
    cams = json.loads(res.truth["cameras"].read_text())
    sk = TreeSkeleton.load(res.truth["skeleton"])
    base = sk.positions[:1].astype(np.float64)
    assert np.allclose(base[0, [0, 2]], 0.0, atol=0.5) and abs(base[0, 1]) < 0.5
    azimuths = []
    for name, cam in cams.items():
        assert set(cam) == {"K", "cam_to_world", "size"} and cam["size"] == [160, 120]
        c2w = np.array(cam["cam_to_world"])
        assert np.allclose(c2w[:3, :3] @ c2w[:3, :3].T, np.eye(3), atol=1e-5)
        centre = c2w[:3, 3]
        assert 1.2 < centre[1] < 2.0  # eye height 1.6 m ± 0.2 m
        assert np.hypot(centre[0], centre[2]) >= 1.3 * res.height * 0.95
        assert c2w[:3, 2] @ -centre > 0  # looks toward the tree
        azimuths.append(np.degrees(np.arctan2(centre[0], centre[2])) % 360)
        lab = np.asarray(Image.open(res.out / "truth" / "labels" / name.replace(".jpg", ".png")))
        u, v = _project(cam, base + [0.0, 0.3, 0.0])[0]
        assert 0 <= u < 160 and 0 <= v < 120
        win = lab[max(0, int(v) - 3):int(v) + 3, max(0, int(u) - 3):int(u) + 4]
        assert (win == 2).any(), (name, u, v)
        # the whole skeleton projects into the frame
        uv = _project(cam, sk.positions.astype(np.float64))
        assert uv.min() >= 0 and uv[:, 0].max() < 160 and uv[:, 1].max() < 120
    gaps = np.diff(np.sort(azimuths + [min(azimuths) + 360]))
    assert np.all(np.abs(gaps - 90) < 10)  # evenly spaced, a little jitter


def test_cameras_json_is_the_sfm_format(capture):
    from treeform.sfm.result import SfmResult

    res, _ = capture
    cams = json.loads(res.truth["cameras"].read_text())
    names = sorted(cams)
    r = SfmResult(names, [cams[n]["K"] for n in names], [cams[n]["cam_to_world"] for n in names],
                  [cams[n]["size"] for n in names], np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0), [])
    assert r.cameras_json() == cams


def test_labels_show_the_main_tree_only(capture):
    res, _ = capture
    meta = json.loads(res.truth["meta"].read_text())
    cams = json.loads(res.truth["cameras"].read_text())
    for path in res.truth["labels"]:
        lab = np.asarray(Image.open(path))
        assert lab.dtype == np.uint8 and lab.shape == (120, 160) and set(np.unique(lab)) <= {0, 1, 2}
        assert (lab == 1).mean() > 0.02 and (lab == 2).any() and (lab == 0).mean() > 0.5
    # background trees stand behind, outside the camera circle: their trunks are labelled background
    seen = 0
    for name, cam in cams.items():
        lab = np.asarray(Image.open(res.out / "truth" / "labels" / name.replace(".jpg", ".png")))
        for bg in meta["scene"]["background_trees"]:
            p = np.array([bg["position"]], np.float64) + [0.0, 1.0, 0.0]
            c2w = np.array(cam["cam_to_world"])
            if (p[0] - c2w[:3, 3]) @ c2w[:3, 2] <= 0:
                continue
            u, v = _project(cam, p)[0]
            if 0 <= u < 160 and 0 <= v < 120:
                seen += 1
                assert lab[int(v), int(u)] == 0
    assert seen > 0


def test_same_arguments_give_identical_bytes(capture, tmp_path):
    res, _ = capture
    again = synthetic_capture(tmp_path / "again", **SMALL)
    for a, b in zip(res.images + res.truth["labels"], again.images + again.truth["labels"]):
        assert a.read_bytes() == b.read_bytes(), a.name
    for key in ("cameras", "meta", "skeleton", "tree"):
        assert res.truth[key].read_bytes() == again.truth[key].read_bytes(), key
    other = synthetic_capture(tmp_path / "other", **{**SMALL, "seed": 4, "views": 3})
    assert other.images[0].read_bytes() != res.images[0].read_bytes()


@pytest.mark.parametrize("kwargs, word", [
    ({"views": 2}, "views"), ({"views": 361}, "views"), ({"size": 32}, "size"), ({"size": 5000}, "size"),
    ({"species": "palm"}, "species"), ({"model": "/nope/tree.glb"}, "model"), ({"radius": 0.1}, "radius"),
    ({"views": 3.5}, "views"), ({"camera_height": float("nan")}, "camera_height"),
])
def test_bad_input_is_one_clear_error(tmp_path, kwargs, word):
    out = tmp_path / "cap"
    with pytest.raises(InputError) as exc:
        synthetic_capture(out, **kwargs)
    msg = str(exc.value)
    assert msg.startswith(word) and "\n" not in msg
    assert not out.exists() and not list(tmp_path.iterdir())


def test_no_partial_folder_after_a_failure(gl, tmp_path, monkeypatch):
    import treeform.dataset.capture as capture_mod

    calls = []

    def failing_exif(k, *args):
        calls.append(k)
        if k == 1:
            raise RuntimeError("disk full")
        return real(k, *args)

    real = capture_mod._exif
    monkeypatch.setattr(capture_mod, "_exif", failing_exif)
    with pytest.raises(RuntimeError):
        synthetic_capture(tmp_path / "cap", views=3, size=64, seed=1)
    assert calls == [0, 1]  # the first view was written before the failure
    assert list(tmp_path.iterdir()) == []
    # an existing capture folder is left as it was
    (tmp_path / "cap").mkdir()
    (tmp_path / "cap" / "notes.txt").write_text("mine")
    with pytest.raises(RuntimeError):
        synthetic_capture(tmp_path / "cap", views=3, size=64, seed=1)
    assert [p.name for p in tmp_path.iterdir()] == ["cap"]
    assert [p.name for p in (tmp_path / "cap").iterdir()] == ["notes.txt"]


def test_a_third_party_model_has_no_skeleton_truth(gl, tmp_path):
    model = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "models" / "cesium_tree.glb"
    if not model.exists():
        pytest.skip("../shared/data/models/cesium_tree.glb is not available")
    res = synthetic_capture(tmp_path / "cap", views=3, size=96, model=model)
    meta = json.loads(res.truth["meta"].read_text())
    assert meta["skeleton"] is False and "skeleton" not in res.truth and meta["skeleton_note"]
    assert not (res.out / "truth" / "skeleton.json").exists() and res.truth["tree"].exists()
    assert res.height == pytest.approx(16.57, abs=0.1)  # Z-up COLLADA export, stood up (Y up)
    lab = np.asarray(Image.open(res.truth["labels"][0]))
    assert (lab == 1).any() and (lab == 2).any()


def test_cli_capture(gl, tmp_path):
    from typer.testing import CliRunner

    from treeform.cli.app import app

    out = tmp_path / "cap"
    run = CliRunner().invoke(app, ["dataset", "capture", str(out), "--views", "3", "--size", "64", "--species",
                                   "pine", "--seed", "2", "--no-clutter"])
    assert run.exit_code == 0, run.output
    assert "3 views of a" in run.output and (out / "images" / "view_02.jpg").exists()
    meta = json.loads((out / "truth" / "meta.json").read_text())
    assert meta["species"] == "pine" and meta["clutter"] is False and meta["scene"]["props"] == 0
    bad = CliRunner().invoke(app, ["dataset", "capture", str(tmp_path / "x"), "--views", "2"])
    assert bad.exit_code != 0 and "error: views" in bad.output and not (tmp_path / "x").exists()


def test_pycolmap_registers_a_small_capture(gl, tmp_path):
    """24 views (15° apart) at 480 px: fewer, wider-spaced views register only in part in this scene."""
    pycolmap = pytest.importorskip("pycolmap", reason="pycolmap is not installed (optional: multi-view SfM)")
    res = synthetic_capture(tmp_path / "cap", views=24, size=480, seed=0)
    db, sparse = tmp_path / "db.db", tmp_path / "sparse"
    sparse.mkdir()
    reader = pycolmap.ImageReaderOptions()
    reader.camera_model = "SIMPLE_RADIAL"
    extract = pycolmap.FeatureExtractionOptions()
    extract.num_threads = 2
    pycolmap.extract_features(db, res.out / "images", camera_mode=pycolmap.CameraMode.SINGLE, reader_options=reader,
                              extraction_options=extract, device=pycolmap.Device.cpu)
    match = pycolmap.FeatureMatchingOptions()
    match.num_threads = 2
    pycolmap.match_exhaustive(db, matching_options=match, device=pycolmap.Device.cpu)
    options = pycolmap.IncrementalPipelineOptions()
    options.num_threads = 2
    recs = pycolmap.incremental_mapping(db, res.out / "images", sparse, options=options)
    registered = max((r.num_reg_images() for r in recs.values()), default=0)
    assert registered >= 22, registered
