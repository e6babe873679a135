"""End-to-end tests of the learned single-photo method (seed 003 §5) on the bundled sample."""

import json
from pathlib import Path

import numpy as np
import pytest

from treeform._shared.errors import InputError, NoTreeFoundError
from treeform.io import read_glb_counts
from treeform.methods import METHODS
from treeform.methods.learned.pipeline import STAGES, reconstruct

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = ROOT / "src" / "treeform" / "data" / "Celtis_occidentalis_1.jpg"
FAST = dict(max_size=400, lod="low", render_size=128)


@pytest.fixture(scope="module")
def run(tmp_path_factory, gl):
    out = tmp_path_factory.mktemp("learned") / "tree"
    return reconstruct(SAMPLE, out=out, seed=0, **FAST), out


def test_registry_points_at_the_pipeline():
    assert METHODS["learned"][2] == "treeform.methods.learned.pipeline:reconstruct"


def test_outputs_exist_and_agree(run):
    res, out = run
    names = {p.name for p in out.iterdir()}
    assert {"tree.glb", "tree.obj", "skeleton.json", "skeleton.ply", "preview.png", "metrics.json",
            "config.json"} <= names
    assert read_glb_counts(out / "tree.glb") == (res.mesh.n_vertices, res.mesh.n_triangles)
    m = json.loads((out / "metrics.json").read_text())
    assert m["species"] in m["species_probabilities"] and set(STAGES) <= set(m["timings"])
    assert abs(sum(m["species_probabilities"].values()) - 1) < 1e-3
    cfg = json.loads((out / "config.json").read_text())
    assert cfg["method"] == "learned"


def test_tree_matches_the_photo_and_the_predicted_volume(run):
    res, _ = run
    m = res.metrics
    # carved to the silhouette's cone, filled where it shows foliage and wearing the photo's crown:
    # 8.1 % / 0.92 / SSIM 0.64 on 2026-11-26 (as the paper grows it, without these: 35 % / 0.73 / 0.10)
    assert m["reprojection_error"] < 0.15 and m["iou"] > 0.85 and m["front_ssim"] > 0.4
    assert 0.6 < m["depth_width_ratio"] < 1.6  # still a 3D crown, not a card cut-out
    assert m["stems_at_5_percent"] == 1  # one trunk at the ground
    # the tree stands in its RBV: almost every node inside the (slightly grown) volume
    sk = res.skeleton
    h = res.rbv.physical_height
    assert 0.6 * h < sk.positions[:, 1].max() < 1.4 * h
    assert abs(sk.positions[0, 1]) < 0.05 * h


def test_species_override_and_determinism(tmp_path, run):
    res, out = run
    again = reconstruct(SAMPLE, seed=0, **FAST)
    np.testing.assert_array_equal(again.skeleton.positions, res.skeleton.positions)
    other = "pine" if res.species != "pine" else "oak"
    forced = reconstruct(SAMPLE, seed=0, species=other, **FAST)
    assert forced.species == other and forced.metrics["species_predicted"] == res.metrics["species_predicted"]


def test_bad_species_and_treeless_photo(tmp_path):
    with pytest.raises(InputError, match="species"):
        reconstruct(SAMPLE, species="palm", **FAST)
    noise = np.random.default_rng(0).integers(0, 256, (240, 320, 3)).astype(np.uint8)
    with pytest.raises(NoTreeFoundError):
        reconstruct(noise, out=tmp_path / "x", **FAST)
    assert not (tmp_path / "x").exists() or not any((tmp_path / "x").iterdir())


def test_carving_keeps_the_tree_inside_its_silhouette(run):
    """Every leaf card projects onto the tree mask grown by a card; the trunk is never cut."""
    import scipy.ndimage as ndi

    from treeform.crown.sampling import visual_hull_contains

    res, _ = run
    f, sk = res.foliage, res.skeleton
    mpp = res.metrics["metres_per_pixel"]
    half = int(round(np.median(f.size) / mpp)) + 2
    grown = ndi.binary_dilation(ndi.binary_fill_holes(res.segmentation.tree_mask), iterations=half)
    assert visual_hull_contains(res.camera, grown, f.positions).all()
    assert (f.node >= 0).all() and f.node.max() < sk.n_nodes  # cards still name their (renumbered) nodes
    loose = reconstruct(SAMPLE, seed=0, carve=False, leaf_texture="procedural", **FAST)
    assert loose.metrics["reprojection_error"] > res.metrics["reprojection_error"] + 0.1
    assert (sk.order == 0).sum() == (loose.skeleton.order == 0).sum()  # the same trunk, uncut


