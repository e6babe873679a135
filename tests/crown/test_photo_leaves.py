"""Leaf cards textured with the photo's own crown: the atlas reproduces the photo from its camera."""

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.crown.photo_leaves import photo_leaf_atlas
from treeform.structures import Camera, Foliage

CAM = Camera(96, 96, 40.0, (0.0, 0.0, 10.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0))


def _photo(seed=0):
    """A textured 'crown' photo: smooth colour waves plus fine noise, alpha a disc."""
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[:96, :96]
    img = np.stack([128 + 90 * np.sin(xx / 6.0), 128 + 90 * np.cos(yy / 5.0), 128 + 60 * np.sin((xx + yy) / 9.0)],
                   axis=-1)
    img = np.clip(img + rng.normal(0, 6, img.shape), 0, 255).astype(np.uint8)
    alpha = ((yy - 48) ** 2 + (xx - 48) ** 2 < 36**2).astype(np.float32)
    return img, alpha


def _cards(n, *, tilt=0.0, seed=0):
    """n cards on the z = 0 plane (in front of the camera), tilted by ``tilt`` about random in-plane axes."""
    rng = np.random.default_rng(seed)
    pos = np.column_stack([rng.uniform(-1.6, 1.6, (n, 2)), rng.uniform(-0.5, 0.5, n)])
    normal = np.tile([0.0, 0.0, 1.0], (n, 1))
    if tilt:
        axis = rng.normal(size=(n, 3))
        axis[:, 2] = 0
        axis /= np.linalg.norm(axis, axis=1, keepdims=True)
        normal = np.cos(tilt) * normal + np.sin(tilt) * np.cross(axis, normal)
    up = rng.normal(size=(n, 3))
    return Foliage(pos, normal, up, np.full(n, 0.6), np.ones((n, 3)))


def _render(foliage, atlas):
    from treeform.geometry import leaf_cards
    from treeform.render import Lighting, Renderer
    from treeform.structures import Mesh

    unlit = Lighting(key=(0.0, 0.0, 0.0), sky=(1.0, 1.0, 1.0), ground=(1.0, 1.0, 1.0))
    renderer = Renderer(CAM, samples=1, lighting=unlit)
    try:
        return renderer.render(Mesh([leaf_cards(foliage, texture=atlas)]))
    finally:
        renderer.release()


def test_front_render_reproduces_the_photo_through_the_cards():
    img, alpha = _photo()
    atlas, f = photo_leaf_atlas(_cards(300), CAM, img, alpha, tile=32, detail=0.0, seed=0)
    res = _render(f, atlas)
    inner = res.mask & (alpha > 0)
    assert inner.sum() > 0.5 * (alpha > 0).sum()
    err = np.abs(res.color[..., :3].astype(float) - img.astype(float))[inner]
    assert np.median(err) < 12  # texel-for-pixel: the photo, resampled once
    # nothing drawn outside the photo's crown: the cards are cut by the photo's alpha
    assert (res.mask & (alpha == 0)).mean() < 0.01
    # the photo shifted by half a colour wave gives a different render (the test can fail)
    other = np.roll(img, 19, axis=1)
    atlas2, f2 = photo_leaf_atlas(_cards(300), CAM, other, alpha, tile=32, detail=0.0, seed=0)
    err2 = np.abs(_render(f2, atlas2).color[..., :3].astype(float) - img.astype(float))[inner]
    assert np.median(err2) > 3 * np.median(err)


def test_tilted_cards_still_show_their_part_of_the_photo():
    img, alpha = _photo()
    atlas, f = photo_leaf_atlas(_cards(300, tilt=0.9), CAM, img, alpha, tile=32, detail=0.0, seed=0)
    res = _render(f, atlas)
    inner = res.mask & (alpha > 0)
    err = np.abs(res.color[..., :3].astype(float) - img.astype(float))[inner]
    assert np.median(err) < 20


