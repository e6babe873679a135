"""Training scenes of the trunk-foot detector: several trees on the ground, each foot's exact pixel.

:func:`treeform.segment.instances.find_tree_instances` must find every tree of a photo, also
one standing nearly behind another or under a neighbour's low crown (issue 16 item 2). The
learned cue is a heatmap of trunk feet (:mod:`treeform.learn.feet`), trained on the scenes of
:func:`feet_scene`: 0-6 tree sprites (real RGBA cut-outs and, optionally, synthetic renders of
``treeform dataset generate``; never the package's 14 library trees, which are the
benchmark's) standing on one ground plane seen by a level-ish camera, pasted
far to near as :func:`~treeform.dataset.scenes.group_scene` pastes them (the sprite's lowest
row at the foot's row, its trunk's column, :func:`~treeform.dataset.scenes._sprite_foot`, at
the foot's column), and randomised as the segmenter's scenes are:

- **trees**: 1-6 of them (and, in 8 % of the scenes, none); sizes from a sapling to a tree
  taller than the frame (the height in pixels follows the distance: a foot lower in the
  frame is nearer, so larger); each tree after the first stands, with a chance of 35 %
  (``behind``), nearly behind another (a few pixels to a tenth of the frame aside,
  ``behind_aside``, slightly farther), the case where two feet merge in a mask; seasons,
  bark tints and thinning of :func:`~treeform.dataset.scenes._tree_look`;
- **backgrounds**: :func:`~treeform.dataset.scenes.group_scene`'s lawn under a sky, the
  procedural skies, lawns, roads and buildings, or a blurred real photo
  (:func:`~treeform.dataset.scenes.photo_background`); clutter (cars, people, lamp posts:
  upright things that are no trunk), small hazy trees far behind (no target: smaller than a
  tree :func:`~treeform.segment.instances.find_tree_instances` keeps), and rows of bushes
  behind the trees or in front of their feet;
- **camera**: :func:`~treeform.dataset.scenes.camera_effects`.

Targets: each tree whose foot lies inside the frame and that is at least :data:`MIN_HEIGHT`
of the frame tall; a foot hidden behind a nearer tree is marked ``visible=False`` (the loss
ignores its neighbourhood: whether a tree is there cannot be seen). A foot below the frame's
bottom edge or beside it has no target.

numpy + OpenCV only (no torch). Same inputs and generator state -> the same scene.
"""

from __future__ import annotations

import numpy as np

from treeform._shared.errors import InputError

__all__ = ["feet_scene", "MIN_HEIGHT"]

MIN_HEIGHT = 0.12
"""Trees shorter than this share of the frame's height get no target (the instance finder drops them)."""


def _background(rng, W: int, H: int, photos) -> tuple[np.ndarray, int]:
    """(H, W, 3) float32 background in [0, 1] and its horizon row (rough, for placing things on the ground)."""
    from treeform.dataset.backgrounds import procedural_background
    from treeform.dataset.scenes import group_scene, photo_background

    r = rng.random()
    if r < 0.3:  # group_scene's own lawn and sky, the horizon at a random row (the camera tilted)
        tall = group_scene([], np.zeros((0, 2)), np.zeros(0), rng, size=(W, 2 * H))["image"]
        horizon = int(rng.uniform(0.3, 0.7) * H)
        y0 = H - horizon
        img = tall[y0:y0 + H]
    elif r < 0.6 and photos:
        sq = photo_background(photos[int(rng.integers(len(photos)))], rng, size=W, blur=(1.5, 5.0))
        y0 = int(rng.integers(0, W - H + 1))
        img = sq[y0:y0 + H]
        horizon = int(rng.uniform(0.35, 0.7) * H)
    else:
        img = procedural_background((H, W), seed=rng)
        horizon = int(rng.uniform(0.4, 0.7) * H)
    img = img.astype(np.float32) / 255.0
    if rng.random() < 0.5:
        img = img[:, ::-1]
    return np.ascontiguousarray(img), horizon


def _layout(n: int, rng, W: int, H: int, horizon: int, behind: float = 0.35,
            behind_aside: float = 0.1) -> list[tuple[float, float, float]]:
    """(u, v, height_px) of ``n`` trees on one ground plane: v below the horizon, height ~ v - horizon."""
    trees = []
    ratio = rng.uniform(2.0, 5.5)  # tree height / camera height, shared roughly by the group
    for _ in range(n):
        if trees and rng.random() < behind:  # nearly behind a tree already placed: a little aside, a little farther
            u0, v0, _ = trees[int(rng.integers(len(trees)))]
            u = u0 + rng.choice([-1, 1]) * rng.uniform(0.005, behind_aside) * W
            v = v0 - rng.uniform(0.005, 0.08) * H
        else:
            u = rng.uniform(0.03, 0.97) * W if rng.random() < 0.85 else rng.uniform(-0.05, 1.05) * W
            v = rng.uniform(horizon + 0.04 * H, 1.05 * H)
        v = max(v, horizon + 0.02 * H)
        hpx = (v - horizon) * ratio * rng.uniform(0.7, 1.4)
        trees.append((float(u), float(v), float(min(hpx, 1.15 * H))))
    return trees