def test_filling_adds_cards_only_where_the_photo_shows_the_tree_and_none_projects(run):
    from treeform.crown.sampling import fill_silhouette
    from treeform.structures import Foliage

    res, _ = run
    mask = res.segmentation.tree_mask
    cam, mpp = res.camera, res.metrics["metres_per_pixel"]
    f = res.foliage
    # without the cards of the right half, the fill puts cards back there and nowhere else
    uv = cam.project(f.positions)[:, :2]
    mid = np.median(uv[:, 0])
    left = f.subset(uv[:, 0] < mid)
    filled = fill_silhouette(res.skeleton, left, cam, mask, res.rbv, mpp=mpp, seed=0)
    added = filled.subset(np.arange(len(left), len(filled)))
    assert isinstance(filled, Foliage) and len(added) > 50
    au = cam.project(added.positions)[:, :2]
    assert np.mean(au[:, 0] > mid - 2 * np.median(f.size) / mpp) > 0.95
    ui, vi = au[:, 0].astype(int), au[:, 1].astype(int)
    assert mask[vi, ui].all()  # each new card's centre on the tree
    assert (added.node > 0).all() and np.allclose(filled.positions[:len(left)], left.positions)
    again = fill_silhouette(res.skeleton, left, cam, mask, res.rbv, mpp=mpp, seed=0)
    np.testing.assert_array_equal(again.positions, filled.positions)  # deterministic
    assert len(fill_silhouette(res.skeleton, f, cam, mask, res.rbv, mpp=mpp, seed=0)) - len(f) < 0.1 * len(added)


def test_cards_stay_where_their_square_lies_on_the_mask():
    """A card whose centre alone is inside the outline reaches half its edge past it; over a gap it fills it."""
    from treeform.crown.sampling import card_cover, carve_to_silhouette
    from treeform.structures import Camera, Foliage, TreeSkeleton

    cam = Camera(100, 100, 90.0, (0, 0, 10.0), (0, 0, 0), (0, 1, 0))  # 5 px a metre at the origin
    mask = np.zeros((100, 100), bool)
    mask[20:80, 20:80] = True
    mask[45:55, 30:70] = False  # a gap between two whorls
    sk = TreeSkeleton(np.array([[0, -6, 0], [0, 0, 0], [3, 3, 0]]), np.array([-1, 0, 1]), order=np.array([0, 0, 1]))
    pos = [[0, 3, 0], [5.9, 3, 0], [0, 0, 0], [-3, -4, 0]]  # inside; centre in but half out; on the gap; inside
    f = Foliage(pos, [[0, 0, 1]] * 4, [[0, 1, 0]] * 4, [1.6] * 4, [[1, 1, 1]] * 4, [1, 2, 1, 1])
    cover = card_cover(cam, mask, f)
    assert cover[0] == cover[3] == 1.0 and 0.3 < cover[1] < 0.7 and cover[2] == 0.0
    sk2, f2 = carve_to_silhouette(sk, f, cam, mask)
    assert len(f2) == 2 and np.allclose(f2.positions, [[0, 3, 0], [-3, -4, 0]])
    assert sk2.n_nodes == 3  # the limb ends inside the outline: kept


