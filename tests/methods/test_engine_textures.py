"""Textures for game engines (issue 15 item 5): alpha-tested atlases keep their colour down the mip chain."""

from __future__ import annotations

import numpy as np

from treeform.methods.envelope.engine import _bleed


def _box_mips(rgb: np.ndarray) -> list:
    """The plain 2x2 box-filter mip chain an engine or WebGL builds (colour not weighted by alpha)."""
    out = [rgb.astype(np.float64)]
    while out[-1].shape[0] > 1:
        a = out[-1]
        out.append(0.25 * (a[0::2, 0::2] + a[1::2, 0::2] + a[0::2, 1::2] + a[1::2, 1::2]))
    return out


def test_every_empty_texel_takes_a_leaf_colour_so_no_mip_level_darkens():
    rgba = np.zeros((128, 128, 4), np.uint8)
    yy, xx = np.mgrid[:128, :128]
    leaf = (yy - 40) ** 2 + (xx - 90) ** 2 < 12 ** 2  # one small leaf far from most of the texture
    rgba[leaf] = (60, 140, 40, 255)
    out = _bleed(rgba)
    assert np.array_equal(out[..., 3], rgba[..., 3])  # alpha unchanged
    assert np.array_equal(out[leaf], rgba[leaf])  # the leaf itself unchanged
    assert (out[..., :3] == (60, 140, 40)).all()  # one colour: every empty texel took it
    for level in _box_mips(out[..., :3]):
        assert np.allclose(level, (60, 140, 40))
    # without the fill past the first rings, the 1x1 level would be near black
    assert _box_mips(rgba[..., :3])[-1].max() < 15


def test_two_colours_meet_between_them_and_an_empty_texture_stays_as_it_is():
    rgba = np.zeros((64, 64, 4), np.uint8)
    rgba[:, :4] = (200, 0, 0, 255)
    rgba[:, -4:] = (0, 0, 200, 255)
    out = _bleed(rgba)
    assert (out[:, :20, 0] > 150).all() and (out[:, -20:, 2] > 150).all()  # each side takes its nearer colour
    assert (out[..., :3].sum(-1) > 150).all()  # nothing left black
    empty = np.zeros((8, 8, 4), np.uint8)
    assert np.array_equal(_bleed(empty), empty)
