"""End-to-end tests of the analysis-by-synthesis method (seed 004) on the bundled sample."""

import json
from pathlib import Path

import numpy as np
import pytest

from treeform._shared.errors import InputError, NoTreeFoundError, OutputError
from treeform.io import read_glb_counts
from treeform.methods import METHODS
from treeform.methods.synthesis.pipeline import STAGES, reconstruct, skeleton2d
from treeform.methods.synthesis.search import ERROR_SCALE, best_so_far, choose, prior, propose, score

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = ROOT / "src" / "treeform" / "data" / "Celtis_occidentalis_1.jpg"
FAST = dict(max_size=320, candidates=5, lod="low", search_size=96, species="oak")


@pytest.fixture(scope="module")
def run(tmp_path_factory, gl):
    out = tmp_path_factory.mktemp("abs") / "tree"
    return reconstruct(SAMPLE, out=out, seed=0, **FAST), out


def test_registry_points_at_the_pipeline():
    assert METHODS["abs"][2] == "treeform.methods.synthesis.pipeline:reconstruct"


def test_outputs_exist_and_agree(run):
    res, out = run
    names = {p.name for p in out.iterdir()}
    assert {"tree.glb", "tree.obj", "skeleton.json", "skeleton.ply", "preview.png", "metrics.json", "config.json",
            "candidates.png", "skeleton2d.png", "skeleton2d.json"} <= names
    assert read_glb_counts(out / "tree.glb") == (res.mesh.n_vertices, res.mesh.n_triangles)
    m = json.loads((out / "metrics.json").read_text())
    assert set(STAGES) <= set(m["timings"])
    assert json.loads((out / "config.json").read_text())["method"] == "abs"
    sk = json.loads((out / "skeleton2d.json").read_text())
    assert len(sk["branches"]) == len(res.skeleton2d.branches) >= 2


def test_search_curve_is_the_running_best(run):
    res, _ = run
    m = res.metrics
    errors = [c["error"] for c in m["candidates"]]
    assert len(errors) == FAST["candidates"] and len({c["index"] for c in m["candidates"]}) == len(errors)
    curve = m["candidate_curve"]
    assert len(curve) == len(errors) and all(b <= a for a, b in zip(curve, curve[1:]))
    assert curve[-1] == pytest.approx(min(errors)) and curve[0] == pytest.approx(errors[0])
    best = max(m["candidates"], key=lambda c: c["score"])
    assert m["search_error_best"] == best["error"] and m["n_branches"] == best["n_branches"]
    # eq. (4): log prior minus the error over its scale
    for c in m["candidates"]:
        assert c["score"] == pytest.approx(np.log(c["prior"]) - c["error"] / ERROR_SCALE, abs=1e-4)


def test_tree_matches_the_photo_and_is_3d(run):
    res, _ = run
    m = res.metrics
    assert m["reprojection_error"] < 0.25 and m["iou"] > 0.75
    assert 0.5 < m["depth_width_ratio"] < 1.6
    sk = res.skeleton
    assert abs(sk.positions[0, 1]) < 1e-6 and 7.0 < sk.positions[:, 1].max() < 13.0
    assert np.ptp(sk.positions[:, 2]) > 0.2 * np.ptp(sk.positions[:, 0])  # branches leave the image plane
    assert len(res.foliage) > 100 and np.all(res.foliage.node < sk.n_nodes)
    assert sk.positions[:, 1].min() >= 0.0 and res.foliage.positions[:, 1].min() >= 0.0  # nothing under the ground


