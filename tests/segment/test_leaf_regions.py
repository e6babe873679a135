"""Leaf regions (seed 002 §6.1): mean shift, split or merge, bright clusters, ellipses."""

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.segment.leaf_regions import leaf_regions


def _leaves_image():
    """Dark shaded foliage with bright lit leaves: ellipses of 7 x 3 px semi-axes on a grid."""
    import cv2

    img = np.zeros((96, 128, 3), np.uint8)
    img[:] = (20, 45, 20)
    truth = []
    for i, y in enumerate(range(12, 96, 24)):
        for j, x in enumerate(range(12, 128, 24)):
            ang = 30 * ((i + j) % 3)
            col = (110, 200, 90) if (i + j) % 2 == 0 else (60, 120, 50)
            cv2.ellipse(img, (x, y), (7, 3), ang, 0, 360, col, -1)
            truth.append((x, y, ang, (i + j) % 2 == 0))
    return img, truth


def test_regions_are_the_leaves_and_the_bright_ones_are_kept():
    img, truth = _leaves_image()
    area = np.pi * 7 * 3
    r = leaf_regions(img, np.ones(img.shape[:2], bool), leaf_area=area, clusters=4, keep=0.05)
    assert r.labels.shape == img.shape[:2] and r.labels.min() >= 0
    for x, y, ang, bright in truth:
        i = r.labels[y, x]
        assert np.hypot(*(r.centroid[i] - (x, y))) < 1.0           # one region per leaf, centred on it
        assert r.axes[i, 0] == pytest.approx(7.5, abs=1.0) and r.axes[i, 1] == pytest.approx(3.5, abs=1.0)
        d = np.degrees(r.angle[i]) % 180 - ang
        assert min(abs(d), 180 - abs(d)) < 8                          # the ellipse's direction
        assert r.kept[i] == bright                                     # lit leaves kept, shaded ones not
    # the shaded background is split into leaf-sized pieces, none kept
    assert r.area.max() <= 2.0 * area + 1 and not r.kept[r.labels[0, 0]]


def test_small_regions_merge_and_bad_input():
    rng = np.random.default_rng(0)
    img = (rng.random((40, 40, 3)) * 255).astype(np.uint8)  # noise: every pixel its own colour
    mask = np.zeros((40, 40), bool)
    mask[5:35, 5:35] = True
    r = leaf_regions(img, mask, leaf_area=30.0, hr=3)
    assert (r.labels[~mask] == -1).all() and (r.labels[mask] >= 0).all()
    assert r.area.sum() == mask.sum() and np.median(r.area) >= 15    # merged up to leaf size
    again = leaf_regions(img, mask, leaf_area=30.0, hr=3)
    assert np.array_equal(again.labels, r.labels) and np.array_equal(again.kept, r.kept)
    assert len(leaf_regions(img, np.zeros((40, 40), bool), leaf_area=30.0)) == 0
    with pytest.raises(InputError, match="foliage"):
        leaf_regions(img, mask[:10], leaf_area=30.0)
    with pytest.raises(InputError, match="leaf_area"):
        leaf_regions(img, mask, leaf_area=0.0)
    with pytest.raises(InputError, match="image"):
        leaf_regions(img[..., 0], mask, leaf_area=30.0)