def test_tiles_shading_sharing_and_determinism():
    img, alpha = _photo()
    cards = _cards(50)
    a1, f1 = photo_leaf_atlas(cards, CAM, img, alpha, seed=3)
    a2, f2 = photo_leaf_atlas(cards, CAM, img, alpha, seed=3)
    np.testing.assert_array_equal(a1, a2)
    np.testing.assert_array_equal(f1.uv, f2.uv)
    assert len(np.unique(f1.uv, axis=0)) == 50  # one tile per card
    assert (f1.uv[:, 2] > f1.uv[:, 0]).all() and (f1.uv[:, 3] > f1.uv[:, 1]).all()
    # shading is baked into the card's own tile
    dark, _ = photo_leaf_atlas(cards, CAM, img, alpha, shade=np.full(50, 0.5), seed=3)
    op = a1[..., 3] > 127
    ratio = dark[..., :3][op].astype(float).mean() / a1[..., :3][op].astype(float).mean()
    assert 0.45 < ratio < 0.55
    # past max_tiles the hidden cards borrow the tiles of visible ones
    vis = np.arange(50) < 20
    _, fs = photo_leaf_atlas(cards, CAM, img, alpha, visible=vis, max_tiles=20, seed=3)
    assert len(np.unique(fs.uv, axis=0)) == 20
    assert np.isin(fs.uv[~vis].view([("", fs.uv.dtype)] * 4), fs.uv[vis].view([("", fs.uv.dtype)] * 4)).all()
    # more visible cards than max_tiles: smaller tiles, each visible card still its own (not another card's patch)
    big, fa = photo_leaf_atlas(cards, CAM, img, alpha, max_tiles=20, seed=3)
    assert len(np.unique(fa.uv, axis=0)) == 50
    assert big.shape[0] * big.shape[1] <= a1.shape[0] * a1.shape[1]  # in no more texels than before
    fixed, ff = photo_leaf_atlas(cards, CAM, img, alpha, max_tiles=20, tile=16, seed=3)  # a tile size asked for stays
    assert len(np.unique(ff.uv, axis=0)) == 20


def test_bad_inputs_are_one_line_errors():
    img, alpha = _photo()
    with pytest.raises(InputError, match="alpha"):
        photo_leaf_atlas(_cards(3), CAM, img, alpha[:10])
    with pytest.raises(InputError, match="kind"):
        photo_leaf_atlas(_cards(3), CAM, img, alpha, kind="fern")
    with pytest.raises(InputError, match="shade"):
        photo_leaf_atlas(_cards(3), CAM, img, alpha, shade=[2.0, 1.0, 1.0])
    atlas, f = photo_leaf_atlas(Foliage.empty(), CAM, img, alpha)
    assert len(f) == 0 and atlas.shape[2] == 4


def test_camera_sees_the_front_of_a_crown_and_shades_its_back():
    from treeform.crown.photo_leaves import camera_sees
    from treeform.structures import Camera, Foliage

    rng = np.random.default_rng(3)
    d = rng.normal(size=(3000, 3))
    p = d / np.linalg.norm(d, axis=1, keepdims=True) * rng.uniform(0.2, 1.0, (3000, 1)) ** (1 / 3) * 3.0
    n = len(p)
    f = Foliage(p, np.tile([0, 0, 1.0], (n, 1)), np.tile([0, 1, 0.0], (n, 1)), np.full(n, 0.3), np.ones((n, 3)))
    cam = Camera(200, 200, 30.0, (0, 0, 20.0), (0, 0, 0), (0, 1, 0))
    vis, shade = camera_sees(f, cam, np.ones((200, 200), bool))
    z = p[:, 2]
    assert vis[z > 2.5].mean() > 0.9 and vis[z < -1.0].mean() < 0.05  # the near side shows, the far side not
    assert np.all(shade[vis] == 1.0) and shade[z < -2.0].mean() < shade[(z > 0) & ~vis].mean() <= 1.0
    vis_none, _ = camera_sees(f, cam, np.zeros((200, 200), bool))
    assert not vis_none.any()  # off the tree mask nothing shows