def test_no_twigs_below_the_bole_and_one_stem(run):
    """The L-system's twigs on the lowest main branches hung round the trunk's foot: six branches crossed the
    plane at 5 % of the sample's height. Below the bole (10 %) only the trunk and the given main branches
    stand; leaves whose twig went stay where they were."""
    res, _ = run
    sk = res.skeleton
    h = sk.positions[:, 1].max()
    assert res.metrics["stems_at_5_percent"] == 1
    assert not ((sk.positions[:, 1] < 0.1 * h) & (sk.order > 0)).any()
    assert res.foliage.node.min() >= 0 and res.foliage.node.max() < sk.n_nodes
    free = reconstruct(SAMPLE, seed=0, bole=0.0, **FAST)
    assert free.metrics["stems_at_5_percent"] > 1
    assert len(free.foliage) == len(res.foliage)  # the same leaves: none went with the twigs


def test_same_seed_same_tree(run):
    res, _ = run
    again = reconstruct(SAMPLE, seed=0, **FAST)
    np.testing.assert_array_equal(again.skeleton.positions, res.skeleton.positions)
    np.testing.assert_array_equal(again.foliage.positions, res.foliage.positions)
    assert [c["error"] for c in again.candidates] == [c["error"] for c in res.candidates]


def test_proposals_are_distinct_and_follow_the_prior():
    ps = propose(40, "pine", seed=3)
    assert len(set(ps)) == 40 and ps[0].n_branches == 8
    assert propose(40, "pine", seed=3) == ps
    fixed = propose(10, "oak", n_branches=3, seed=0)
    assert {p.n_branches for p in fixed} == {3}
    assert prior(8, "pine") == 1.0 and prior(4, "pine") < prior(6, "pine") < 1.0
    assert best_so_far([0.3, 0.4, 0.2, 0.25]) == [0.3, 0.3, 0.2, 0.2]
    # a clearly better fit beats the prior's favourite; a near-tie goes to the prior
    assert score(0.05, 4, "pine") > score(0.12, 8, "pine")
    assert score(0.051, 8, "pine") > score(0.05, 5, "pine")


def test_build_candidate_fits_leaves_and_wood_to_the_silhouette(gl):
    import scipy.ndimage as ndi

    from treeform.crown.layout import tree_layout
    from treeform.methods._single_photo import load_photo, photo_camera, segment_or_mask
    from treeform.methods.synthesis.pipeline import build_candidate, foliage_reach, row_half_widths
    from treeform.skeleton import foliage_skeleton

    ph, _ = load_photo(SAMPLE, None, max_size=320)
    seg = segment_or_mask(ph.image, None, segmenter="classical", seed=0)
    lay = tree_layout(seg)
    cam, mpp = photo_camera(ph.shape[1], ph.shape[0], lay, 10.0, 40.0)
    sk = foliage_skeleton(lay.crown_mask, n_branches=5, trunk=np.asarray(lay.trunk_path, float), seed=0)
    reach = foliage_reach(sk, lay.crown_mask)
    p = propose(1, "oak")[0]
    kw = dict(species="oak", base=lay.base, mpp=mpp, camera=cam, leaf_size=0.4, reach=reach)
    free_sk, free = build_candidate(sk, p, edge_distance=None, **kw)
    edge = ndi.distance_transform_edt(seg.tree_mask)
    bound = row_half_widths(seg.tree_mask)
    fit_sk, fit = build_candidate(sk, p, edge_distance=edge, depth_bound=bound, **kw)
    assert 0 < len(fit) < len(free) and fit_sk.n_nodes < free_sk.n_nodes

    def inside(points):
        uv = np.floor(cam.project(points)[:, :2]).astype(int)
        return seg.tree_mask[np.clip(uv[:, 1], 0, ph.shape[0] - 1), np.clip(uv[:, 0], 0, ph.shape[1] - 1)]

    assert inside(free.positions).mean() < 0.97 and inside(fit.positions).all()
    row = np.clip(np.round(lay.base[1] - fit.positions[:, 1] / mpp).astype(int), 0, len(bound) - 1)
    assert np.all(np.abs(fit.positions[:, 2]) <= bound[row] * mpp + 1e-9)
    assert fit.size.max() <= free.size.max() and fit.size.min() < 0.7 * free.size.min()  # cards at the outline shrank
    assert fit.node.max() < fit_sk.n_nodes


