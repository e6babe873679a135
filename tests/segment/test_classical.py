"""Tests of treeform.segment.classical: automatic tree segmentation and user masks."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from treeform._shared.errors import InputError, NoTreeFoundError
from treeform.segment import mask_to_segmentation, segment_tree, wood_colour_mask
from treeform.structures import Segmentation

PHOTOS = Path(__file__).resolve().parents[3] / "shared/data/photos"

# isolated photos with a visible trunk standing on the ground
TRUNK_PHOTOS = ["Catalpa_speciosa_1.jpg", "Celtis_occidentalis_1.jpg", "Fagus_grandifolia_2.jpg", "Thuja_plicata_1.jpg"]
BLUE_SKY_PHOTO = "Catalpa_speciosa_1.jpg"


def _read(name: str) -> np.ndarray:
    if not PHOTOS.is_dir():
        pytest.skip(f"{PHOTOS} is not available")
    bgr = cv2.imread(str(PHOTOS / name), cv2.IMREAD_COLOR)
    assert bgr is not None, name
    return np.ascontiguousarray(bgr[..., ::-1])


_cache: dict[str, tuple[np.ndarray, Segmentation]] = {}


def _segmented(name: str) -> tuple[np.ndarray, Segmentation]:
    if name not in _cache:
        img = _read(name)
        _cache[name] = (img, segment_tree(img))
    return _cache[name]


def drawn_tree(h: int = 480, w: int = 360, *, noise: float = 0.0, seed: int = 0):
    """A synthetic tree: green disc on a brown trunk, blue sky above a green lawn.

    Returns the (h, w, 3) uint8 RGB image and the (h, w) bool tree mask.
    """
    img = np.empty((h, w, 3), np.uint8)
    img[:] = (110, 160, 230)
    img[int(0.8 * h):] = (95, 170, 60)
    mask = np.zeros((h, w), np.uint8)
    cx, cy, r, tw = w // 2, int(0.38 * h), int(0.3 * w), int(0.06 * w)
    for target, trunk_col, crown_col in ((img, (105, 75, 50), (40, 110, 35)), (mask, 1, 1)):
        cv2.rectangle(target, (cx - tw // 2, cy), (cx + tw // 2, int(0.88 * h)), trunk_col, -1)
        cv2.circle(target, (cx, cy), r, crown_col, -1)
    if noise:
        rng = np.random.default_rng(seed)
        img = np.clip(img + rng.normal(0.0, noise, (h, w, 1)), 0, 255).astype(np.uint8)
    return img, mask.astype(bool)


# --------------------------------------------------------------------------- real photos


@pytest.mark.parametrize("name", TRUNK_PHOTOS)
def test_real_photo_mask_is_one_standing_tree(name):
    img, seg = _segmented(name)
    h, w = img.shape[:2]
    assert seg.labels.shape == (h, w) and seg.labels.dtype == np.uint8
    assert seg.alpha.shape == (h, w) and seg.alpha.dtype == np.float32
    mask = seg.tree_mask
    n, _ = cv2.connectedComponents(mask.astype(np.uint8), connectivity=8)
    assert n - 1 == 1, "the tree mask is a single connected component"
    rows = np.nonzero(mask.any(1))[0]
    assert rows.max() > h / 2, "the tree reaches the lower half"
    assert 0.05 < mask.mean() < 0.90
    assert np.all(seg.alpha[mask] >= 0.5) and np.all(seg.alpha[~mask] < 0.5)


@pytest.mark.parametrize("name", TRUNK_PHOTOS)
def test_real_photo_trunk_base_is_wood(name):
    img, seg = _segmented(name)
    h = img.shape[0]
    bottom = np.nonzero(seg.tree_mask.any(1))[0].max()
    base = seg.labels[max(0, bottom - int(0.01 * h)): bottom + 1]
    base = base[base > 0]
    assert (base == 2).mean() > 0.8, "the bottom-most tree pixels (the trunk base) are wood"
    assert seg.wood_mask.sum() > 200
    assert seg.foliage_mask.sum() > seg.wood_mask.sum(), "a leafy tree is mostly foliage"


def test_real_photo_blue_sky_corners_are_background():
    img, seg = _segmented(BLUE_SKY_PHOTO)
    c = max(8, img.shape[0] // 30)
    assert not seg.labels[:c, :c].any()
    assert not seg.labels[:c, -c:].any()


def test_real_photo_is_deterministic():
    img, seg = _segmented(BLUE_SKY_PHOTO)
    again = segment_tree(img, seed=0)
    np.testing.assert_array_equal(seg.labels, again.labels)
    np.testing.assert_array_equal(seg.alpha, again.alpha)


# --------------------------------------------------------------------------- synthetic images


@pytest.mark.parametrize("noise", [0.0, 6.0])
def test_drawn_tree_is_found(noise):
    img, truth = drawn_tree(noise=noise)
    seg = segment_tree(img)
    pred = seg.tree_mask
    iou = (pred & truth).sum() / (pred | truth).sum()
    assert iou >= 0.85
    # the trunk below the crown is wood, the crown is foliage
    h, w = truth.shape
    assert (seg.labels[int(0.75 * h): int(0.86 * h), w // 2 - 3: w // 2 + 4] == 2).mean() > 0.9
    assert (seg.labels[int(0.2 * h): int(0.3 * h), int(0.4 * w): int(0.6 * w)] == 1).mean() > 0.9


def test_drawn_tree_is_deterministic():
    img, _ = drawn_tree(noise=6.0, seed=3)
    a, b = segment_tree(img, seed=7), segment_tree(img, seed=7)
    np.testing.assert_array_equal(a.labels, b.labels)


def test_plain_blue_sky_has_no_tree():
    sky = np.empty((300, 400, 3), np.uint8)
    sky[:] = (110, 160, 230)
    with pytest.raises(NoTreeFoundError, match="no tree found in the photo"):
        segment_tree(sky)


def test_sky_gradient_and_lawn_have_no_tree():
    h, w = 300, 400
    t = np.linspace(0.0, 1.0, h)[:, None, None]
    img = (np.array([70, 120, 220]) * (1 - t) + np.array([200, 220, 245]) * t) * np.ones((1, w, 1))
    img[int(0.7 * h):] = (95, 170, 60)
    img = np.clip(img + np.random.default_rng(0).normal(0, 4, img.shape), 0, 255).astype(np.uint8)
    with pytest.raises(NoTreeFoundError):
        segment_tree(img)


def test_tiny_tree_is_not_a_tree():
    h, w = 480, 360
    img = np.empty((h, w, 3), np.uint8)
    img[:] = (110, 160, 230)
    img[int(0.8 * h):] = (95, 170, 60)
    cv2.circle(img, (w // 2, int(0.75 * h)), 8, (40, 110, 35), -1)  # a bush of 0.1 % of the photo
    img = np.clip(img + np.random.default_rng(1).normal(0, 6, (h, w, 1)), 0, 255).astype(np.uint8)
    with pytest.raises(NoTreeFoundError):
        segment_tree(img)


@pytest.mark.parametrize(
    "bad",
    [np.zeros((20, 20), np.uint8), np.zeros((20, 20, 4), np.uint8), np.zeros((20, 20, 3), np.float32), np.zeros((4, 4, 3), np.uint8)],
)
def test_bad_image_raises_input_error(bad):
    with pytest.raises(InputError, match="image"):
        segment_tree(bad)


# --------------------------------------------------------------------------- user masks


def test_mask_to_segmentation_labels_trunk_as_wood():
    img, truth = drawn_tree(noise=6.0)
    seg = mask_to_segmentation((truth * 255).astype(np.uint8), img)
    np.testing.assert_array_equal(seg.tree_mask, truth)
    h, w = truth.shape
    assert (seg.labels[int(0.75 * h): int(0.86 * h), w // 2 - 3: w // 2 + 4] == 2).mean() > 0.9
    assert (seg.labels[int(0.2 * h): int(0.3 * h), int(0.4 * w): int(0.6 * w)] == 1).mean() > 0.9
    # bool masks work the same way
    np.testing.assert_array_equal(mask_to_segmentation(truth, img).labels, seg.labels)


def test_mask_to_segmentation_size_mismatch():
    img, truth = drawn_tree()
    with pytest.raises(InputError, match=r"mask: size 359 x 480 .* 360 x 480"):
        mask_to_segmentation(truth[:, :-1], img)


def test_mask_to_segmentation_empty_mask():
    img, truth = drawn_tree()
    with pytest.raises(NoTreeFoundError):
        mask_to_segmentation(np.zeros_like(truth), img)


def test_wood_colour_mask():
    px = np.array([[[110, 80, 55], [60, 140, 40], [110, 160, 230]]], np.uint8)  # bark, leaf, sky
    assert wood_colour_mask(px).tolist() == [[True, False, False]]


def test_trunk_run_stops_where_a_same_coloured_crown_begins():
    from treeform.segment.classical import _below_the_crown

    run = np.zeros((100, 60), bool)
    run[40:100, 27:33] = True  # a 6-px trunk standing on the bottom row
    run[5:45, 5:55] = True  # a crown of the trunk's colour on top of it
    cut = _below_the_crown(run)
    rows = np.flatnonzero(cut.any(axis=1))
    assert rows.max() == 99 and 40 <= rows.min() <= 46  # the trunk, not the crown
    assert cut[rows].sum(axis=1).max() <= 6
    lone = np.zeros((100, 60), bool)
    lone[10:100, 28:32] = True  # a plain trunk is kept whole
    assert np.array_equal(_below_the_crown(lone), lone)
