"""The trunk's width read from the photos (methods/multiview/trunk.py)."""

from __future__ import annotations

import numpy as np
import pytest

from treeform.methods.multiview.trunk import trunk_axis, trunk_chain, trunk_diameter
from treeform.sfm.result import SfmResult

BARK = (120, 80, 40)
W, H, F = 320, 240, 300.0


class ColourSegmenter:
    """Stands in for the network: bark-coloured pixels are tree, the rest background."""

    def __init__(self):
        self.calls = 0

    def probabilities(self, image):
        self.calls += 1
        tree = np.all(image == BARK, axis=2)
        p = np.zeros(image.shape[:2] + (3,), np.float32)
        p[..., 0] = ~tree
        p[..., 2] = tree
        return p


def ring(n: int, distance: float, eye: float) -> SfmResult:
    """Level cameras on a ring around the origin, looking at the point ``eye`` metres up the Y axis."""
    K = np.array([[F, 0, W / 2], [0, F, H / 2], [0, 0, 1]])
    c2w = []
    for a in np.linspace(0, 2 * np.pi, n, endpoint=False):
        c = np.array([distance * np.cos(a), eye, distance * np.sin(a)])
        fwd = -c * [1, 0, 1] / distance
        down = np.array([0.0, -1.0, 0.0])
        T = np.eye(4)
        T[:3, :3] = np.column_stack([np.cross(down, fwd), down, fwd])
        T[:3, 3] = c
        c2w.append(T)
    return SfmResult([f"v{k:02d}.jpg" for k in range(n)], [K] * n, c2w, [(W, H)] * n, np.zeros((0, 3)),
                     np.zeros((0, 3), np.uint8), np.zeros(0), [])


def photos(sfm: SfmResult, radius: float, height: float, hedge: float = 0.0) -> list:
    """Each camera's picture of an upright trunk of ``radius`` at the origin, ``height`` tall; a hedge
    (a wider run joined to the trunk) over its lowest ``hedge`` metres."""
    out = []
    for k in range(sfm.n_cameras):
        img = np.full((H, W, 3), (150, 190, 230), np.uint8)
        d = float(np.linalg.norm(sfm.centers[k, [0, 2]]))
        half = F * radius / np.sqrt(d * d - radius * radius)
        top = int(round(sfm.project(np.array([[0.0, height, 0.0]]), k)[0, 1]))
        foot = int(round(sfm.project(np.array([[0.0, 0.0, 0.0]]), k)[0, 1]))
        img[max(0, top):min(H, foot), int(round(W / 2 - half)):int(round(W / 2 + half))] = BARK
        if hedge:
            v = int(round(sfm.project(np.array([[0.0, hedge, 0.0]]), k)[0, 1]))
            img[v:min(H, foot), int(W / 2 - 4 * half):int(W / 2 + 4 * half)] = BARK
        out.append(img)
    return out


AXIS = np.array([[0.0, 0.0, 0.0], [0.0, 12.0, 0.0]])


def test_an_upright_trunk_is_measured_in_metres_from_every_side():
    sfm = ring(8, 20.0, 1.6)
    seg = ColourSegmenter()
    d = trunk_diameter(sfm, photos(sfm, 0.25, 12.0), AXIS, 12.0, segmenter=seg)
    assert seg.calls == 8
    assert d == pytest.approx(0.5, rel=0.08)
    # photos at half the size the SfM saw: the same metres
    small = [img[::2, ::2] for img in photos(sfm, 0.25, 12.0)]
    assert trunk_diameter(sfm, small, AXIS, 12.0, segmenter=ColourSegmenter()) == pytest.approx(0.5, rel=0.12)


def test_a_hedge_against_the_trunk_does_not_widen_it():
    """Rows where something joins the trunk read wider, never narrower: a view's lower quartile is its width."""
    sfm = ring(8, 20.0, 1.6)
    d = trunk_diameter(sfm, photos(sfm, 0.25, 12.0, hedge=0.7), AXIS, 12.0, segmenter=ColourSegmenter())
    assert d == pytest.approx(0.5, rel=0.08)


def test_no_width_where_the_photos_do_not_show_the_trunk():
    sfm = ring(8, 20.0, 1.6)
    blank = [np.full((H, W, 3), 200, np.uint8)] * 8
    assert trunk_diameter(sfm, blank, AXIS, 12.0, segmenter=ColourSegmenter()) is None
    # an axis the cameras look away from (behind every camera but the ring's far side): too few views
    assert trunk_diameter(sfm, photos(sfm, 0.25, 12.0), AXIS + [60.0, 0, 0], 12.0,
                          segmenter=ColourSegmenter()) is None


def test_the_axis_follows_the_largest_subtree():
    from treeform.structures import TreeSkeleton

    # a long low side branch (3 nodes) and the trunk going on up (4 nodes)
    pos = np.array([[0, 0, 0], [0, 1, 0], [1, 1.2, 0], [2, 1.4, 0], [3, 1.6, 0], [0, 2, 0], [0, 3, 0], [0, 4, 0],
                    [0, 5, 0.0]])
    par = np.array([-1, 0, 1, 2, 3, 1, 5, 6, 7])
    sk = TreeSkeleton(pos, par, np.ones(9))
    assert trunk_chain(sk).tolist() == [0, 1, 5, 6, 7, 8]
    assert np.array_equal(trunk_axis(sk), pos[[0, 1, 5, 6, 7, 8]])
