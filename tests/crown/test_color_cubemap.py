"""Colour cubemap by patch-based synthesis (seed 001 §3.3): layout, seams, the front view kept, errors."""

from __future__ import annotations

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.crown.color_cubemap import (color_cubemap, cross_from_faces, cross_layout, cube_edges, edge_strip,
                                          faces_from_cross, synthesize)
from treeform.structures.rdm import direction_to_texel, texel_directions


def _tree_view(size=192, seed=0):
    """An RGBA 'tree': a textured ellipse (leafy noise in greens) on a transparent background."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[:size, :size]
    alpha = ((xx - size / 2) / (0.42 * size)) ** 2 + ((yy - size / 2) / (0.46 * size)) ** 2 < 1
    blobs = rng.random((size // 8, size // 8))
    tex = np.kron(blobs, np.ones((8, 8)))
    rgb = np.stack([40 + 60 * tex, 90 + 110 * tex, 30 + 40 * tex], -1) + rng.normal(0, 6, (size, size, 3))
    return np.dstack([np.clip(rgb, 0, 255), alpha * 255]).astype(np.uint8)


def test_the_cross_is_the_cube_unfolded():
    f = 16
    lay = cross_layout(f)
    assert lay.shape == (48, 64) and sorted(np.unique(lay[lay >= 0])) == list(range(6)) and (lay >= 0).sum() == 6 * f * f
    # a canvas whose every pixel holds its own face and position: faces_from_cross gives each face's
    # texels from its own cell, every texel exactly once
    canvas = np.dstack([lay, np.arange(lay.size).reshape(lay.shape)]).astype(np.int64)
    faces = faces_from_cross(canvas)
    assert faces.shape == (6, f, f, 2)
    assert all(np.all(faces[k, ..., 0] == k) for k in range(6))
    assert len(np.unique(faces[..., 1])) == 6 * f * f
    assert np.array_equal(cross_from_faces(faces, fill=-1), np.where((lay >= 0)[..., None], canvas, -1))
    assert sum(joined for *_e, joined in cube_edges()) == 5 and len(cube_edges()) == 12


@pytest.mark.parametrize("a,b", [(0, 2), (1, 5), (3, 4)])
def test_edge_strips_meet_at_the_edge(a, b):
    f, w = 32, 6
    tex, u = edge_strip(a, b, f, w)
    assert np.all(tex[:, u < 0, 0] == a) and np.all(tex[:, u > 0, 0] == b)
    # the two columns nearest the edge are neighbouring texels on the cube: their directions are close
    d = texel_directions(f)
    left, right = tex[:, w - 1], tex[:, w]
    dl, dr = d[left[:, 0], left[:, 1], left[:, 2]], d[right[:, 0], right[:, 1], right[:, 2]]
    assert np.degrees(np.arccos(np.clip((dl * dr).sum(1), -1, 1))).max() < 2 * 90 / f
    # and direction_to_texel agrees with the strip's texels
    f2, r2, c2 = direction_to_texel(dl, f)
    assert np.array_equal(np.stack([f2, r2, c2], 1), left)


def test_synthesis_fills_only_the_target_from_the_source():
    rng = np.random.default_rng(1)
    src = np.zeros((48, 48, 3), np.uint8)
    src[..., 1] = rng.integers(100, 200, (48, 48))
    canvas = np.full((64, 64, 3), 7, np.uint8)
    fixed = np.zeros((64, 64), bool)
    fixed[:, :20] = True
    target = np.zeros((64, 64), bool)
    target[10:50, 25:60] = True
    out = synthesize(canvas, fixed, target, src, np.ones((48, 48), bool), patch=12, overlap=3, seed=3)
    assert np.array_equal(out[~target], canvas[~target])  # the rest untouched
    g = out[target][:, 1]
    assert g.min() >= 100 and g.max() <= 200 and np.all(out[target][:, [0, 2]] == 0)  # colours of the source
    again = synthesize(canvas, fixed, target, src, np.ones((48, 48), bool), patch=12, overlap=3, seed=3)
    assert np.array_equal(out, again)


def test_color_cubemap_keeps_the_front_view_and_has_no_seams():
    view = _tree_view()
    f = 64
    faces = color_cubemap(view, face=f, patch=16, overlap=4, band=4, seed=0)
    assert faces.shape == (6, f, f, 3) and faces.dtype == np.uint8
    assert np.array_equal(faces, color_cubemap(view, face=f, patch=16, overlap=4, band=4, seed=0))
    # the +Z face shows the view: its centre is the view's centre (scaled), tree texels unchanged
    centre = faces[4, f // 2 - 4:f // 2 + 4, f // 2 - 4:f // 2 + 4].reshape(-1, 3).mean(0)
    assert np.abs(centre - view[90:102, 90:102, :3].reshape(-1, 3).mean(0)).max() < 25
    # every face is foliage-coloured (green dominant), none left black
    means = faces.reshape(6, -1, 3).mean(1)
    assert np.all(means[:, 1] > means[:, 0]) and np.all(means[:, 1] > means[:, 2]) and means.min() > 20
    # no seam on any of the 12 edges: across an edge colours differ like neighbouring texels do
    for a, b, _joined in cube_edges():
        tex, _u = edge_strip(a, b, f, 3)
        s = faces[tex[..., 0], tex[..., 1], tex[..., 2]].astype(float)
        across = np.abs(s[:, 2] - s[:, 3]).mean()
        inside = 0.5 * (np.abs(s[:, 1] - s[:, 2]).mean() + np.abs(s[:, 3] - s[:, 4]).mean())
        assert across < 1.6 * inside + 2, (a, b, across, inside)


def test_color_cubemap_bad_input():
    with pytest.raises(InputError, match="RGBA"):
        color_cubemap(np.zeros((64, 64, 3), np.uint8))
    with pytest.raises(InputError, match="too few"):
        color_cubemap(np.zeros((64, 64, 4), np.uint8))
    with pytest.raises(InputError, match="face"):
        color_cubemap(_tree_view(), face=8)
