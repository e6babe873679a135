"""Tests of treeform.dataset.scenes: randomised training scenes, cut-outs and real-texture composites."""

import numpy as np
import pytest

from treeform._shared.errors import InputError

from treeform.dataset.scenes import (SEASONS, TREE_ANY, Sprite, compose_scene, cutout_split, load_cutouts,
                                     load_photos, paste_on_photo, photo_background, photo_split, recolor_season,
                                     sprite_from_render)


def _sprite(rng_seed=0, known=True):
    rng = np.random.default_rng(rng_seed)
    rgba = np.zeros((80, 50, 4), np.uint8)
    rgba[5:50, 5:45, :3] = (50, 120, 40)
    rgba[5:50, 5:45, 3] = 255
    rgba[50:80, 22:28, :3] = (100, 70, 40)
    rgba[50:80, 22:28, 3] = 255
    rgba[..., :3] = np.clip(rgba[..., :3] + rng.integers(-10, 10, rgba[..., :3].shape), 0, 255)
    labels = np.zeros((80, 50), np.uint8)
    labels[5:50, 5:45] = 1 if known else TREE_ANY
    labels[50:80, 22:28] = 2 if known else TREE_ANY
    return sprite_from_render(rgba, labels) if known else Sprite(rgba, labels)


def test_compose_scene_is_deterministic_and_labels_the_tree():
    tree, others = _sprite(), [_sprite(1), _sprite(2, known=False)]
    a = compose_scene(tree, others, np.random.default_rng([3, 4]), size=96)
    b = compose_scene(tree, others, np.random.default_rng([3, 4]), size=96)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    img, lab = a
    assert img.shape == (96, 96, 3) and img.dtype == np.uint8 and lab.shape == (96, 96)
    assert set(np.unique(lab)) <= {0, 1, 2}
    # the tree (45-98 % of the frame high) is labelled; background trees never are
    assert (lab > 0).mean() > 0.02


def test_scenes_without_a_main_tree_are_all_background():
    for k in range(5):
        img, lab = compose_scene(None, [_sprite(1)], np.random.default_rng(k), size=64)
        assert not lab.any()
        assert img.std() > 1.0  # a scene, not a blank


def test_cutout_labels_stay_tree_of_unknown_part():
    img, lab = compose_scene(_sprite(0, known=False), [], np.random.default_rng(1), size=96)
    assert set(np.unique(lab)) <= {0, TREE_ANY} and (lab == TREE_ANY).any()


@pytest.mark.parametrize("season", SEASONS)
def test_recolor_season_changes_only_foliage(season):
    sp = _sprite()
    rgb = np.ascontiguousarray(sp.rgba[..., :3])
    fol = sp.labels == 1
    out = recolor_season(rgb, fol, season, np.random.default_rng(0))
    assert np.array_equal(out[~fol], rgb[~fol])
    if season in ("red", "orange", "yellow", "purple"):
        r, g = out[fol][:, 0].astype(int), out[fol][:, 1].astype(int)
        assert np.median(r - g) > -5  # no longer green-dominant


def test_cutout_split_keeps_an_identity_together():
    names = [f"deciduous_row{r}_col{c}.png" for r in range(4) for c in range(8)]
    by_id = {}
    for n in names:
        by_id.setdefault(n.split("_col")[1], set()).add(cutout_split(n))
    assert all(len(v) == 1 for v in by_id.values())
    assert {cutout_split(n) for n in names} <= {"train", "test"}


def test_load_cutouts_of_the_shared_billboards():
    from pathlib import Path

    folder = Path(__file__).resolve().parents[2].parent / "shared" / "data" / "billboards"
    if not folder.is_dir():
        pytest.skip("../shared/data/billboards is not available")
    train, test = load_cutouts(folder, split="train"), load_cutouts(folder, split="test")
    assert len(train) > len(test) > 20
    assert not {s.name for s in train} & {s.name for s in test}
    for s in test[:5]:
        assert s.rgba.shape[:2] == s.labels.shape and set(np.unique(s.labels)) <= {0, TREE_ANY}