def feet_scene(sprites, rng, *, size: tuple = (384, 288), photos=(), empty: float = 0.08,
               max_trees: int = 6, renders=(), render_fraction: float = 0.0, behind: float = 0.35,
               behind_aside: float = 0.1) -> dict:
    """One randomised scene of several trees with the pixel of each trunk's foot (see the module docstring).

    Parameters
    ----------
    sprites : sequence of Sprite
        Tree sprites (:func:`~treeform.dataset.scenes.load_cutouts`, the 'train' split).
    rng : numpy.random.Generator
    size : (width, height)
    photos : sequence of ndarray, optional
        Real photos, (h, w, 3) uint8, for blurred backgrounds.
    empty : float
        Share of scenes without a tree (all targets empty).
    max_trees : int
    renders : sequence of Sprite, optional
        Synthetic tree renders (:func:`~treeform.learn.data.render_sprites` of a dataset of
        ``treeform dataset generate``), a second pool of sprites.
    render_fraction : float
        Share of the trees drawn from ``renders`` (when given).
    behind : float
        Chance that each tree after the first stands nearly behind one already placed.
    behind_aside : float
        How far aside of that tree it may stand, as a share of the frame's width (0.5 % up to this).

    Returns
    -------
    dict
        ``image`` (H, W, 3) uint8; ``feet`` (N, 2) float (u, v) pixel of each target foot (the
        ground contact of its trunk, y down); ``visible`` (N,) bool, False where a nearer tree
        hides the foot; ``instances`` (H, W) uint8, k + 1 where tree k (of all pasted, in
        paste order) is seen.
    """
    from treeform.dataset.scenes import _bushes, _clutter, _paste, _sprite_foot, _tree_look, camera_effects

    if not sprites:
        raise InputError("sprites: expected at least one tree sprite")
    W, H = (int(x) for x in size)
    if min(W, H) < 32:
        raise InputError(f"size: expected at least 32 x 32 pixels, got {W} x {H}")
    img, horizon = _background(rng, W, H, photos)
    _clutter(img, horizon, rng)
    sky_col = img[: max(2, H // 8)].reshape(-1, 3).mean(0)

    def look():
        pool = renders if len(renders) and rng.random() < render_fraction else sprites
        rgba, _ = _tree_look(pool[int(rng.integers(len(pool)))], rng)
        return np.ascontiguousarray(rgba[:, ::-1] if rng.random() < 0.5 else rgba)

    for _ in range(int(rng.choice([0, 1, 3, 6], p=[0.4, 0.25, 0.2, 0.15]))):  # far behind: small, hazy, no target
        _paste(img, None, look(), None, H * rng.uniform(0.03, MIN_HEIGHT * 0.8), rng.uniform(-0.05, 1.05) * W,
               horizon + rng.uniform(-0.01, 0.03) * H, haze=rng.uniform(0.1, 0.5), haze_col=sky_col,
               blur=rng.uniform(0.0, 1.5))
    bush_front = rng.random() < 0.15

    def other():
        return look()

    if rng.random() < 0.2 and not bush_front:
        _bushes(img, other, rng, horizon)
    n = 0 if rng.random() < empty else int(rng.integers(1, max_trees + 1))
    # far (high in the frame) to near
    layout = sorted(_layout(n, rng, W, H, horizon, behind, behind_aside), key=lambda t: t[1])
    lab = np.zeros((H, W), np.uint8)
    feet = np.zeros((len(layout), 2))
    for k, (u, v, hpx) in enumerate(layout):
        rgba = look()
        fx = _sprite_foot(rgba[..., 3] > 0.5)
        shift = (0.5 * (rgba.shape[1] - 1) - fx) * hpx / rgba.shape[0]
        if v < H and rng.random() < 0.4:  # a soft shadow on the ground at the foot
            sh = np.zeros((H, W), np.float32)
            import cv2

            cv2.ellipse(sh, (int(u), int(v)), (max(1, int(hpx * rng.uniform(0.1, 0.3))), max(1, int(0.01 * H))),
                        0, 0, 360, 1.0, -1)
            img *= 1 - cv2.GaussianBlur(sh, (0, 0), 2)[..., None] * rng.uniform(0.2, 0.5)
        _paste(img, lab, rgba, None, hpx, u + shift, v + 1.0, label_value=k + 1)
        feet[k] = (u, v)
    if bush_front and layout:
        _bushes(img, other, rng, horizon)  # bushes and hedges in front of the feet (the feet still stand there)
    keep = np.array([0 <= u < W and 0 <= v < H and h >= MIN_HEIGHT * H for u, v, h in layout], bool)
    visible = np.ones(len(layout), bool)
    for k, (u, v) in enumerate(feet):  # a foot behind a nearer tree's pixels: ambiguous
        if keep[k]:
            y0, y1 = max(0, int(v) - 3), min(H, int(v) + 1)
            x0, x1 = max(0, int(u) - 2), min(W, int(u) + 3)
            win = lab[y0:y1, x0:x1]
            visible[k] = win.size > 0 and bool((win == k + 1).any() or not (win > k + 1).any())
    out = camera_effects(img, sky_col, rng)
    return {"image": out, "feet": feet[keep], "visible": visible[keep], "instances": lab}
