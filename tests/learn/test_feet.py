"""The trunk-foot detector (issue 16 item 2): scenes, targets, peaks and the shipped feet.onnx (no torch)."""

import numpy as np
import pytest

from treeform._shared.errors import InputError, ModelError
from treeform.data import GROUP_TREES, data_path, group_photo
from treeform.learn.feet import STRIDE, feet_targets, heatmap_peaks, score_feet
from treeform.learn.infer import FeetDetector, weights_path


@pytest.fixture(scope="module")
def sprites():
    from treeform.dataset.scenes import load_cutouts

    return load_cutouts(data_path("library"))


@pytest.fixture(scope="module")
def group_truth(sprites):
    from treeform.dataset.scenes import group_scene

    by_name = {s.name: s for s in sprites}
    feet = np.array([(x, z) for _, x, z, _ in GROUP_TREES])
    heights = np.array([h for *_, h in GROUP_TREES])
    return group_scene([by_name[n] for n, *_ in GROUP_TREES], feet, heights, np.random.default_rng(0))


def test_targets_and_peaks_give_the_feet_back():
    feet = np.array([[21.0, 70.0], [30.0, 71.0], [90.0, 40.0]])
    heat, offset, weight = feet_targets(feet, [True, True, False], (24, 32))
    assert heat.max() == 1.0 and (heat == 1.0).sum() == 2
    assert weight[10, 22] == 0 and weight.min() == 0 and weight[17, 5] == 1  # no loss near the hidden foot
    got = heatmap_peaks(heat, offset, threshold=0.5)
    assert np.allclose(np.sort(got[:, 0]), [21.0, 30.0]) and np.allclose(got[:, 1], [70.0, 71.0][: len(got)])
    # a foot outside the frame has no target; non-maximum suppression keeps the stronger of two close peaks
    h2, _, _ = feet_targets([[-5.0, 10.0], [10.0, 500.0]], [True, True], (24, 32))
    assert h2.max() == 0
    p = np.zeros((10, 10))
    p[4, 4], p[4, 6] = 0.9, 0.8
    assert len(heatmap_peaks(p, min_distance=1.5)) == 2 and len(heatmap_peaks(p, min_distance=3)) == 1
    with pytest.raises(InputError, match="prob"):
        heatmap_peaks(np.zeros(5))


def test_scenes_are_reproducible_and_their_feet_stand_on_their_trees(sprites):
    from treeform.dataset.feet_scenes import feet_scene

    a = feet_scene(sprites, np.random.default_rng(7), size=(192, 144))
    b = feet_scene(sprites, np.random.default_rng(7), size=(192, 144))
    assert np.array_equal(a["image"], b["image"]) and np.array_equal(a["feet"], b["feet"])
    n = 0
    for seed in range(12):
        sc = feet_scene(sprites, np.random.default_rng(seed), size=(192, 144), empty=0.0)
        assert sc["image"].shape == (144, 192, 3) and sc["feet"].shape[1] == 2
        assert ((sc["feet"] >= 0) & (sc["feet"] < [192, 144])).all()  # only feet inside the frame are targets
        for (u, v), vis in zip(sc["feet"], sc["visible"]):
            if vis:  # a visible foot has tree pixels just above it
                win = sc["instances"][max(0, int(v) - 6):int(v) + 1, max(0, int(u) - 4):int(u) + 5]
                n += int((win > 0).any())
    assert n >= 10
    with pytest.raises(InputError, match="sprites"):
        feet_scene([], np.random.default_rng(0))


def test_layout_places_trees_nearly_behind_others_as_asked():
    from treeform.dataset.feet_scenes import _layout

    W, H = 400, 300
    for seed in range(5):
        t = _layout(6, np.random.default_rng(seed), W, H, 120, behind=1.0, behind_aside=0.05)
        u, v = np.array([a[0] for a in t]), np.array([a[1] for a in t])
        for k in range(1, 6):  # each later tree a little aside of and farther than one placed before it
            near = np.abs(u[:k] - u[k]) <= 0.05 * W + 1e-9
            assert near.any() and (v[k] <= v[:k][near].max() + 1e-9)
    spread = [np.ptp([a[0] for a in _layout(6, np.random.default_rng(s), W, H, 120, behind=0.0)]) for s in range(5)]
    assert min(spread) > 0.25 * W  # none behind: the trees scatter over the frame


def test_score_feet_counts_matches_misses_and_false_feet():
    s = score_feet([np.array([[10.0, 10.0, 0.9], [50.0, 50.0, 0.5]])], [np.array([[11.0, 10.0], [80.0, 80.0]])],
                   [np.array([True, True])], tolerance=5.0)
    assert s["recall"] == 0.5 and s["precision"] == 0.5 and s["false_feet"] == 1 and s["median_error_px"] == 1.0


def test_shipped_detector_finds_the_three_feet_of_the_sample_group(group_truth):
    p = weights_path("feet")
    assert p.is_file() and p.stat().st_size <= 3 * 2**20
    det = FeetDetector()
    img = group_photo()
    feet = det.detect(img, threshold=0.5)
    assert len(feet) == 3
    truth = group_truth["feet_px"][np.argsort(group_truth["feet_px"][:, 0])]
    found = feet[np.argsort(feet[:, 0]), :2]
    assert np.abs(found - truth).max() < 0.02 * img.shape[1]
    again = det.detect(img, threshold=0.5)
    assert np.array_equal(feet, again)  # deterministic
    prob, offset, scale = det.heatmap(img)
    assert prob.shape == (288 // STRIDE, 384 // STRIDE) and offset.shape == (2, *prob.shape) and scale == (0.4, 0.4)


def test_learned_feet_split_the_sample_group_into_its_three_trees(group_truth):
    from treeform.segment.instances import find_tree_instances

    for feet in ("learned", "both"):
        inst = find_tree_instances(group_truth["image"], feet=feet)
        assert len(inst) == 3
        found = np.array([t.base for t in inst])
        truth = group_truth["feet_px"][np.argsort(group_truth["feet_px"][:, 0])]
        assert np.abs(found - truth).max() < 0.02 * 960
    with pytest.raises(InputError, match="feet"):
        find_tree_instances(group_truth["image"], feet="nope")


def test_missing_and_corrupt_feet_weights_name_the_file_and_make_weights(tmp_path, group_truth):
    from treeform.segment.instances import find_tree_instances

    with pytest.raises(ModelError, match=r"nope\.onnx.*missing.*make weights"):
        FeetDetector(tmp_path / "nope.onnx")
    bad = tmp_path / "bad.onnx"
    bad.write_bytes(b"not a graph")
    with pytest.raises(ModelError) as exc:
        find_tree_instances(group_truth["image"], feet="learned", feet_weights=bad)
    msg = str(exc.value)
    assert "bad.onnx" in msg and "make weights" in msg and "\n" not in msg
    with pytest.raises(ModelError, match="not the foot detector"):
        FeetDetector(weights_path("seg"))