def test_a_limb_looping_round_the_outline_goes_and_one_crossing_a_gap_stays():
    """A stretch of branch that leaves the silhouette and comes back in only after a long loop outside is a wire
    round the crown in the photo's view (those wires were 16 % of the front's pixels on Pinus ponderosa 1): it
    goes, and the branch past it hangs, where it is, from the node before it, if the straight limb between them
    lies within the outline (else it goes too). One that crosses a narrow gap of the mask, or a hole of the
    crown, stays whole."""
    from treeform.crown.sampling import carve_to_silhouette
    from treeform.structures import Camera, Foliage, TreeSkeleton

    cam = Camera(100, 100, 90.0, (0, 0, 10.0), (0, 0, 0), (0, 1, 0))  # 5 px a metre; y = 0 at row 50
    mask = np.zeros((100, 100), bool)
    mask[20:80, 20:80] = True
    mask[48:52, 10:40] = False  # a narrow gap (0.8 m) across the left of the crown
    mask[22:34, 30:45] = False  # a hole in the crown (sky through it), 2.4 m tall
    pos = np.array([[0, -9, 0], [0, 0, 0],                                         # trunk
                    [3, 3, 0], [8, 3, 0], [8, -3, 0], [3, -3, 0], [2, -4, 0],     # loop outside on the right
                    [-3, 1, 0], [-3, 0.6, 0], [-3, 0.2, 0], [-3, -0.2, 0], [-3, -0.6, 0], [-3, -1.5, 0],  # gap
                    [3, 0, 0], [9, 0, 0], [9, 1, 0],                               # out for good
                    [-2, 2, 0], [-2, 3.5, 0], [-2, 5, 0], [-2, 5.9, 0]])           # across a hole
    parent = np.array([-1, 0, 1, 2, 3, 4, 5, 1, 7, 8, 9, 10, 11, 1, 13, 14, 1, 16, 17, 18])
    sk = TreeSkeleton(pos, parent, order=np.array([0, 0] + [1] * 18))
    f = Foliage([[2, -4, 0], [-3, -1.5, 0]], [[0, 0, 1]] * 2, [[0, 1, 0]] * 2, [0.4] * 2, [[1, 1, 1]] * 2, [6, 12])

    def where(s, q):
        return int(np.flatnonzero(np.all(np.isclose(s.positions, q), axis=1))[0])

    cut, fc = carve_to_silhouette(sk, f, cam, mask, bridge=0.1)  # 1.5 m on this 15 m tree
    assert cut.n_nodes == sk.n_nodes - 4  # the loop's two nodes outside, the branch out for good
    assert all(cut.parent[where(cut, q)] == where(cut, p) for q, p in zip(pos[17:], pos[16:19]))  # across the hole
    assert cut.parent[where(cut, [3, -3, 0])] == where(cut, [3, 3, 0])  # hung from the node before the loop
    assert all(cut.parent[where(cut, q)] == where(cut, p) for q, p in zip(pos[8:13], pos[7:12]))  # the gap: whole
    assert np.allclose(fc.positions, f.positions) and fc.node.tolist() == [where(cut, q) for q in f.positions]
    whole, fw = carve_to_silhouette(sk, f, cam, mask, bridge=10.0)  # every branch that comes back stays
    assert whole.n_nodes == sk.n_nodes - 2 and len(fw) == 2
    # no stretch outside the outline kept: the narrow gap lies within it (the mask closed over it), the loop not
    none, fn = carve_to_silhouette(sk, f, cam, mask, bridge=0.0)
    assert np.array_equal(none.positions, cut.positions) and len(fn) == 2


def test_a_cutout_pine_is_not_inflated_past_its_outline(gl):
    # the cut-out's exact alpha leaves gaps between the whorls; cards kept by their centre alone on the
    # outline grown by half a card filled them and overhung it: 40 % error (2026-11-29), 21 % now
    lib = ROOT / "src" / "treeform" / "data" / "library" / "pine_0.png"
    res = reconstruct(lib, seed=0, **FAST)
    assert res.species == "pine" and res.metrics["reprojection_error"] < 0.3


def test_a_crown_the_frame_cuts_is_continued_past_it(tmp_path, gl):
    """The sample with its top 30 % cropped away: the tree goes on above the photo, leaves and all (it was cut
    flat at the frame: no card above it), and the photo's view of it stays as close."""
    from PIL import Image

    img = np.asarray(Image.open(SAMPLE).convert("RGB"))
    Image.fromarray(img[int(0.3 * img.shape[0]):]).save(tmp_path / "cut.jpg")

    def above(res):  # share of the cards and of the skeleton's nodes above the photo's top edge
        return tuple(float((res.camera.project(p)[:, 1] < 0).mean()) for p in (res.foliage.positions,
                                                                            res.skeleton.positions))

    cont = reconstruct(tmp_path / "cut.jpg", seed=0, **FAST)
    flat = reconstruct(tmp_path / "cut.jpg", seed=0, beyond_frame=False, **FAST)
    (cards, nodes), (cards_f, nodes_f) = above(cont), above(flat)
    assert cards > 0.05 and cards > 0.5 * nodes  # measured 14.5 % and 14.7 %
    assert cards_f == 0.0 and nodes_f == 0.0
    assert cont.metrics["reprojection_error"] < flat.metrics["reprojection_error"] + 0.02  # 7.0 against 6.1 %
    with pytest.raises(InputError, match="beyond_frame"):
        reconstruct(tmp_path / "cut.jpg", beyond_frame="yes", **FAST)
