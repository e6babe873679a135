"""Load-time augmentation: geometry keeps image, mask and RBV consistent."""

from __future__ import annotations

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.dataset import Augment, mirror_rbv
from treeform.structures import RadialBoundingVolume

NONE = dict(brightness=0.0, contrast=0.0, saturation=0.0, hue=0.0, blur=0.0)


def _sample(size=64, seed=0):
    rng = np.random.default_rng(seed)
    img = rng.integers(0, 256, (size, size, 3), dtype=np.uint8)
    mask = (rng.random((size, size)) * 3).astype(np.uint8)
    return img, mask


def test_mirror_rbv_matches_mirrored_points():
    rng = np.random.default_rng(1)
    pts = np.c_[rng.uniform(-1, 3, 200), rng.uniform(0, 4, 200), rng.uniform(-2, 1, 200)]
    pts[0] = (0, 0, 0)
    for level in (1, 2, 3, 4, 5):
        a = RadialBoundingVolume.from_points(pts, level=level, axis_origin=(0, 0, 0)).radii
        b = RadialBoundingVolume.from_points(pts * [-1, 1, 1], level=level, axis_origin=(0, 0, 0)).radii
        assert np.allclose(mirror_rbv(a), b)
        assert np.allclose(mirror_rbv(mirror_rbv(a)), a)


def test_flip_and_crop_move_image_and_mask_together():
    img, mask = _sample()
    out = Augment(**NONE, flip=1.0, crop_min=64)(img, mask, rng=np.random.default_rng(0))
    assert out["flipped"] and (out["image"] == img[:, ::-1]).all() and (out["mask"] == mask[:, ::-1]).all()
    # crops: the mask's labels stay where the image's pixels go (a label image carried in the image)
    lab = np.repeat(mask[..., None] * 100, 3, axis=2).astype(np.uint8)
    for s in range(10):
        o = Augment(**NONE, flip=0.5, crop_min=16, out_size=32)(lab, mask, rng=np.random.default_rng(s))
        assert o["image"].shape == (32, 32, 3) and o["mask"].shape == (32, 32)
        assert set(np.unique(o["mask"])) <= {0, 1, 2}


def test_photometric_changes_leave_the_mask_and_are_reproducible():
    img, mask = _sample()
    aug = Augment(crop_min=64, flip=0.0, blur_p=1.0)
    a = aug(img, mask, [np.ones((2, 2))], rng=np.random.default_rng(5))
    b = aug(img, mask, [np.ones((2, 2))], rng=np.random.default_rng(5))
    assert (a["image"] == b["image"]).all() and (a["mask"] == mask).all()
    assert not (a["image"] == img).all()
    assert np.abs(a["image"].astype(float).mean() - img.mean()) < 80


def test_hue_rotation_keeps_grey():
    grey = np.full((16, 16, 3), 120, np.uint8)
    out = Augment(brightness=0, contrast=0, saturation=0.5, hue=0.5, blur=0, flip=0, crop_min=16)(
        grey, np.zeros((16, 16), np.uint8), rng=np.random.default_rng(0))
    assert np.abs(out["image"].astype(int) - 120).max() <= 1


def test_bad_options_and_inputs():
    with pytest.raises(InputError, match="brightness"):
        Augment(brightness=1.5)
    with pytest.raises(InputError, match="crop_min"):
        Augment(crop_min=2)
    with pytest.raises(InputError, match="image"):
        Augment()(np.zeros((8, 8)), np.zeros((8, 8)), rng=np.random.default_rng(0))