def test_bad_input(tmp_path, gl):
    with pytest.raises(InputError, match="candidates"):
        reconstruct(SAMPLE, candidates=0)
    with pytest.raises(InputError, match="species"):
        reconstruct(SAMPLE, species="palm")
    sky = np.zeros((240, 320, 3), np.uint8) + np.array([120, 170, 230], np.uint8)  # a photo of the sky
    with pytest.raises(NoTreeFoundError):
        reconstruct(sky, out=tmp_path / "x", **FAST)
    assert not (tmp_path / "x").exists() or not any((tmp_path / "x").iterdir())


def test_skeleton2d_writes_overlay_and_polylines(tmp_path):
    sk, files = skeleton2d(SAMPLE, out=tmp_path / "sk.png", n_branches=4, max_size=320)
    doc = json.loads(files["json"].read_text())
    assert files["png"].exists() and len(doc["branches"]) == len(sk.branches)
    assert int(np.sum(sk.order == 1)) >= 2 and doc["photo_size"][0] <= 320
    with pytest.raises(InputError):
        skeleton2d(SAMPLE, out=tmp_path / "sk.jpg")
    with pytest.raises(OutputError):
        skeleton2d(SAMPLE, out=tmp_path)


def test_glb_passes_khronos_validator(run):
    import shutil
    import subprocess

    _, out = run
    script = ROOT / "tools" / "gltf_validate.mjs"
    if not shutil.which("node") or not (ROOT / "tools" / "node_modules" / "gltf-validator").exists():
        pytest.skip("node or the npm gltf-validator is not installed (make validator)")
    proc = subprocess.run(["node", str(script), str(out / "tree.glb")], capture_output=True, text=True, timeout=120)
    report = json.loads(proc.stdout)
    assert proc.returncode == 0 and report["numErrors"] == 0, proc.stdout



def test_visible_wood_adds_wood_skeleton_proposals(photos_dir, gl):
    # a leafless plane tree against the sky: its branches are in the photo
    res = reconstruct(photos_dir / "Platanus_occidentalis_2.jpg", seed=0, **{**FAST, "candidates": 6})
    m = res.metrics
    assert m["wood_visible"] is True and res.skeleton2d.meta["mode"] == m["skeleton_source"].replace("foliage", "tree")
    sources = [c["skeleton"] for c in m["candidates"]]
    assert sources[0] == "foliage" and sources.count("wood") == 3
    for c in m["candidates"]:  # the wood's branches are observed: no prior on their number
        if c["skeleton"] == "wood":
            assert c["prior"] == 1.0 and c["n_branches"] == 0 and c["n_first_order"] >= 5
    best = choose(m["candidates"])
    assert m["skeleton_source"] == best["skeleton"] and m["n_first_order"] == best["n_first_order"]
    assert m["search_error_best"] == best["error"]
    # following the wood fits this photo about as well as the best draw of foliage cuts (0.2939 against 0.2943
    # when measured; 0.249 against 0.243 with no twigs below the bole: a margin too thin to assert which wins,
    # as one texel of mip rounding flipped it), and a wood proposal that went wrong (branches off the photo's
    # wood) would be far behind
    wood = min(c["error"] for c in m["candidates"] if c["skeleton"] == "wood")
    assert wood <= 1.05 * min(c["error"] for c in m["candidates"] if c["skeleton"] == "foliage")


def test_leafy_photo_keeps_the_papers_search(run):
    res, _ = run  # the leafy sample shows no wood to speak of: foliage cuts only
    assert res.metrics["wood_visible"] is False
    assert {c["skeleton"] for c in res.metrics["candidates"]} == {"foliage"}


