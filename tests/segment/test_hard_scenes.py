"""Finding the tree in the scenes that broke the colour rules: autumn crowns, bare winter trees,
cluttered streets and a darker tree behind the main one (issue 11, "find the tree robustly").

Composites with exact truth: our own grown trees (rendered alone, with foliage / wood labels)
pasted over procedural backgrounds. Where a segmenter is known to fail a scene kind today,
the test is a strict xfail: it documents the gap and turns red the day the gap closes.
"""

from __future__ import annotations

import numpy as np
import pytest

from treeform.metrics import tree_iou

SIZE = 256
SEASONS_AUTUMN = ("red", "orange", "yellow", "purple")


@pytest.fixture(scope="module")
def sprites(gl):
    from treeform.dataset.scenes import sprite_from_render
    from treeform.dataset.synthetic import SampleOptions, make_sample

    opts = SampleOptions(size=256, lod="low", species=("maple", "oak", "birch", "apple"))
    out = [sprite_from_render(s.rgba, s.mask, str(i)) for i, s in ((i, make_sample(5, i, opts)) for i in range(4))]
    assert all(sp is not None for sp in out)
    return out


def scene(sprites, kind: str, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Scene ``k`` of a kind: (image (S, S, 3) uint8, labels (S, S): 0 background, 1 foliage, 2 wood)."""
    from treeform.dataset.backgrounds import procedural_background
    from treeform.dataset.scenes import _paste, recolor_season

    rng = np.random.default_rng([11, k, ("autumn", "winter", "street", "overlap").index(kind)])
    bg = {"street": "street", "overlap": "park", "autumn": "field", "winter": "park"}[kind]
    img = procedural_background(SIZE, seed=rng, kind=bg).astype(np.float32) / 255.0
    lab = np.zeros((SIZE, SIZE), np.uint8)
    main = sprites[k % len(sprites)]
    rgba, labels = main.rgba.copy(), main.labels.copy()
    foliage = labels == 1
    if kind == "autumn":
        rgba[..., :3] = recolor_season(np.ascontiguousarray(rgba[..., :3]), foliage, SEASONS_AUTUMN[k], rng)
    elif kind == "winter":  # bare: the branches alone
        rgba[foliage, 3] = 0
        labels[foliage] = 0
    elif kind == "overlap":  # a darker, slightly defocused tree behind the main one's lower crown
        other = sprites[(k + 1) % len(sprites)].rgba.astype(np.float32) / 255.0
        other[..., :3] *= 0.6
        _paste(img, None, other, None, SIZE * 0.75, SIZE * (0.5 + 0.28 * (1 if k % 2 else -1)), SIZE * 0.8,
               blur=1.5)
    _paste(img, lab, rgba.astype(np.float32) / 255.0, labels, SIZE * rng.uniform(0.7, 0.9),
           SIZE * rng.uniform(0.4, 0.6), SIZE * 0.95)
    return (np.clip(img, 0, 1) * 255).astype(np.uint8), lab


def _segment(image, method):
    from treeform._shared.errors import NoTreeFoundError
    from treeform.segment import segment

    try:
        return segment(image, method=method, seed=0).labels
    except NoTreeFoundError:
        return np.zeros(image.shape[:2], np.uint8)


def _foliage_share(pred, truth):
    """Of the true foliage pixels the segmenter calls tree, the share it calls foliage (not wood)."""
    fol = (truth == 1) & (pred > 0)
    return float((pred[fol] == 1).mean()) if fol.any() else 0.0


def test_scenes_are_deterministic_and_labelled(sprites):
    for kind in ("autumn", "winter", "street", "overlap"):
        a, la = scene(sprites, kind, 1)
        b, lb = scene(sprites, kind, 1)
        assert np.array_equal(a, b) and np.array_equal(la, lb)
        assert (la > 0).mean() > (0.001 if kind == "winter" else 0.02)  # a bare tree is thin (its wood: ~0.16 %)
    assert not (scene(sprites, "winter", 0)[1] == 1).any()  # bare: no foliage


def test_learned_segmenter_keeps_autumn_crowns_foliage(sprites):
    for k in range(4):
        image, truth = scene(sprites, "autumn", k)
        pred = _segment(image, "learned")
        assert tree_iou(pred, truth) > 0.65, (SEASONS_AUTUMN[k], tree_iou(pred, truth))
        # the colour rules call a third of the red crown wood (the xfail below); the network of 2026-11-26
        # calls 7 % of it wood (0.926; the other seasons 0.995-0.998), the one before it 1 %
        assert _foliage_share(pred, truth) > 0.9, SEASONS_AUTUMN[k]


def test_learned_segmenter_leaves_the_street_out(sprites):
    ious = [tree_iou(_segment(im, "learned"), t) for im, t in (scene(sprites, "street", k) for k in range(4))]
    assert min(ious) > 0.7, ious


def test_learned_segmenter_separates_a_tree_behind(sprites):
    ious = [tree_iou(_segment(im, "learned"), t) for im, t in (scene(sprites, "overlap", k) for k in range(4))]
    assert np.median(ious) > 0.55 and min(ious) > 0.35, ious


@pytest.mark.xfail(strict=True, reason="classical rules still call a third of a red autumn crown wood (issue 11 item 1)")
def test_classical_segmenter_keeps_autumn_crowns_foliage(sprites):
    for k in range(4):
        image, truth = scene(sprites, "autumn", k)
        assert _foliage_share(_segment(image, "classical"), truth) > 0.9, SEASONS_AUTUMN[k]


@pytest.mark.xfail(strict=True, reason="neither segmenter finds a bare winter tree yet (issue 11 item 1)")
@pytest.mark.parametrize("method", ["learned", "classical"])
def test_bare_winter_trees_are_found(sprites, method):
    ious = [tree_iou(_segment(im, method), t) for im, t in (scene(sprites, "winter", k) for k in range(4))]
    assert np.median(ious) > 0.3, ious
