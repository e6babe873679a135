"""Sprite packs and scene rounds of the training data (numpy only: no torch needed)."""

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.dataset.scenes import Sprite


def _sprites(n=5, seed=0):
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        h, w = int(rng.integers(20, 60)), int(rng.integers(20, 60))
        rgba = rng.integers(0, 256, (h, w, 4)).astype(np.uint8)
        rgba[..., 3] = np.where(rng.random((h, w)) < 0.7, rng.integers(128, 256, (h, w)), 0)
        labels = np.where(rgba[..., 3] >= 128, rng.integers(1, 3, (h, w)), 0).astype(np.uint8)
        out.append(Sprite(rgba, labels, f"s{i}"))
    return out


def test_a_lossless_sprite_pack_reads_back_exactly(tmp_path):
    from treeform.learn.data import load_sprites, render_sprites, save_sprites

    sp = _sprites()
    save_sprites(sp, tmp_path / "pack")
    back = load_sprites(tmp_path / "pack")
    assert [b.name for b in back] == [s.name for s in sp]
    for a, b in zip(sp, back):
        assert np.array_equal(a.rgba, b.rgba) and np.array_equal(a.labels, b.labels)
    assert len(render_sprites(tmp_path / "pack", limit=2)) == 2  # the training entry point reads packs too


def test_a_lossy_pack_keeps_labels_and_alpha_exact_and_colour_close(tmp_path):
    from treeform.learn.data import load_sprites, save_sprites

    rng = np.random.default_rng(1)
    y, x = np.mgrid[:48, :40]
    rgba = np.dstack([(x * 5) % 256, (y * 4) % 256, (x + y) % 256, np.full_like(x, 255)]).astype(np.uint8)
    rgba[rng.random((48, 40)) < 0.2, 3] = 0
    sp = [Sprite(rgba, np.where(rgba[..., 3] > 0, 1 + (x > 20), 0).astype(np.uint8), "smooth")]
    save_sprites(sp, tmp_path / "pack", quality=95)
    (b,) = load_sprites(tmp_path / "pack")
    assert np.array_equal(b.labels, sp[0].labels) and np.array_equal(b.rgba[..., 3], rgba[..., 3])
    assert np.abs(b.rgba[..., :3].astype(int) - rgba[..., :3]).mean() < 4.0


def test_a_broken_pack_is_a_clear_error(tmp_path):
    from treeform.learn.data import load_sprites, save_sprites

    with pytest.raises(InputError, match="not a sprite pack"):
        load_sprites(tmp_path)
    save_sprites(_sprites(2), tmp_path / "pack")
    (tmp_path / "pack" / "00001.la.png").unlink()
    with pytest.raises(InputError, match="sprite 1"):
        load_sprites(tmp_path / "pack")
    with pytest.raises(InputError, match="quality"):
        save_sprites(_sprites(1), tmp_path / "q", quality=0)


def test_rounds_composed_by_worker_processes_are_the_rounds_composed_in_line():
    import functools

    from treeform.learn.data import SceneStream
    from treeform.learn.train import _Rounds

    make = functools.partial(SceneStream, _sprites(6), size=48, seed=4, pool=16)
    inline, ahead = _Rounds(make, 5, 0), _Rounds(make, 5, 2)
    try:
        for r in (0, 1, 3, 2):  # out of order too: a round depends on (seed, r) alone
            (ia, la), (ib, lb) = inline.get(r), ahead.get(r)
            assert np.array_equal(ia, ib) and np.array_equal(la, lb)
        assert not np.array_equal(inline.get(0)[0], inline.get(1)[0])
    finally:
        ahead.close()


def test_a_photo_is_pseudo_labelled_tree_inside_background_far_out_and_unsure_between():
    from pathlib import Path

    from PIL import Image

    from treeform.dataset.scenes import TREE_ANY, UNSURE, photo_pseudo_labels, photo_scene
    from treeform.segment import segment_tree

    sample = Path(__file__).resolve().parents[2] / "src" / "treeform" / "data" / "Celtis_occidentalis_1.jpg"
    photo = np.asarray(Image.open(sample).convert("RGB").resize((240, 320)))
    lab = photo_pseudo_labels(photo)
    assert lab.shape == photo.shape[:2] and set(np.unique(lab)) == {0, TREE_ANY, UNSURE}
    tree = segment_tree(photo, seed=0).tree_mask
    assert tree[lab == TREE_ANY].all()  # the tree label lies inside the rules' tree ...
    assert not tree[lab == 0].any()  # ... the background label outside it, with a band between
    assert 0.2 < (lab == TREE_ANY).sum() / tree.sum() < 1.0
    img, sl = photo_scene(photo, lab, np.random.default_rng(0), size=64)
    assert img.shape == (64, 64, 3) and img.dtype == np.uint8 and sl.shape == (64, 64)
    assert set(np.unique(sl)) <= {0, TREE_ANY, UNSURE}
    # no tree in a flat grey picture: nothing to label
    assert photo_pseudo_labels(np.full((64, 64, 3), 128, np.uint8)) is None


def test_photo_tree_scenes_join_the_stream_reproducibly():
    from treeform.learn.data import SceneStream

    rng = np.random.default_rng(1)
    photo = rng.integers(0, 256, (80, 60, 3)).astype(np.uint8)
    lab = np.zeros((80, 60), np.uint8)
    lab[20:60, 15:45] = 3
    lab[15:20, 15:45] = 255

    def stream():
        return SceneStream(_sprites(), size=48, seed=2, pool=8, photo_trees=[(photo, lab)], photo_tree_fraction=0.5)

    a, b = stream().chunk(0, 12), stream().chunk(0, 12)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1])
    assert (a[1] == 255).any()  # some scenes are the photo, with its no-loss band
    plain = SceneStream(_sprites(), size=48, seed=2, pool=8).chunk(0, 12)
    assert not (plain[1] == 255).any()


def test_noise_negatives_are_all_background_and_vary():
    from treeform.dataset.scenes import noise_image
    from treeform.learn.data import SceneStream

    rng = np.random.default_rng(0)
    pics = [noise_image(rng, size=32) for _ in range(6)]
    assert all(p.shape == (32, 32, 3) and p.dtype == np.uint8 for p in pics)
    assert len({round(float(p.mean()), 1) for p in pics}) > 3  # means and contrasts differ
    imgs, labs = SceneStream(_sprites(), size=32, seed=1, pool=8, noise_fraction=1.0).chunk(0, 4)
    assert not labs.any() and imgs.std() > 10
