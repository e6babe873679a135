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