def test_skeleton2d_source(tmp_path, photos_dir):
    bare = photos_dir / "Platanus_occidentalis_2.jpg"
    auto, _ = skeleton2d(bare, out=tmp_path / "a.png", max_size=320)
    assert auto.meta["mode"] == "wood" and int(np.sum(auto.order == 1)) >= 5
    forced, _ = skeleton2d(bare, out=tmp_path / "b.png", max_size=320, source="foliage", n_branches=3)
    assert forced.meta["mode"] == "tree"
    assert skeleton2d(SAMPLE, out=tmp_path / "c.png", max_size=320)[0].meta["mode"] == "tree"
    with pytest.raises(InputError, match="source"):
        skeleton2d(SAMPLE, out=tmp_path / "d.png", source="bark")


def test_photo_textured_leaves_look_like_the_photo(run, gl):
    res, _ = run  # default: each card a tile of the photo, the seen ones facing the camera
    assert res.config.leaf_texture == "photo" and res.foliage.uv is not None
    assert len(res.foliage.uv) == len(res.foliage)
    plain = reconstruct(SAMPLE, seed=0, leaf_texture="procedural", **FAST)
    assert plain.foliage.uv is None
    # the front view shows the photo's crown: structurally closer to the photo than one colour a card, on the
    # same chosen model (the search never sees the leaf texture). Measured at the photo's size and full detail
    # with a 4-model search: at the small settings above (lod="low" most of all) front SSIM swings either way
    # (0.06-0.21 for both textures over seeds and photo sizes). 0.57 against 0.12 when written (the default
    # 24-model search: 0.55 against 0.11, three times the time; seeds 1-3: 0.41 / 0.32 / 0.22 against 0.10 / 0.11 / 0.09)
    photo = reconstruct(SAMPLE, seed=0, species="oak", candidates=4).metrics["front_ssim"]
    one = reconstruct(SAMPLE, seed=0, species="oak", candidates=4, leaf_texture="procedural").metrics["front_ssim"]
    assert photo > 2 * one + 0.05, (photo, one)
    with pytest.raises(InputError, match="leaf_texture"):
        reconstruct(SAMPLE, leaf_texture="bark")


def test_nothing_grows_under_the_ground(gl):
    # a low crown whose L-system twigs hung below the trunk's base (the eval's synthetic case 16:
    # 30 nodes up to 15 cm under the ground, rejected by the RBV of the evaluation)
    from treeform.evaluation.cases import case_names, load_case

    case = load_case(case_names("synthetic:17", seed=0)[16])
    res = reconstruct(case.image, seed=0, **{**FAST, "species": None, "max_size": 640})
    base = res.skeleton.positions[0, 1]
    assert res.skeleton.positions[:, 1].min() >= base and res.foliage.positions[:, 1].min() >= base


def test_a_crown_the_frame_cuts_is_continued_past_it(tmp_path, gl):
    """The sample with its top 30 % cropped away: the 2D skeleton is drawn on the continued crown and the model
    goes on above the photo (it was cut flat at the frame); the search still scores the photo's own view."""
    from PIL import Image

    img = np.asarray(Image.open(SAMPLE).convert("RGB"))
    Image.fromarray(img[int(0.3 * img.shape[0]):]).save(tmp_path / "cut.jpg")
    cont = reconstruct(tmp_path / "cut.jpg", out=tmp_path / "cont", seed=0, **FAST)
    flat = reconstruct(tmp_path / "cut.jpg", seed=0, beyond_frame=False, **FAST)
    above = lambda r: float((r.camera.project(r.foliage.positions)[:, 1] < 0).mean())  # noqa: E731
    assert above(cont) > 0.05 and above(flat) < 0.01, (above(cont), above(flat))  # measured 13.6 % and 0
    top, left = cont.metrics["canvas_offset"]
    assert top > 0 and cont.skeleton2d.shape[0] == cont.photo.shape[0] + top
    assert cont.metrics["reprojection_error"] < flat.metrics["reprojection_error"] + 0.03  # 5.8 against 6.7 %
    # the 2D skeleton's picture shows the photo on that canvas
    assert np.asarray(Image.open(tmp_path / "cont" / "skeleton2d.png")).shape[:2] == cont.skeleton2d.shape[:2]
