"""End to end: a small synthetic capture -> `treeform multiview` (seed 002)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from treeform._shared.errors import InputError

pytest.importorskip("pycolmap", reason="pycolmap is not installed (multi-view SfM)")


@pytest.fixture(scope="module")
def run(gl, tmp_path_factory):
    """The capture and its multiview run; SfM, the tree frame and the mattes run once for the module's runs
    of the same photos.

    COLMAP is deterministic on the same photos and seed (tests/sfm/test_colmap.py checks it), and so are
    the frame and the mattes (tests/sfm/test_align.py and test_sweep.py; the threads test below): the later runs here test
    what comes after them (other mattes, leaves, --height) and reuse the first run's results (copies of
    them, keyed by every input and setting they read) instead of spending their time again.
    """
    import copy

    import treeform.methods.multiview.pipeline as mv
    import treeform.sfm as sfm_api
    from treeform.dataset.capture import synthetic_capture
    from treeform.methods.multiview.pipeline import reconstruct_multiview

    done = {}
    run_sfm, to_tree_frame, segment_views = sfm_api.run_sfm, sfm_api.to_tree_frame, mv._segment_views

    def memo(key, make):
        if key not in done:
            done[key] = make()
        # SfM's result is handed out as it is (the frame's key is its identity), the later stages' as copies
        return copy.deepcopy(done[key]) if key[0] != "sfm" else done[key]

    def sfm_once(views, **kw):
        return memo(("sfm", tuple(v.name for v in views), tuple(sorted(kw.items()))), lambda: run_sfm(views, **kw))

    def frame_once(result, **kw):  # the images are those of the SfM result's photos
        key = ("frame", id(result), tuple(sorted((k, v) for k, v in kw.items() if k != "images")))
        return memo(key, lambda: to_tree_frame(result, **kw))

    def mattes_once(views, sfm, cfg, masks=None):
        key = ("mattes", tuple(v.name for v in views), tuple(sfm.names), str(masks), mv.MATTE_THREADS,
               mv.TILE_WOOD_FROM, cfg.segmenter, cfg.mask_size, cfg.matte_side, cfg.seed, cfg.tile_wood,
               cfg.thin_wood, cfg.sky_gaps)
        return memo(key, lambda: segment_views(views, sfm, cfg, masks))

    base = tmp_path_factory.mktemp("mv")
    cap = synthetic_capture(base / "capture", views=24, size=480, species="oak", seed=0)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(sfm_api, "run_sfm", sfm_once)
        mp.setattr(sfm_api, "to_tree_frame", frame_once)
        mp.setattr(mv, "_segment_views", mattes_once)
        res = reconstruct_multiview(cap.out / "images", out=base / "out", mask_size=320, leaves=1500, lod="low",
                                    segmenter="learned", seed=0, cells=200, surface_cells=100, leaf_texture="photo")
        yield cap, res, base / "out"


def test_outputs_and_cameras(run):
    cap, res, out = run
    for name in ("tree.glb", "tree.obj", "skeleton.json", "skeleton.ply", "preview.png", "metrics.json",
                 "config.json", "cameras.json", "points.ply"):
        assert (out / name).is_file(), name
    cams = json.loads((out / "cameras.json").read_text())
    assert len(cams) >= 22  # >= 90 % of the 24 views registered
    for c in cams.values():
        T = np.array(c["cam_to_world"])
        assert np.allclose(T[:3, :3] @ T[:3, :3].T, np.eye(3), atol=1e-5)
    from treeform.io.ply import read_points_ply

    pts, cols, labels = read_points_ply(out / "points.ply")
    assert set(np.unique(labels)) <= {0, 1, 2} and (labels == 1).any() and (labels == 2).any()
    # the cameras were turned by silhouette coherence: a few pixels, the views' outlines closer
    pr = json.loads((out / "metrics.json").read_text())["sfm"]["pose_refinement"]
    assert 1 <= pr["rounds"] <= 6 and 0 < pr["shift_median_pct"] < 1.0 and pr["shift_max_pct"] < 4.0
    assert pr["outline_cost_after_px2"] < pr["outline_cost_before_px2"]


def test_views_matted_on_threads_match_one_by_one(run, monkeypatch):
    """The matting stage's threads change when a view is matted, not its matte."""
    from types import SimpleNamespace

    import treeform.methods.multiview.pipeline as mv
    from treeform.methods.multiview.config import MultiviewConfig
    from treeform.sfm.photos import load_photos

    cap = run[0]
    views = load_photos(sorted((cap.out / "images").iterdir())[:4])
    sfm = SimpleNamespace(names=[v.name for v in views],
                          sizes=np.array([[v.image.shape[1], v.image.shape[0]] for v in views]))
    cfg = MultiviewConfig(mask_size=320, segmenter="learned")
    out = {}
    for threads in (1, 3):
        monkeypatch.setattr(mv, "MATTE_THREADS", threads)
        out[threads] = mv._segment_views(views, sfm, cfg)
    (l1, i1, s1), (l3, i3, s3) = out[1], out[3]
    assert len(l3) == 4 and all(np.array_equal(a, b) for a, b in zip(l1, l3))
    assert all(np.array_equal(a, b) for a, b in zip(i1, i3)) and np.array_equal(s1, s3)
    assert all((lab == 1).any() for lab in l3)  # each view's tree found


