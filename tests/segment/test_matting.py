"""Trimap from a segmentation and alpha matting (seed 000 §4.3, Fig. 4) on a small image.

The first PyMatting call compiles its numba kernels (~50 s once, then cached); the
image here is 128 px so the matting itself takes well under a second.
"""

from pathlib import Path

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.segment.matting import (alpha_matting, background_gaps, estimate_foreground, make_trimap, matte_tree,
                                      sky_gaps)
from treeform.structures import Segmentation

pytest.importorskip("pymatting")


def _scene(n=128, seed=0):
    """Blue sky, a textured green crown with soft edges and a sky gap, a brown trunk."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[:n, :n]
    r = np.hypot(xx - n / 2, yy - 0.4 * n)
    alpha = np.clip((0.3 * n - r) / 2.0 + 0.5, 0, 1)  # soft crown edge, 2 px
    trunk = (np.abs(xx - n / 2) < 0.04 * n) & (yy > 0.5 * n) & (yy < 0.95 * n)
    alpha = np.maximum(alpha, trunk.astype(float))
    gap = np.hypot(xx - 0.58 * n, yy - 0.33 * n) < 0.06 * n
    alpha[gap] = 0.0
    sky = np.stack([np.full((n, n), 90.0), np.full((n, n), 150.0), np.full((n, n), 235.0)], -1)
    leaves = np.stack([40 + 40 * rng.random((n, n)), 110 + 60 * rng.random((n, n)), 30 + 20 * rng.random((n, n))], -1)
    leaves[trunk] = (110, 75, 45)
    img = (alpha[..., None] * leaves + (1 - alpha[..., None]) * sky).astype(np.uint8)
    labels = np.zeros((n, n), np.uint8)
    labels[(np.hypot(xx - n / 2, yy - 0.4 * n) < 0.3 * n)] = 1  # the segmentation does not know the gap
    labels[trunk] = 2
    return img, Segmentation(labels), alpha


def test_trimap_layout():
    img, seg, _ = _scene()
    tri = make_trimap(img, seg, seed=0)
    assert set(np.unique(tri)) <= {0.0, 0.5, 1.0}
    assert (tri[~seg.tree_mask] <= 0.5).all()  # outside the tree: unknown band or background
    assert tri[0, 0] == 0.0 and (tri[seg.wood_mask] >= 0.5).all() and (tri == 1).sum() > 50
    # sparse foreground points (the paper's): most of the crown stays unknown
    crown = seg.foliage_mask
    sparse = make_trimap(img, seg, point_spacing=6.0, seed=0)
    assert 0.01 < (sparse[crown] == 1).mean() < 0.2
    assert (tri[crown] == 1).mean() > 0.3
    assert np.array_equal(tri, make_trimap(img, seg, seed=0))
    assert sky_gaps(img, seg)[40:47, 70:78].any()  # the sky seen through the crown


def test_matting_recovers_the_soft_mask_and_clean_colours():
    img, seg, truth = _scene()
    rgba, tri = matte_tree(img, seg, seed=0)
    a = rgba[..., 3] / 255.0
    m, t = a > 0.5, truth > 0.5
    assert (m & t).sum() / (m | t).sum() > 0.9
    assert a[int(0.33 * 128), int(0.58 * 128)] < 0.5  # the gap is see-through
    fg = estimate_foreground(img, a)
    edge = (a > 0.2) & (a < 0.8)
    assert fg[edge][:, 2].mean() < img[edge][:, 2].mean()  # sky blue removed from edge colours


def test_reduced_resolution_and_bad_inputs():
    img, seg, _ = _scene()
    tri = make_trimap(img, seg, seed=0)
    a = alpha_matting(img, tri, max_side=64)
    assert a.shape == (128, 128) and a.dtype == np.float32 and 0 <= a.min() and a.max() <= 1
    assert (a[tri == 1] == 1).all() and (a[tri == 0] == 0).all()
    with pytest.raises(InputError):
        alpha_matting(img, np.full((128, 128), 0.5))
    with pytest.raises(InputError):
        make_trimap(img, Segmentation(np.zeros((128, 128), np.uint8)))
    with pytest.raises(InputError):
        make_trimap(img[:64], seg)


def test_billboard_from_a_real_photo(tmp_path):
    from treeform.methods.variations import billboard

    sample = Path(__file__).resolve().parents[2] / "src" / "treeform" / "data" / "Celtis_occidentalis_1.jpg"
    res = billboard(sample, out=tmp_path / "tree.png", sheet=tmp_path / "sheet.png", photo_max_size=128)
    assert res.metrics["iou"] > 0.8
    from PIL import Image

    with Image.open(tmp_path / "tree.png") as im:
        assert im.mode == "RGBA"
    assert (tmp_path / "sheet.png").is_file()


def test_mattes_on_threads_side_by_side_leave_standard_output_as_it_was(capsys):
    """PyMatting's prints are swallowed while any thread mattes; a redirect per thread (which
    overlapping threads undo in the wrong order) lost the process's output for good."""
    import sys
    import threading

    from treeform.segment import matting

    image, _, alpha = _scene(64)
    tri = np.where(alpha > 0.99, 1.0, np.where(alpha < 0.01, 0.0, 0.5))
    before = sys.stdout
    start = threading.Barrier(3)
    results = []

    def work():
        start.wait()
        with matting._quiet_stdout():
            print("swallowed")
            results.append(alpha_matting(image, tri))

    threads = [threading.Thread(target=work) for _ in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert sys.stdout is before and matting._QUIET["depth"] == 0
    print("still here")
    out = capsys.readouterr().out
    assert "still here" in out and "swallowed" not in out
    assert len(results) == 3 and all(np.array_equal(r, results[0]) for r in results)  # the same matte each time


def _walled_crown(n=120, seed=1):
    """An overcast sky over a brick wall and a lawn; a textured green crown with two gaps (one on the
    sky, one on the wall), a lawn-green patch in it, and a pale grey trunk under it (the tree's lowest fifth)."""
    rng = np.random.default_rng(seed)
    img = np.empty((n, n, 3), np.uint8)
    img[:] = (205, 205, 210)  # overcast sky
    img[45:95] = (150, 70, 55)  # brick wall
    img[95:] = (90, 160, 60)  # lawn
    yy, xx = np.mgrid[:n, :n]
    crown = (np.abs(xx - 60) < 32) & (yy >= 15) & (yy < 84)
    leaves = np.stack([30 + 40 * rng.random((n, n)), 80 + 50 * rng.random((n, n)), 20 + 30 * rng.random((n, n))], -1)
    img[crown] = leaves[crown].astype(np.uint8)
    img[25:45, 40:52] = (90, 160, 60)  # sunlit leaves the colour of the lawn
    trunk = (np.abs(xx - 60) < 4) & (yy >= 84) & (yy < 100)
    img[trunk] = (200, 200, 205)  # a pale trunk, the sky's colour
    sky_gap, wall_gap = (slice(20, 26), slice(68, 76)), (slice(58, 66), slice(40, 48))
    img[sky_gap] = (205, 205, 210)
    img[wall_gap] = (150, 70, 55)
    tree = crown | trunk  # what a coarse segmenter returns: the gaps filled in
    return img, tree, trunk, sky_gap, wall_gap


def test_background_gaps_are_whatever_surrounds_the_tree_not_a_hue():
    from treeform.segment.classical import ground_line

    img, tree, trunk, sky_gap, wall_gap = _walled_crown()
    ground = np.full(img.shape[1], 95)
    gaps = background_gaps(img, tree, ground=ground)
    # the overcast sky and the brick wall seen through the crown: neither blue nor bright
    assert gaps[sky_gap].all() and gaps[wall_gap].all()
    assert not sky_gaps(img, Segmentation(tree.astype(np.uint8)))[wall_gap].any()  # the bright-sky rule misses the wall
    # not the leaves, not the lawn-coloured leaves (the lawn is under the ground line), and not the pale trunk
    # under the crown (the tree's lowest rows are left alone)
    assert gaps.sum() == 6 * 8 + 8 * 8
    assert not gaps[trunk].any() and not gaps[25:45, 40:52].any()
    # wood is never a gap
    wood = np.zeros_like(tree)
    wood[wall_gap] = True
    assert not background_gaps(img, tree, wood=wood, ground=ground)[wall_gap].any()
    assert ground_line(img).shape == (img.shape[1],)


def test_background_gaps_checks_and_edge_cases():
    img, tree, *_ = _walled_crown()
    assert not background_gaps(img, np.zeros_like(tree)).any()
    assert not background_gaps(img, np.ones_like(tree)).any()  # nothing around the tree to compare with
    with pytest.raises(InputError, match="tree"):
        background_gaps(img, tree[:-1])
    with pytest.raises(InputError, match="ratio"):
        background_gaps(img, tree, ratio=0)
    with pytest.raises(InputError, match="ground"):
        background_gaps(img, tree, ground=np.zeros(3))