def test_views_atlas_cuts_each_card_from_the_view_it_faces():
    """Cards on a crown seen from the front and the back: each card's tile comes from the photo
    on its side, its gaps included; rendered from either camera the cards show that photo."""
    from treeform.crown.photo_leaves import choose_views, views_leaf_atlas

    back = Camera(96, 96, 40.0, (0.0, 0.0, -10.0), (0.0, 0.0, 0.0), (0.0, 1.0, 0.0))
    img, alpha = _photo()
    other = np.roll(img, 19, axis=1)  # the back photo: another texture
    alpha_b = alpha.copy()
    alpha_b[40:56, :] = 0.0  # a gap through the crown seen from the back
    front_cards = _cards(300, seed=1)
    rear = _cards(300, seed=2)
    rear = Foliage(rear.positions * [1, 1, -1] - [0, 0, 3.0], -rear.normals, rear.up, rear.size, rear.color)
    cards = Foliage(*(np.concatenate([getattr(front_cards, k), getattr(rear, k)]) for k in
                      ("positions", "normals", "up", "size", "color")))
    view, vis, shade = choose_views(cards, [CAM, back], [alpha > 0, alpha_b > 0])
    assert (view[:300] == 0).mean() > 0.95 and (view[300:] == 1).mean() > 0.95
    assert vis.mean() > 0.25 and np.all(shade[vis] == 1.0)  # the cards nearest each camera in some pixel
    atlas, f = views_leaf_atlas(cards, [CAM, back], [img, other], [alpha, alpha_b], view, visible=vis,
                                shade=shade, tile=32, detail=0.0, seed=0)
    assert len(np.unique(f.uv, axis=0)) == 600
    res = _render(Foliage(f.positions[:300], f.normals[:300], f.up[:300], f.size[:300], f.color[:300],
                          uv=f.uv[:300]), atlas)
    inner = res.mask & (alpha > 0)
    assert np.median(np.abs(res.color[..., :3].astype(float) - img.astype(float))[inner]) < 12
    # from the back, its own photo and its gap (the render's image is mirrored: the back camera looks along +z)
    from treeform.render import Lighting, Renderer
    from treeform.geometry import leaf_cards
    from treeform.structures import Mesh

    unlit = Lighting(key=(0.0, 0.0, 0.0), sky=(1.0, 1.0, 1.0), ground=(1.0, 1.0, 1.0))
    r = Renderer(back, samples=1, lighting=unlit)
    try:
        rb = r.render(Mesh([leaf_cards(Foliage(f.positions[300:], f.normals[300:], f.up[300:], f.size[300:],
                                               f.color[300:], uv=f.uv[300:]), texture=atlas)]))
    finally:
        r.release()
    inner_b = rb.mask & (alpha_b > 0)
    assert inner_b.sum() > 0.5 * (alpha_b > 0).sum()
    assert np.median(np.abs(rb.color[..., :3].astype(float) - other.astype(float))[inner_b]) < 12
    assert rb.mask[42:54, 20:76].mean() < 0.05  # the gap stays open
    # deterministic; bad input is one clear error
    a2, _ = views_leaf_atlas(cards, [CAM, back], [img, other], [alpha, alpha_b], view, visible=vis, shade=shade,
                             tile=32, detail=0.0, seed=0)
    np.testing.assert_array_equal(atlas, a2)
    with pytest.raises(InputError, match="view"):
        views_leaf_atlas(cards, [CAM, back], [img, other], [alpha, alpha_b], np.full(600, 2))
    with pytest.raises(InputError, match="alphas"):
        views_leaf_atlas(cards, [CAM, back], [img, other], [alpha], view)


def test_carve_texels_is_the_visual_hull_of_the_views_with_a_tolerance():
    from treeform.crown.photo_leaves import carve_texels

    cams = [Camera(64, 64, 40.0, tuple(10.0 * np.array([np.sin(a), 0.0, np.cos(a)])), (0, 0, 0), (0, 1, 0))
            for a in np.linspace(0, 2 * np.pi, 5)[:4]]
    f = Foliage([[0, 0, 0]], [[0, 0, 1]], [[0, 1, 0]], [2.0], [[1, 1, 1]])
    full = np.ones((64, 64), bool)
    holed = full.copy()
    holed[28:36, 28:36] = False  # one view sees through the card's middle
    keep = carve_texels(f, cams, [full, holed, full, full], 8, tolerance=0.0)[0]
    assert keep.shape == (8, 8) and keep[0, 0] == 1 and keep[4, 4] == 0 and 0 < keep.mean() < 1
    assert carve_texels(f, cams, [full, holed, full, full], 8, tolerance=0.3)[0].all()  # 1 of 4 views tolerated
    # a spare view is tolerated whatever the share (0.05 of 4 views alone tolerates none), but not two
    assert carve_texels(f, cams, [full, holed, full, full], 8, tolerance=0.05, spare=1)[0].all()
    behind = carve_texels(f, cams, [full, full, holed, full], 8, tolerance=0.0)[0]
    both = carve_texels(f, cams, [full, holed, holed, full], 8, tolerance=0.05, spare=1)[0]
    assert np.array_equal(both, keep | behind) and not both.all()  # cut where both views see through
    with pytest.raises(InputError, match="spare"):
        carve_texels(f, cams, [full] * 4, 8, spare=-1)
    # a texel no view holds (all project outside the images) is kept: nothing says it is not tree
    far = Foliage([[500.0, 0, 0]], [[0, 0, 1]], [[0, 1, 0]], [1.0], [[1, 1, 1]])
    assert carve_texels(far, cams[:1], [np.zeros((64, 64), bool)], 4).all()
    with pytest.raises(InputError, match="tolerance"):
        carve_texels(f, cams, [full] * 4, 8, tolerance=0.5)
    with pytest.raises(InputError, match="masks"):
        carve_texels(f, cams, [full] * 3, 8)