def test_the_glb_passes_the_khronos_validator(run, khronos_report):
    report = khronos_report(run[2] / "tree.glb")
    assert report["numErrors"] == 0 and report["numWarnings"] == 0, report["messages"][:5]
    assert report["info"]["totalTriangleCount"] == run[1].mesh.n_triangles


def test_model_matches_the_views(run):
    cap, res, out = run
    m = json.loads((out / "metrics.json").read_text())
    truth = json.loads((cap.out / "truth" / "meta.json").read_text())
    # metric scale from the eye height above the ground the photos' plane sweep finds (the model's top
    # 1.08-1.10x the truth on three such captures; the SfM points' plane had put it at 0.34-1.15x)
    frame = m["sfm"]["frame"]
    assert frame["ground_source"] == "sweep" and frame["sweep_contrast"] > 0.06 and m["scale_warning"] is None
    assert 0.85 < m["tree_height_m"] / truth["height"] < 1.3, (m["tree_height_m"], truth["height"])
    assert m["hull_height_m"] >= m["tree_height_m"]  # the hull's tent over the crown
    assert m["tree_height_m"] == pytest.approx(float(res.mesh.bounds()[1][1]), abs=1e-3)
    # every photo registered: no registration warning either
    assert (m["registration_warning"] is None) == (m["registered"] == m["photos"])
    assert m["silhouette_iou_median"] > 0.15  # far from the 0.8: see the issue note
    # every registered photo scored against the model; on this right SfM model at most a stray matte
    # disagrees (the segmenter takes the small neighbouring tree for the tree in one view), not the cameras
    views = m["silhouette_iou_views"]
    assert sorted(views) == sorted(json.loads((out / "cameras.json").read_text()))
    low = [n for n, v in views.items() if v < 0.25]
    assert len(low) <= 2 and np.median(list(views.values())) == pytest.approx(m["silhouette_iou_median"], abs=1e-3)
    assert (m["consistency_warning"] is None) == (not low)
    assert m["consistency_warning"] is None or "camera or their tree matte" in m["consistency_warning"]
    assert m["visible_nodes"] > 5 and res.skeleton.n_nodes > m["visible_nodes"]  # hidden branches grown
    # the trunk's width read in the photos at their own resolution (the 320-px mattes made it 1.8x the
    # true one, at the 1 %-of-the-height cap): measured 1.26x the truth's radius between 2 and 15 % of
    # the height, both relative to their tree's height
    from treeform.methods.multiview.trunk import TRUNK_BAND, trunk_chain
    from treeform.structures import TreeSkeleton

    gt = TreeSkeleton.load(cap.out / "truth" / "skeleton.json")
    chain = trunk_chain(gt)
    y = gt.positions[chain, 1] / truth["height"]
    gt_radius = gt.radius[chain][(y >= TRUNK_BAND[0]) & (y <= TRUNK_BAND[1])].mean()
    ratio = (m["trunk_radius_m"] / m["tree_height_m"]) / (gt_radius / truth["height"])
    assert m["trunk_radius_from"] == "photos" and 0.7 < ratio < 1.5, ratio
    # the tree stands on the ground at the origin (its root was 1.7 m up where the mattes lost the foot)
    assert res.skeleton.positions[0, 1] == 0.0 and res.skeleton.parent[0] == -1
    bark = next(p for p in res.mesh.parts if p.name == "bark")
    assert abs(bark.positions[:, 1].min()) < 0.02 * m["tree_height_m"]


