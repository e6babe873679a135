"""The network's wood on full-size tiles of a photo (segment.learned.wood_at_full_size, the multi-view mattes)."""

from __future__ import annotations

import numpy as np

from treeform.methods.multiview.pipeline import TILE_WOOD_FROM, _tile_wood
from treeform.segment.learned import wood_at_full_size


class RedIsWood:
    """Stands in for the network: red pixels are wood, and it records the squares it is given."""

    side = 320

    def __init__(self):
        self.shapes = []

    def probabilities(self, image):
        self.shapes.append(image.shape[:2])
        wood = image[..., 0] > 128
        p = np.zeros(image.shape[:2] + (3,), np.float32)
        p[..., 0] = ~wood
        p[..., 2] = wood
        return p


def photo(w: int, h: int) -> np.ndarray:
    img = np.full((h, w, 3), (60, 120, 200), np.uint8)
    img[:, 333] = (200, 90, 60)  # a limb one pixel wide, across the tiles' seams
    img[500:502, 100:900] = (200, 90, 60)
    return img


def test_tiles_cover_the_photo_at_its_own_size_and_meet_without_seams():
    img = photo(1024, 768)
    net = RedIsWood()
    wood = wood_at_full_size(img, net)
    assert wood.shape == (768, 1024)
    assert all(s == (320, 320) for s in net.shapes) and len(net.shapes) == 4 * 3  # full-size squares, a quarter shared
    assert np.array_equal(wood > 0.5, img[..., 0] > 128)


def test_a_limb_a_pixel_wide_stays_in_the_half_size_matte():
    img = photo(1024, 768)
    mask = _tile_wood(img, (384, 512), RedIsWood())
    assert mask.shape == (384, 512)
    cols = np.flatnonzero(mask[:200].any(0))
    assert cols.tolist() == [166]  # column 333 at half size, one pixel wide, every row
    assert mask[:200, 166].all() and mask[250, 50:450].all()
    assert mask.sum() < 384 + 2 * 410  # nothing else


def test_tiles_only_where_the_photo_is_finer_than_the_network_sees():
    assert TILE_WOOD_FROM * RedIsWood.side > 480  # the evaluation's 480-px captures: the matte alone
    assert TILE_WOOD_FROM * RedIsWood.side <= 1024  # the 1024-px photos a phone's capture is read at
