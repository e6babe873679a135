"""Procedural backgrounds and the background pool."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from treeform._shared.errors import InputError
from treeform.dataset import BACKGROUND_KINDS, BackgroundPool, procedural_background


@pytest.mark.parametrize("kind", BACKGROUND_KINDS)
def test_each_kind_is_a_deterministic_rgb_image(kind):
    a = procedural_background(48, seed=3, kind=kind)
    assert a.shape == (48, 48, 3) and a.dtype == np.uint8
    assert (a == procedural_background(48, seed=3, kind=kind)).all()
    assert a.std() > 2  # not a flat colour


def test_backgrounds_vary_with_the_seed():
    imgs = np.stack([procedural_background((40, 56), seed=s) for s in range(8)]).astype(float)
    assert imgs.shape == (8, 40, 56, 3)
    means = imgs.reshape(8, -1, 3).mean(axis=1)
    assert np.ptp(means, axis=0).max() > 20  # different palettes
    sky_top, ground_bottom = imgs[:, :4].mean(), imgs[:, -4:].mean()
    assert sky_top > ground_bottom  # sky above, darker ground below (on average)


def test_bad_arguments():
    with pytest.raises(InputError, match="kind"):
        procedural_background(32, kind="moon")
    with pytest.raises(InputError, match="16"):
        procedural_background(8)


def test_pool_mixes_in_user_photos(tmp_path):
    Image.fromarray(np.full((30, 50, 3), (200, 10, 10), np.uint8)).save(tmp_path / "red.png")
    pool = BackgroundPool(tmp_path, photo_fraction=1.0)
    img, desc = pool.sample(24, np.random.default_rng(0))
    assert desc == "photo:red.png" and img.shape == (24, 24, 3) and (img == (200, 10, 10)).all()
    procedural = BackgroundPool(tmp_path, photo_fraction=0.0).sample(24, np.random.default_rng(0))[1]
    assert procedural.startswith("procedural:")


def test_pool_errors(tmp_path):
    with pytest.raises(InputError, match="not a directory"):
        BackgroundPool(tmp_path / "missing")
    with pytest.raises(InputError, match="no images"):
        BackgroundPool(tmp_path)
    (tmp_path / "broken.jpg").write_bytes(b"not a jpeg")
    pool = BackgroundPool(tmp_path, photo_fraction=1.0)
    with pytest.raises(InputError, match="broken.jpg"):
        pool.sample(16, np.random.default_rng(0))
    with pytest.raises(InputError, match="photo_fraction"):
        BackgroundPool(None, photo_fraction=2)