def test_leaves_wear_the_photos_crown(run):
    """Each leaf card shows its own tile of the photos (seed 002 §6), cut by the views' foliage mattes."""
    cap, res, out = run
    assert res.config["leaf_texture"] == "photo"
    f = res.foliage
    assert f.uv is not None and len(np.unique(f.uv, axis=0)) == len(f)  # a tile per card
    tex = next(p for p in res.mesh.parts if p.name == "leaves").material.texture
    opaque = tex[..., 3] > 127
    assert 0.2 < opaque.mean() < 0.95  # the mattes' gaps and the clusters' outlines are transparent
    # the tiles carry the photos' leaf colours (the capture's dark oak crown), brightened by one gain
    # that makes the lit model match the photos: the same chromaticity
    from PIL import Image

    from treeform.segment import segment

    photo = np.asarray(Image.open(sorted((cap.out / "images").glob("*.jpg"))[0]).convert("RGB"))
    want = np.median(photo[segment(photo, method="learned").foliage_mask], axis=0).astype(float)
    got = np.median(tex[..., :3][opaque], axis=0).astype(float)
    assert got.sum() >= want.sum()
    assert np.abs(got / got.sum() - want / want.sum()).max() < 0.06, (got, want)


def test_too_few_photos_is_one_clear_error(tmp_path):
    from PIL import Image

    from treeform.methods.multiview.pipeline import reconstruct_multiview

    Image.new("RGB", (64, 48), (90, 120, 60)).save(tmp_path / "a.jpg")
    with pytest.raises(InputError, match="at least 3"):
        reconstruct_multiview(tmp_path, out=tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_user_mattes_replace_the_segmenter(run, tmp_path):
    """The capture's true mattes (--masks) instead of the segmenter, procedural leaf clusters, and
    --height: the model (not the carved hull, whose top is a tent over the crown) is
    that tall, standing on the ground, the cameras scaled with it."""
    from treeform.methods.multiview.pipeline import reconstruct_multiview

    cap, first, _ = run
    res = reconstruct_multiview(cap.out / "images", masks=cap.out / "truth" / "labels", mask_size=320, leaves=500,
                                lod="low", seed=0, cells=200, surface_cells=100, height=12.0,
                                leaf_texture="procedural", refine_poses=False)  # a coarser hull
    assert "pose_refinement" not in res.metrics["sfm"]  # the SfM's cameras as they came
    top = float(res.mesh.bounds()[1][1])
    assert res.metrics["tree_height_m"] == pytest.approx(12.0, abs=1e-3) and top == pytest.approx(12.0, abs=1e-3)
    assert res.skeleton.positions[0, 1] == 0.0 and res.metrics["scale_from"] == "height"
    assert res.metrics["hull_height_m"] > 12.0 and res.metrics["scale_warning"] is None
    # the cameras stand where they saw that tree: the ring's radius against the tree's height is the eye-height
    # run's (within the two runs' differences of SfM and carving)
    ring = lambda r: np.median(np.hypot(r.sfm.centers[:, 0], r.sfm.centers[:, 2])) / r.metrics["tree_height_m"]  # noqa: E731
    assert ring(res) == pytest.approx(ring(first), rel=0.15)
    assert res.metrics["silhouette_iou_median"] > 0.3  # measured 0.37 here (320-px mattes); see the issue note
    assert res.config["leaf_texture"] == "procedural" and res.foliage.uv is None  # drawn clusters, tinted
    # a folder without a photo's matte: one clear error, nothing written
    (tmp_path / "masks").mkdir()
    with pytest.raises(InputError, match="no mask for"):
        reconstruct_multiview(cap.out / "images", masks=tmp_path / "masks", out=tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_an_impostor_of_the_multiview_tree(run, tmp_path):
    """`treeform impostor` (and `multiview --impostor`) works on a multiview output folder too."""
    from treeform.methods.envelope.impostor import make_impostor

    imp = make_impostor(run[2], out=tmp_path / "impostor", face=64, rdm_resolution=32, leaflet_size=64)
    assert imp.color.shape == (6, 64, 64, 3) and (tmp_path / "impostor" / "rdm.npz").is_file()
    means = imp.color.reshape(6, -1, 3).mean(1)
    assert np.all(means[:, 1] >= means[:, 2])  # foliage-coloured on every side


def test_a_report_of_the_multiview_run(run, tmp_path):
    """`multiview --report`: the run's page with its preview, metrics and the model for the viewer."""
    import shutil

    from treeform.report import write_run_report

    out = tmp_path / "out"
    shutil.copytree(run[2], out)
    page = write_run_report(out, title="multiview", preview_caption="preview: the model beside three photos")
    text = page.read_text()
    metrics = json.loads((out / "metrics.json").read_text())
    assert "preview: the model beside three photos" in text and "preview.png" in text
    assert (out / "tree.glb.js").stat().st_size > (out / "tree.glb").stat().st_size  # base64 of the GLB
    assert f">{metrics['registered']}<" in text  # the metrics table holds the run's numbers


def test_the_evaluation_scores_the_multiview_tree_against_the_truth(run, tmp_path, monkeypatch):
    """`treeform eval --cases captures:N --methods envelope,multiview`: the same truth for both routes."""
    from treeform.evaluation import cases as cases_mod
    from treeform.evaluation import run as ev
    from treeform.evaluation.cases import capture_case

    cap, res, _ = run
    monkeypatch.setattr(cases_mod, "load_case", lambda name, size=256: capture_case(cap, name))
    entry = ev._entry
    monkeypatch.setattr(ev, "_entry", lambda m: (lambda *a, **k: res) if m == "multiview" else entry(m))
    r = ev.run_case("capture-0-0", ["envelope", "multiview"], folder=tmp_path / "case", glb=True)
    mv, env = r["methods"]["multiview"], r["methods"]["envelope"]
    assert mv["registration_rate"] == 1.0 and mv["camera_position_err"] < 0.02
    assert mv["front_iou"] > 0.5 and "front_iou_own" not in mv  # the route keeps no per-photo matte
    assert mv["rel_err_height"] < 0.3  # metric scale from eye-height cameras
    assert {"iou_side", "rbv_err_l5", "mrt_err_pct", "rel_err_lai"} <= set(mv) and "species_correct" not in mv
    assert env["front_iou"] > 0.5  # the envelope route on the first photo, scored against the same truth
    # what the photos all around buy: the back of the tree (0.63 against 0.22 when written; 0.57 against
    # 0.40 since the envelope route stands its trunk on the trunk's foot, skeleton.trunk_foot)
    assert mv["iou_back"] > env["iou_back"] + 0.1
    for f in ("multiview_front.png", "multiview_side.png", "multiview.glb", "gt.glb", "envelope.glb"):
        assert (tmp_path / "case" / f).is_file()
    assert cap.out.exists()  # a case made from an existing capture does not remove it


def test_matte_side_and_sky_gaps_are_checked():
    from treeform.methods.multiview.config import MultiviewConfig

    assert MultiviewConfig().matte_side is None and MultiviewConfig(matte_side=0).validate().matte_side == 0
    with pytest.raises(InputError, match="matte_side"):
        MultiviewConfig(matte_side=10).validate()
    with pytest.raises(InputError, match="sky_gaps"):
        MultiviewConfig(sky_gaps="yes").validate()


def test_mattes_are_seen_closer_and_open_the_sky_gaps(run, monkeypatch):
    """The network sees each matte at 1.25x its size; foliage coloured like the sky above the tree goes."""
    from types import SimpleNamespace

    import treeform.methods.multiview.pipeline as mv
    import treeform.segment as seg_mod
    from treeform.methods.multiview.config import MultiviewConfig
    from treeform.sfm.photos import load_photos

    views = load_photos(sorted((run[0].out / "images").iterdir())[:3])
    sfm = SimpleNamespace(names=[v.name for v in views],
                          sizes=np.array([[v.image.shape[1], v.image.shape[0]] for v in views]))
    seen, real = [], seg_mod.segment

    def spy(image, **kw):
        seen.append((max(image.shape[:2]), kw.get("side")))
        return real(image, **kw)

    monkeypatch.setattr(seg_mod, "segment", spy)
    on = mv._segment_views(views, sfm, MultiviewConfig(mask_size=320))
    assert seen and all(side == round(1.25 * n) for n, side in seen)
    off = mv._segment_views(views, sfm, MultiviewConfig(mask_size=320, sky_gaps=False))
    cut = 0
    for a, b, img in zip(on[0], off[0], on[1]):
        assert np.array_equal(a == 2, b == 2) and not ((a > 0) & (b == 0)).any()  # only foliage goes
        gone = (b == 1) & (a == 0)
        cut += int(gone.sum())
        if gone.sum() >= 20:  # what goes is brighter than the foliage that stays (sky, not leaves)
            grey = img.astype(float).mean(axis=2)
            assert np.median(grey[gone]) > np.median(grey[a == 1]) + 20
    assert cut > 0


def test_leaves_from_the_photos_leaf_regions(run, tmp_path, monkeypatch):
    """leaf_placement='segments' (seed 002 §6): leaves from each view's regions, placed on the hull,
    de-duplicated, the sparse branches synthesized; same seed, same model.

    Determinism without a second run of the whole route: the stages before the leaves must give the
    module's first run's points, labels and skeleton (same photos and seed, other leaves; SfM, the frame
    and the mattes are that run's, reused by the fixture, so the carving and the skeleton are what is
    checked), and the leaf stage, called again on the inputs and generator state this run gave it, must
    give the same leaves."""
    import copy

    from scipy.spatial import cKDTree

    import treeform.methods.multiview.leaf_segments as leaf_segments
    from treeform.methods.multiview.pipeline import reconstruct_multiview

    calls = []
    stage = leaf_segments.segmented_leaves

    def spy(*args, **kw):
        calls.append((args, {k: copy.deepcopy(v) if k == "rng" else v for k, v in kw.items()}))
        return stage(*args, **kw)

    monkeypatch.setattr(leaf_segments, "segmented_leaves", spy)
    cap, base, _ = run
    kw = dict(mask_size=320, leaves=1500, lod="low", segmenter="learned", seed=0, cells=200, surface_cells=100,
              leaf_texture="procedural", leaf_placement="segments")
    res = reconstruct_multiview(cap.out / "images", out=tmp_path / "a", **kw)
    st = res.metrics["leaf_regions"]
    assert st["from_regions"] > 100 and st["duplicates"] > 0
    assert res.metrics["leaves"] == len(res.foliage) == st["from_regions"] + st["synthesized"] <= 1500
    f = res.foliage
    assert np.allclose(np.linalg.norm(f.normals, axis=1), 1, atol=1e-5)
    assert np.allclose(np.sum(f.normals * f.up, axis=1), 0, atol=1e-5)
    # the leaves from the regions lie on the carved hull (a leaf point, or the skeleton where none is)
    leaf_pts = res.carved.points[~res.branch]
    d = np.minimum(cKDTree(leaf_pts).query(f.positions[:st["from_regions"]])[0],
                   cKDTree(res.skeleton.positions).query(f.positions[:st["from_regions"]])[0])
    assert np.percentile(d, 99) < 1e-6 + 0.02 * res.metrics["hull_height_m"]
    assert (tmp_path / "a" / "tree.glb").is_file()
    # same seed, same model: the stages before the leaves as in the first run, the leaves as again
    assert np.array_equal(res.carved.points, base.carved.points) and np.array_equal(res.branch, base.branch)
    assert np.array_equal(res.skeleton.positions, base.skeleton.positions)
    (args, kwargs), = calls
    again, _ = stage(*args, **kwargs)
    assert np.array_equal(again.positions, f.positions) and np.array_equal(again.normals, f.normals)
    assert res.metrics["leaf_regions"] is not None and base.metrics["leaf_regions"] is None
