"""Billboard-cloud geometry (seed 000 §6): superpixels, straight-edge replacement, atlas,
placement and quads, on a synthetic dense tree and on a real RGBA tree."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from treeform._shared.errors import InputError, NoTreeFoundError
from treeform.crown import inflate_envelope
from treeform.geometry.billboard_cloud import (
    FRONT,
    INTERIOR,
    REAR,
    TRUNK,
    CloudFrame,
    build_atlas,
    cloud_mesh,
    luminance,
    place_billboards,
    replace_straight_edges,
    superpixels,
)
from treeform.methods.variations import normalize_rgba, read_rgba, split_crown_trunk

CESIUM = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "billboards" / "cesium_tree_billboard.png"


def _prepared(rgba, n_segments=96):
    pic = normalize_rgba(rgba, size=256)
    labels = split_crown_trunk(pic)
    crown = labels == 1
    sp = superpixels(pic[..., :3], crown, n_segments=n_segments)
    return pic, labels, crown, sp


@pytest.fixture(scope="module")
def dense(dense_tree_rgba):
    pic, labels, crown, sp = _prepared(dense_tree_rgba)
    regions = replace_straight_edges(sp, crown, within=labels > 0, seed=0)
    return pic, labels, crown, sp, regions


@pytest.fixture(scope="module")
def cesium():
    if not CESIUM.is_file():
        pytest.skip("../shared/data/billboards/cesium_tree_billboard.png is not available")
    pic, labels, crown, sp = _prepared(read_rgba(CESIUM))
    return pic, labels, crown, sp, replace_straight_edges(sp, crown, seed=0)


def test_superpixels_partition_the_crown(dense):
    _, _, crown, sp, _ = dense
    assert ((sp > 0) == crown).all()
    n = sp.max()
    assert np.array_equal(np.unique(sp[crown]), np.arange(1, n + 1))
    assert 48 <= n <= 140  # about the 96 asked for


def test_lower_compactness_gives_less_compact_superpixels(dense):
    pic, _, crown, _, _ = dense

    def boundary_fraction(lab):
        return float((np.diff(lab, axis=1) != 0)[crown[:, 1:]].mean())

    loose = superpixels(pic[..., :3], crown, n_segments=96, compactness=0.05)
    tight = superpixels(pic[..., :3], crown, n_segments=96, compactness=5.0)
    assert boundary_fraction(loose) > boundary_fraction(tight)


@pytest.mark.parametrize("which", ["dense", "cesium"])
def test_every_crown_pixel_covered_after_edge_replacement(which, request):
    _, _, crown, _, regions = request.getfixturevalue(which)
    cover = regions.coverage(crown.shape)
    assert (cover[crown] >= 1).all()
    # a fractal silhouette has pieces for most straight edges, the synthetic smooth one for some
    assert len(regions.curves) > (0.5 if which == "cesium" else 0.05) * regions.straight > 0
    for (x0, y0, w, h), m in zip(regions.boxes, regions.masks):  # footprints are tight boxes
        assert m.shape == (h, w) and m[0].any() and m[-1].any() and m[:, 0].any() and m[:, -1].any()


def test_regions_only_grow_and_overlap_their_neighbours(dense):
    _, _, _, sp, regions = dense
    cover = regions.coverage(sp.shape)
    for i, ((x0, y0, w, h), m) in enumerate(zip(regions.boxes, regions.masks)):
        own = sp == i + 1
        ys, xs = np.nonzero(own)
        assert ys.min() >= y0 and xs.min() >= x0 and ys.max() < y0 + h and xs.max() < x0 + w
        assert m[ys - y0, xs - x0].all()  # the superpixel stays inside its grown region
    assert (cover[sp > 0] >= 2).mean() > 0.2  # neighbours overlap (curves and the 2-pixel overlap)


def test_curves_match_endpoints_and_never_cross_their_edge_inward(dense):
    _, _, _, sp, regions = dense
    assert len(regions.curves) == len(regions.edges) > 0
    for (r, px, py, qx, qy), c in zip(regions.edges, regions.curves):
        p, q = np.array([px, py]), np.array([qx, qy])
        assert np.allclose(c[0], p) and np.allclose(c[-1], q)
        d = (q - p) / np.linalg.norm(q - p)
        normal = np.array([d[1], -d[0]])
        # the superpixel's own side of the edge: its pixels next to the edge's middle
        ys, xs = np.nonzero(sp == int(r) + 1)
        rel = np.stack([xs, ys], 1) - (p + q) / 2
        near = np.abs(rel @ d) < 0.4 * np.linalg.norm(q - p)
        inside = np.sign(np.median((rel @ normal)[near & (np.abs(rel @ normal) < 4)]))
        assert inside != 0
        offsets = (c - p) @ normal * -inside  # positive = away from the superpixel
        assert offsets.min() >= -0.5 - 1e-9 and offsets.max() >= 1.0


def test_contours_rebuild_the_footprints(dense):
    _, labels, _, _, regions = dense
    tree = labels > 0
    for (x0, y0, w, h), m, cs in zip(regions.boxes, regions.masks, regions.contours):
        canvas = np.zeros(tree.shape, np.uint8)
        cv2.drawContours(canvas, [c.reshape(-1, 1, 2) for c in cs], -1, 1, thickness=cv2.FILLED)
        rebuilt = canvas.astype(bool) & tree
        assert np.array_equal(rebuilt[y0:y0 + h, x0:x0 + w], m) and rebuilt.sum() == m.sum()


def test_edge_replacement_is_seeded(dense):
    _, labels, crown, sp, regions = dense
    again = replace_straight_edges(sp, crown, within=labels > 0, seed=0)
    other = replace_straight_edges(sp, crown, within=labels > 0, seed=1)
    assert np.array_equal(again.edges, regions.edges)
    assert all(np.array_equal(a, b) for a, b in zip(again.masks, regions.masks))
    assert not all(np.array_equal(a, b) for a, b in zip(other.curves, regions.curves))


def test_atlas_holds_every_crop(dense):
    pic, _, _, _, regions = dense
    atlas, rects = build_atlas(pic, regions.boxes, regions.masks)
    assert atlas.shape[0] % 4 == 0 and atlas.shape[1] % 4 == 0
    for (x0, y0, w, h), (u0, v0, rw, rh), m in zip(regions.boxes, rects, regions.masks):
        assert (rw, rh) == (w, h)
        tile = atlas[v0:v0 + h, u0:u0 + w]
        assert np.array_equal(tile[..., 3] == 255, m) and not tile[..., 3][~m].any()
        assert np.array_equal(tile[..., :3][m], pic[y0:y0 + h, x0:x0 + w, :3][m])
    # crops never overlap: every opaque atlas texel belongs to exactly one rectangle
    owner = np.zeros(atlas.shape[:2], np.int32)
    for u0, v0, w, h in rects:
        owner[v0 - 1:v0 + h + 1, u0 - 1:u0 + w + 1] += 1
    assert owner.max() == 1


@pytest.fixture(scope="module")
def placed(dense):
    pic, labels, crown, _, regions = dense
    trunk_px = labels == 2
    ys, xs = np.nonzero(trunk_px)
    tbox = (xs.min(), ys.min(), xs.max() + 1 - xs.min(), ys.max() + 1 - ys.min())
    boxes = np.vstack([regions.boxes, tbox])
    masks = list(regions.masks) + [trunk_px[tbox[1]:tbox[1] + tbox[3], tbox[0]:tbox[0] + tbox[2]]]
    height = inflate_envelope(crown, k=None).front_z
    lum = luminance(pic, boxes, masks)
    kw = dict(crown=crown, trunk=len(masks) - 1, seed=3)
    return boxes, masks, lum, height, labels > 0, place_billboards(boxes, masks, lum, height, labels > 0, **kw), kw


def test_placement_layers(placed):
    boxes, masks, lum, height, tree, p, kw = placed
    n = len(boxes) - 1
    counts = p.counts()
    assert counts["front"] == n and counts["trunk"] == 1
    assert counts["rear"] > 0.8 * n and counts["interior"] > 0.3 * n
    front = p.layer == FRONT
    # the front layer keeps the image positions; darker than average -> deeper
    assert np.array_equal(p.sprite[front], np.arange(n))
    assert np.allclose(p.x[front], boxes[:n, 0] + boxes[:n, 2] / 2)
    assert np.allclose(p.y[front], boxes[:n, 1] + boxes[:n, 3] / 2)
    assert (p.z[front] >= 0).all()
    flat = place_billboards(boxes, masks, lum, height, tree, **{**kw, "push": 0.0}).z[front]
    dark = (lum[:n].mean() - lum[:n]).clip(0)
    free = p.z[front] > 0  # not clamped at the picture plane
    expected = 0.5 * height.max() * dark / dark.max()
    assert np.allclose((flat - p.z[front])[free], expected[free], atol=1e-3) and (dark[free] > 0).sum() > 10
    assert (p.shade[~(p.layer == INTERIOR)] == 1).all()
    t = p.layer == TRUNK
    assert p.z[t] == 0 and p.sprite[t] == n
    # rear: behind the picture plane, mirrored across the crown (positions only)
    rear = p.layer == REAR
    assert (p.z[rear] < 0).all()
    cx = (tree.nonzero()[1].min() + tree.nonzero()[1].max() + 1) / 2
    left_front = (p.x[front] < cx - 20).mean()
    right_rear_of_left = (p.x[rear][p.x[front][p.sprite[rear]] < cx - 20] > cx).mean()
    assert 0.2 < left_front < 0.8 and right_rear_of_left > 0.8
    # interior: inside the crown volume, darker the deeper inside
    inner = p.layer == INTERIOR
    xi, yi = p.x[inner].astype(int), p.y[inner].astype(int)
    assert (np.abs(p.z[inner]) <= height[yi, xi] + 1).mean() > 0.9
    assert (p.shade[inner] < 1).all() and (p.shade[inner] >= 0.5).all()
    assert np.corrcoef(np.abs(p.z[inner]) / np.maximum(height[yi, xi], 1), p.shade[inner])[0, 1] > 0.5


def test_rear_and_interior_stay_inside_the_tree(placed):
    boxes, masks, _, _, tree, p, _ = placed
    for s, x, y, k in zip(p.sprite, p.x, p.y, p.layer):
        if k in (REAR, INTERIOR):
            w, h = boxes[s, 2], boxes[s, 3]
            ox, oy = int(round(x - w / 2)), int(round(y - h / 2))
            canvas = np.zeros((tree.shape[0] + 2 * h, tree.shape[1] + 2 * w), bool)
            canvas[oy + h:oy + 2 * h, ox + w:ox + 2 * w] = masks[s]
            inside = canvas[h:-h, w:-w] & tree
            assert inside.sum() >= 0.98 * masks[s].sum()


def test_placement_is_seeded(placed):
    boxes, masks, lum, height, tree, p, kw = placed
    again = place_billboards(boxes, masks, lum, height, tree, **kw)
    other = place_billboards(boxes, masks, lum, height, tree, **{**kw, "seed": 4})
    assert all(np.array_equal(getattr(p, f), getattr(again, f)) for f in ("sprite", "x", "y", "z", "yaw", "shade"))
    assert not np.array_equal(p.yaw, other.yaw)


def test_mesh_quads_project_onto_their_boxes(placed, dense):
    pic = dense[0]
    boxes, masks, _, _, tree, p, _ = placed
    atlas, rects = build_atlas(pic, boxes, masks)
    frame = CloudFrame.for_tree(tree, tree_height=12.0)
    mesh = cloud_mesh(p, boxes, rects, atlas, frame)
    part = mesh.parts[0]
    assert part.material.alpha_mode == "MASK" and part.material.double_sided and part.material.texture is atlas
    # the tree's base is the origin, its top 12 m above
    ys = np.nonzero(tree.any(1))[0]
    assert np.allclose(frame.to_world(*frame.origin, 0.0), 0.0)
    assert np.isclose(frame.to_world(frame.origin[0], ys.min(), 0.0)[1], 12.0)
    # every vertex projects onto the top or bottom edge of its billboard's box
    uvz = frame.camera().project(part.positions)
    assert np.isfinite(uvz).all() and uvz[:, 0].min() >= -1 and uvz[:, 0].max() <= pic.shape[1] + 1
    rows = np.sort(np.unique(np.round(uvz[:, 1], 3)))
    edges = np.unique(np.round(np.concatenate([p.y - boxes[p.sprite, 3] / 2, p.y + boxes[p.sprite, 3] / 2]), 3))
    assert np.isin(rows, edges).all()
    assert (part.colors[:, 0] <= 1).all() and (part.colors[:, 0] >= 0.5).all()


@pytest.mark.parametrize("call, match", [
    (lambda: superpixels(np.zeros((8, 8, 3), np.uint8), np.zeros((8, 8), bool)), "no crown"),
    (lambda: superpixels(np.zeros((8, 8, 3), np.uint8), np.ones((8, 9), bool)), "rgb"),
    (lambda: superpixels(np.zeros((8, 8, 3), np.uint8), np.ones((8, 8), bool), n_segments=0), "n_segments"),
    (lambda: superpixels(np.zeros((8, 8, 3), np.uint8), np.ones((8, 8), bool), compactness=-1), "compactness"),
    (lambda: replace_straight_edges(np.ones((8, 8), int), np.zeros((8, 8), bool)), "labels"),
    (lambda: replace_straight_edges(np.ones((8, 8), int), np.ones((8, 8), bool), max_arc=1.0), "max_arc"),
    (lambda: build_atlas(np.zeros((8, 8, 3), np.uint8), np.zeros((1, 4), int), [np.ones((0, 0), bool)]), "rgba"),
    (lambda: place_billboards(np.array([[0, 0, 2, 2]]), [np.ones((2, 2), bool)], [0.5], np.zeros((4, 4)),
                              np.ones((4, 4), bool), yaw=(50, 10)), "yaw"),
    (lambda: CloudFrame.for_tree(np.zeros((8, 8), bool)), "no opaque"),
])
def test_bad_arguments_name_themselves(call, match):
    with pytest.raises((InputError, NoTreeFoundError), match=match):
        call()