def test_paste_on_photo_mask_matches_the_pasted_alpha():
    rng = np.random.default_rng(0)
    photo = rng.integers(0, 255, (300, 400, 3)).astype(np.uint8)
    img, mask = paste_on_photo(_sprite(0, known=False), photo, np.random.default_rng(5), size=128)
    assert img.shape == (128, 128, 3) and mask.dtype == bool
    frac = mask.mean()
    assert 0.02 < frac < 0.9
    # the tree pixels carry the sprite's green, the rest the blurred photo
    assert img[mask][:, 1].mean() > img[mask][:, 0].mean()


def test_photo_split_keeps_a_species_together(tmp_path):
    from PIL import Image

    species = ["Acer_rubrum", "Quercus_alba", "Pinus_taeda", "Thuja_plicata", "Ulmus_americana", "Morus_rubra",
               "Cornus_florida", "Fagus_grandifolia"]
    for sp in species:
        assert photo_split(f"{sp}_1.jpg") == photo_split(f"{sp}_2.jpg") == photo_split(f"{sp.lower()}_3.JPG")
    assert {photo_split(f"{sp}_1.jpg") for sp in species} == {"train", "test"}
    for i, sp in enumerate(species[:4]):
        Image.fromarray(np.full((40, 60, 3), 40 * i, np.uint8)).save(tmp_path / f"{sp}_1.jpg")
    (tmp_path / "notes.txt").write_text("not a photo")
    train, test = load_photos(tmp_path, split="train"), load_photos(tmp_path, split="test")
    assert len(train) + len(test) == 4 and all(p.shape == (40, 60, 3) for p in train + test)
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="no JPEG"):
        load_photos(tmp_path / "empty")
    with pytest.raises(InputError, match="not a directory"):
        load_photos(tmp_path / "missing")


def test_photo_background_is_an_out_of_focus_crop():
    rng = np.random.default_rng(0)
    photo = rng.integers(0, 255, (300, 400, 3)).astype(np.uint8)
    a = photo_background(photo, np.random.default_rng(1), size=96)
    b = photo_background(photo, np.random.default_rng(1), size=96)
    assert a.shape == (96, 96, 3) and a.dtype == np.uint8 and np.array_equal(a, b)
    assert a.std() < photo.std() / 3  # blurred: the pixel noise is gone
    assert abs(float(a.mean()) - float(photo.mean())) < 10


def test_scene_stream_composes_over_real_photos():
    from treeform.learn.data import SceneStream

    red = np.zeros((200, 300, 3), np.uint8)
    red[...] = (200, 30, 30)
    st = SceneStream([_sprite(0)], photos=[red], photo_fraction=1.0, negatives=1.0, size=64, pool=8)
    imgs, labs = st.chunk(0, 4)
    assert not labs.any()  # scenes without a main tree: all background
    r, g = imgs[..., 0].astype(int), imgs[..., 1].astype(int)
    assert np.median(r - g) > 60  # the photo shows through (clutter covers only part of it)
    imgs2, _ = SceneStream([_sprite(0)], photos=[red], photo_fraction=1.0, negatives=1.0, size=64, pool=8).chunk(0, 4)
    assert np.array_equal(imgs, imgs2)


def test_sprite_labels_shrink_with_the_image_not_by_sampling_phase():
    """A 1-px twig halved in size: nearest-neighbour resizing keeps it at even columns and
    drops it at odd ones; coverage resampling labels it the same at both (as the image shows it)."""
    import cv2

    from treeform.dataset.scenes import _resample_labels

    for x in (10, 11):
        lab = np.zeros((40, 40), np.uint8)
        lab[:, x] = 2
        lab[30:, 20:26] = 1  # a foliage block elsewhere keeps its area
        out = _resample_labels(lab, (20, 20), cv2.INTER_AREA)
        assert out.shape == (20, 20)
        assert np.array_equal(np.flatnonzero((out == 2).all(0)), [5])
        assert (out == 1).sum() == 5 * 3
    assert not _resample_labels(np.zeros((8, 8), np.uint8), (4, 4), cv2.INTER_AREA).any()


def test_bushes_behind_the_foot_are_background_and_off_by_default():
    tree, others = _sprite(), [_sprite(1), _sprite(2, known=False)]
    plain = compose_scene(None, others, np.random.default_rng(5), size=96)
    bushy = compose_scene(None, others, np.random.default_rng(5), size=96, bushes=1.0)
    off = compose_scene(None, others, np.random.default_rng(5), size=96, bushes=0.0)
    assert np.array_equal(plain[0], off[0])  # bushes=0 draws nothing: yesterday's scenes stay the same
    assert not bushy[1].any()  # leafy bushes are labelled background
    # they stand on the ground below the horizon, and are leafy crowns (of the sprites given)
    from treeform.dataset.scenes import _bushes

    canvas = np.zeros((96, 96, 3), np.float32)
    crown = _sprite(1).rgba.astype(np.float32) / 255.0
    for k in range(5):
        c = canvas.copy()
        _bushes(c, lambda: crown, np.random.default_rng(k), horizon=60)
        painted = c.sum(-1) > 0
        # feet from the horizon (60) down, at most a third of the frame high
        assert painted[60:].any() and not painted[:24].any()
        r, g, b = c[painted].mean(0)
        assert g > r and g > b  # the crown's green leaves
    # with a main tree the tree keeps its labels (bushes are behind it)
    img, lab = compose_scene(tree, others, np.random.default_rng(6), size=96, bushes=1.0)
    assert set(np.unique(lab)) <= {0, 1, 2} and (lab > 0).mean() > 0.02


def test_sparse_boost_draws_thin_cutouts_more_often():
    from treeform.learn.data import SceneStream

    dense = _sprite(0, known=False)
    thin_rgba = dense.rgba.copy()
    thin_lab = dense.labels.copy()
    thin_rgba[::2, :, 3] = 0  # every other row gone: half the fill
    thin_rgba[:, ::2, 3] = 0
    thin_lab[thin_rgba[..., 3] == 0] = 0
    thin = Sprite(thin_rgba, thin_lab, "thin")
    even = SceneStream([], [dense, thin], size=64, cutout_fraction=1.0)
    boosted = SceneStream([], [dense, thin], size=64, cutout_fraction=1.0, sparse_boost=1.0)
    assert even._cut_p is None
    fill = np.array([(dense.labels > 0).mean(), (thin.labels > 0).mean()])
    assert boosted._cut_p[1] / boosted._cut_p[0] == pytest.approx(fill[0] / fill[1], rel=1e-6)
    assert boosted._cut_p[1] > 0.7


def test_group_scene_truth_foot_is_on_each_library_trees_trunk():
    """The true foot of a group composite is where the trunk meets the ground: for every library
    tree the foot column holds bark (not green) in the sprite's lowest fifth, also for a conifer
    whose needle skirt hangs lower than its trunk (pine_2: its lowest row is a needle tip at the
    sprite's right edge, where the foot used to be put)."""
    from treeform.data import data_path
    from treeform.dataset.scenes import _sprite_foot, load_cutouts

    for sp in load_cutouts(data_path("library")):
        a = sp.rgba[..., 3] > 127
        fx = int(round(_sprite_foot(a, sp.rgba[..., :3])))
        rows = np.flatnonzero(a.any(1))
        low = slice(int(rows[-1] - 0.2 * (rows[-1] - rows[0])), rows[-1] + 1)
        col = sp.rgba[low, max(0, fx - 1):fx + 2]
        bark = (col[..., 3] > 127) & (col[..., 1].astype(int) <= np.maximum(col[..., 0], col[..., 2]).astype(int) + 8)
        assert bark.sum() >= 5, (sp.name, fx)


def test_group_scene_areas_are_each_tree_alone():
    """``areas_px`` is each tree's pixel count drawn alone: a tree by itself is fully visible, and
    a tree standing behind a nearer one shows less of itself than it would alone."""
    from treeform.data import data_path
    from treeform.dataset.scenes import group_scene, load_cutouts

    sp = load_cutouts(data_path("library"))[:2]
    alone = group_scene(sp[:1], [[0.0, 15.0]], [6.0], np.random.default_rng(0), size=(320, 240))
    assert alone["areas_px"][0] == np.count_nonzero(alone["instances"] == 1) > 100
    both = group_scene([sp[1], sp[0]], [[0.3, 20.0], [0.0, 15.0]], [6.0, 6.0], np.random.default_rng(0), size=(320, 240))
    seen = np.array([np.count_nonzero(both["instances"] == k + 1) for k in range(2)])
    assert seen[1] == both["areas_px"][1] == alone["areas_px"][0]  # the near tree: whole, as alone
    assert 0 < seen[0] < 0.9 * both["areas_px"][0]  # the far one: partly behind the near one
