"""Randomised scenes for training perception networks: trees over cluttered, photo-like backgrounds.

The renders of :func:`~treeform.dataset.make_sample` are clean: one tree, a painted
background, correct exposure. Real photos are not, and a network trained on clean renders
alone labels autumn crowns as wood and houses as trees. :func:`compose_scene` therefore
re-composites a tree *sprite* (an RGBA tree alone with its labels: a synthetic render from
the dataset's ``rgba.png`` or a real photo cut-out) over a scene randomised as seed 003
§4.2.2 asks ("augmentation ... to bridge the domain gap"), with everything the issue names:

- **seasons**: the foliage recoloured to spring, summer, autumn yellow / orange / red /
  purple, conifer blue-green, or thinned to a sparse crown (blobs of foliage removed);
  bark tinted grey to dark brown;
- **clutter**: the procedural skies, lawns, roads and buildings of
  :func:`~treeform.dataset.procedural_background`, plus cars, people-sized figures,
  hedges, lamp posts and lawn bands;
- **framing**: the main tree whole in the frame (35–98 % of its height) or, in a third of
  the scenes, a close-up that fills the frame and is cut by its edges;
- **other trees labelled background**: large trees out of focus right behind the subject,
  smaller, hazier trees standing further back, and large neighbour trees cut by the left or
  right edge of the frame;
- **camera**: haze, defocus blur, exposure, white balance and gamma errors, sensor
  noise and JPEG artefacts.

Labels: 0 background, 1 foliage, 2 wood and :data:`TREE_ANY` (3) for tree pixels whose
part is unknown (photo cut-outs carry a tree mask only); the training loss scores those
with the summed foliage + wood probability. Scenes without a main tree (``tree=None``)
teach the network to answer "no tree".

Everything random comes from the generator passed in: same inputs and seed -> same scene.
"""

from __future__ import annotations

import colorsys
import zlib
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from treeform._shared.errors import InputError

__all__ = ["Sprite", "TREE_ANY", "SEASONS", "compose_scene", "load_cutouts", "paste_on_photo", "sprite_from_render",
           "recolor_season", "cutout_split", "photo_split", "load_photos", "photo_background", "UNSURE",
           "photo_pseudo_labels", "photo_scene", "camera_effects", "noise_image"]

TREE_ANY = 3
"""Label of a tree pixel whose part (foliage or wood) is unknown."""

UNSURE = 255
"""Label of a pixel the loss ignores (the band between a photo's pseudo-labelled tree and background)."""

SEASONS = ("summer", "spring", "yellow", "orange", "red", "purple", "bluegreen", "sparse")
"""Foliage looks drawn by :func:`recolor_season`."""

# target hue (degrees), saturation scale, value scale per season
_SEASON_HSV = {"spring": (85, 1.1, 1.15), "yellow": (50, 1.25, 1.15), "orange": (30, 1.35, 1.0),
               "red": (5, 1.3, 0.85), "purple": (325, 0.9, 0.6), "bluegreen": (165, 0.55, 0.85)}


@dataclass
class Sprite:
    """A tree alone: ``rgba`` (h, w, 4) uint8 cropped to its alpha, ``labels`` (h, w) uint8.

    ``labels`` holds 1 foliage / 2 wood for synthetic renders, :data:`TREE_ANY` for cut-outs
    (0 outside the tree).
    """

    rgba: np.ndarray
    labels: np.ndarray
    name: str = ""


def _crop(rgba: np.ndarray, labels: np.ndarray, name: str) -> Sprite | None:
    ys, xs = np.nonzero(rgba[..., 3] > 0)
    if ys.size < 16:
        return None
    y0, y1, x0, x1 = ys.min(), ys.max() + 1, xs.min(), xs.max() + 1
    return Sprite(np.ascontiguousarray(rgba[y0:y1, x0:x1]), np.ascontiguousarray(labels[y0:y1, x0:x1]), name)


def sprite_from_render(rgba: np.ndarray, mask: np.ndarray, name: str = "") -> Sprite | None:
    """A synthetic sample's tree alone (``rgba`` from the shard) with its 0/1/2 ``mask``."""
    lab = np.where(rgba[..., 3] >= 128, mask, 0).astype(np.uint8)
    return _crop(rgba, lab, name)


def cutout_split(name: str, *, test_fraction: float = 0.25) -> str:
    """'train' or 'test' for a cut-out file name, by tree identity (atlas + column).

    The rows of an atlas are seasons of the same eight trees, so all rows of one column go
    to the same split; the split is a fixed hash, independent of the machine and order.

    >>> cutout_split("deciduous_row0_col3.png") == cutout_split("deciduous_row3_col3.png")
    True
    """
    stem = Path(name).stem
    ident = stem.split("_row")[0] + "_col" + stem.rsplit("_col", 1)[-1] if "_row" in stem else stem
    return _split_side(ident, test_fraction)


def _split_side(ident: str, test_fraction: float) -> str:
    """'test' for a fixed, machine-independent hash share ``test_fraction`` of identities, else 'train'."""
    return "test" if zlib.crc32(ident.encode()) % 1000 < test_fraction * 1000 else "train"


def photo_split(name: str, *, test_fraction: float = 0.35) -> str:
    """'train' or 'test' for a background photo's file name, by species (all photos of one together).

    The photos of ``../shared/data/photos`` are named ``Genus_species_N.jpg``; the trailing
    number is dropped, so a species' photos never sit on both sides. Training scenes use the
    'train' side as (blurred) backgrounds, the real-texture benchmark only the 'test' side.

    >>> photo_split("Acer_rubrum_1.jpg") == photo_split("acer_rubrum_2.jpg")
    True
    """
    stem = Path(name).stem.lower()
    head, _, tail = stem.rpartition("_")
    return _split_side(head if head and tail.isdigit() else stem, test_fraction)


def load_photos(folder, *, split: str | None = None, max_side: int = 1024) -> list[np.ndarray]:
    """The JPEG / PNG photos of a folder as RGB uint8 arrays (long side at most ``max_side``).

    Parameters
    ----------
    folder : path
    split : {'train', 'test'}, optional
        Keep only that side of :func:`photo_split`.
    """
    from PIL import Image

    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"photos {folder}: not a directory")
    out = []
    for f in sorted(q for q in folder.iterdir() if q.suffix.lower() in (".jpg", ".jpeg", ".png")):
        if split is not None and photo_split(f.name) != split:
            continue
        with Image.open(f) as im:
            rgb = np.asarray(im.convert("RGB"), np.uint8)
        if max(rgb.shape[:2]) > max_side:
            s = max_side / max(rgb.shape[:2])
            rgb = cv2.resize(rgb, (round(rgb.shape[1] * s), round(rgb.shape[0] * s)), interpolation=cv2.INTER_AREA)
        out.append(rgb)
    if not out:
        where = "" if split is None else f" in split {split!r}"
        raise InputError(f"photos {folder}: no JPEG or PNG files{where}")
    return out


def photo_background(photo: np.ndarray, rng, *, size: int, blur: tuple = (2.0, 6.0)) -> np.ndarray:
    """An out-of-focus background from a real photo: a random square crop, scaled and blurred.

    The crop covers at least half the photo's short side; ``blur`` is the range of the
    Gaussian sigma in pixels at ``size``, the depth of field behind a photographed tree.
    Returns (size, size, 3) uint8.
    """
    S = int(size)
    H, W = photo.shape[:2]
    side = int(min(H, W) * rng.uniform(0.5, 1.0))
    y, x = int(rng.integers(0, H - side + 1)), int(rng.integers(0, W - side + 1))
    bg = cv2.resize(np.ascontiguousarray(photo[y:y + side, x:x + side]), (S, S), interpolation=cv2.INTER_AREA)
    sigma = rng.uniform(*blur)
    return np.clip(np.rint(cv2.GaussianBlur(bg.astype(np.float32), (0, 0), sigma)), 0, 255).astype(np.uint8)


def photo_pseudo_labels(photo: np.ndarray, *, inner: float = 0.02, outer: float = 0.05,
                        max_side: int = 512) -> np.ndarray | None:
    """Pseudo-labels of a real photo's main tree for training: tree inside, background far outside.

    The colour rules (:func:`treeform.segment.segment_tree`) find the main tree; its mask
    eroded by ``inner`` x the long side is :data:`TREE_ANY`, everything farther than
    ``outer`` x the long side from it is background, the band between is :data:`UNSURE`
    (no loss). Only real *sharp* tree texture labelled tree teaches a network that a real
    photographed tree is a tree: otherwise the real photos it sees are all out-of-focus
    backgrounds, labelled background, and it learns to call real foliage background.

    Returns (H, W) uint8 at the photo's size, or None when the rules find no tree.
    """
    from treeform._shared.errors import NoTreeFoundError
    from treeform.segment.classical import _disc, segment_tree

    img = np.asarray(photo)
    H, W = img.shape[:2]
    s = min(1.0, max_side / max(H, W))
    small = img if s == 1.0 else cv2.resize(img, (round(W * s), round(H * s)), interpolation=cv2.INTER_AREA)
    try:
        tree = segment_tree(small, seed=0).tree_mask.astype(np.uint8)
    except NoTreeFoundError:
        return None
    side = max(small.shape[:2])

    def disc(share):
        return _disc(max(1, int(round(share * side))))

    lab = np.full(tree.shape, UNSURE, np.uint8)
    lab[cv2.dilate(tree, disc(outer)) == 0] = 0
    lab[cv2.erode(tree, disc(inner)) > 0] = TREE_ANY
    if s < 1.0:
        lab = cv2.resize(lab, (W, H), interpolation=cv2.INTER_NEAREST)
    return lab


def noise_image(rng, *, size: int) -> np.ndarray:
    """A picture of nothing: random noise (uniform or Gaussian, per pixel, blurred or blocky, grey or
    colour, any mean and contrast), (size, size, 3) uint8. A negative for the segmenter: noise
    has texture everywhere, like foliage, but no tree.
    """
    S = int(size)
    cells = S if rng.random() < 0.5 else int(rng.integers(4, max(5, S // 2)))
    shape = (cells, cells, 3 if rng.random() < 0.6 else 1)
    z = rng.random(shape) if rng.random() < 0.5 else np.clip(0.5 + rng.normal(0, 0.25, shape), 0, 1)
    z = z.astype(np.float32)
    if cells != S:
        interp = cv2.INTER_NEAREST if rng.random() < 0.5 else cv2.INTER_LINEAR
        z = cv2.resize(z, (S, S), interpolation=interp).reshape(S, S, -1)
    if z.shape[2] == 1:
        z = np.repeat(z, 3, 2)
    if rng.random() < 0.3:
        z = cv2.GaussianBlur(z, (0, 0), rng.uniform(0.5, 3.0))
    mean, amp = rng.uniform(0.2, 0.8, 3), rng.uniform(0.3, 1.0)
    return np.clip(np.rint(255 * np.clip(mean + amp * (z - 0.5), 0, 1)), 0, 255).astype(np.uint8)


def photo_scene(photo: np.ndarray, labels: np.ndarray, rng, *, size: int) -> tuple[np.ndarray, np.ndarray]:
    """A training scene from a real photo and its :func:`photo_pseudo_labels`: a random crop.

    The crop (60-100 % of the short side, anywhere) is scaled to ``size``; the labels follow
    by nearest neighbour (the :data:`UNSURE` band absorbs the edge). Camera effects are the
    caller's. Returns (size, size, 3) uint8 and (size, size) uint8.
    """
    S = int(size)
    H, W = photo.shape[:2]
    side = int(min(H, W) * rng.uniform(0.6, 1.0))
    y, x = int(rng.integers(0, H - side + 1)), int(rng.integers(0, W - side + 1))
    img = cv2.resize(np.ascontiguousarray(photo[y:y + side, x:x + side]), (S, S), interpolation=cv2.INTER_AREA)
    lab = cv2.resize(np.ascontiguousarray(labels[y:y + side, x:x + side]), (S, S), interpolation=cv2.INTER_NEAREST)
    if rng.random() < 0.5:
        img, lab = img[:, ::-1], lab[:, ::-1]
    return np.ascontiguousarray(img), np.ascontiguousarray(lab)


def load_cutouts(folder, *, split: str | None = None, recursive: bool = True) -> list[Sprite]:
    """RGBA tree cut-outs of a folder as sprites (tree mask = alpha >= 1/2, part unknown).

    Parameters
    ----------
    folder : path
        PNG files with an alpha channel (e.g. ``../shared/data/billboards``).
    split : {'train', 'test'}, optional
        Keep only that side of :func:`cutout_split`.
    """
    from PIL import Image

    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"cut-outs {folder}: not a directory")
    files = sorted(folder.rglob("*.png") if recursive else folder.glob("*.png"))
    out = []
    for f in files:
        if split is not None and cutout_split(f.name) != split:
            continue
        with Image.open(f) as im:
            if "A" not in im.getbands():
                continue
            rgba = np.asarray(im.convert("RGBA"), np.uint8)
        if max(rgba.shape[:2]) > 512:  # large cut-outs: keep them a handy size
            s = 512 / max(rgba.shape[:2])
            rgba = cv2.resize(rgba, (max(1, round(rgba.shape[1] * s)), max(1, round(rgba.shape[0] * s))),
                              interpolation=cv2.INTER_AREA)
        lab = np.where(rgba[..., 3] >= 128, TREE_ANY, 0).astype(np.uint8)
        sp = _crop(rgba, lab, f.name)
        if sp is not None:
            out.append(sp)
    if not out:
        raise InputError(f"cut-outs {folder}: no RGBA PNG files{'' if split is None else f' in split {split!r}'}")
    return out


# ------------------------------------------------------------------------------ tree looks
def _smooth_noise(rng, h: int, w: int, scale: float) -> np.ndarray:
    """Low-frequency noise in [0, 1], features ~ ``scale`` pixels."""
    gh, gw = max(2, int(h / scale) + 2), max(2, int(w / scale) + 2)
    n = cv2.resize(rng.random((gh, gw)).astype(np.float32), (w, h), interpolation=cv2.INTER_CUBIC)
    return np.clip(n, 0, 1)


def recolor_season(rgb: np.ndarray, foliage: np.ndarray, season: str, rng) -> np.ndarray:
    """Recolour the ``foliage`` pixels of an (h, w, 3) uint8 image to a season's look.

    Hue moves to the season's hue (keeping half the leaf's own hue variation, plus a
    low-frequency patchiness), saturation and value are scaled. 'summer' jitters the hue a
    little; 'sparse' leaves the colour alone (thinning happens in :func:`compose_scene`).
    """
    if season not in SEASONS:
        raise InputError(f"season: expected one of {', '.join(SEASONS)}, got {season!r}")
    out = rgb.copy()
    if season in ("sparse",) or not foliage.any():
        return out
    hsv = cv2.cvtColor(rgb, cv2.COLOR_RGB2HSV_FULL).astype(np.float32)  # H in 0..255
    hdeg = hsv[..., 0] * (360.0 / 256.0)
    h0 = float(np.median(hdeg[foliage]))
    if season == "summer":
        target, s_mul, v_mul = h0 + rng.uniform(-12, 12), rng.uniform(0.8, 1.15), rng.uniform(0.85, 1.1)
    else:
        target, s_mul, v_mul = _SEASON_HSV[season]
        target += rng.uniform(-8, 8)
        s_mul *= rng.uniform(0.85, 1.15)
        v_mul *= rng.uniform(0.85, 1.15)
    patch = _smooth_noise(rng, *rgb.shape[:2], max(4.0, rgb.shape[0] / rng.uniform(3, 10)))
    mix_hue = target + (patch - 0.5) * rng.uniform(0, 50)
    dh = ((hdeg - h0 + 180.0) % 360.0) - 180.0
    new_h = (mix_hue + 0.5 * dh) % 360.0
    s = hsv[..., 1]
    if season != "summer":
        s = np.maximum(s, 70.0)  # grey-green needles still take the colour
    new_s = np.clip(s * s_mul, 0, 255)
    new_v = np.clip(hsv[..., 2] * v_mul, 0, 255)
    rec = np.stack([new_h * (256.0 / 360.0) % 256.0, new_s, new_v], -1).astype(np.uint8)
    rec = cv2.cvtColor(rec, cv2.COLOR_HSV2RGB_FULL)
    out[foliage] = rec[foliage]
    return out


def _foliage_pixels(sprite: Sprite) -> np.ndarray:
    """Foliage of a sprite: its label 1, or for cut-outs the green-to-yellow, saturated pixels."""
    if (sprite.labels == TREE_ANY).any():
        hsv = cv2.cvtColor(np.ascontiguousarray(sprite.rgba[..., :3]), cv2.COLOR_RGB2HSV_FULL)
        hdeg = hsv[..., 0].astype(np.float32) * (360.0 / 256.0)
        return (sprite.labels > 0) & (hdeg > 45) & (hdeg < 200) & (hsv[..., 1] > 30)
    return sprite.labels == 1


def _tree_look(sprite: Sprite, rng) -> tuple[np.ndarray, np.ndarray]:
    """Season, bark tint and thinning applied to a sprite: (rgba float [0, 1], labels)."""
    rgba = sprite.rgba.copy()
    labels = sprite.labels.copy()
    season = str(rng.choice(SEASONS, p=[0.3, 0.1, 0.12, 0.12, 0.1, 0.06, 0.1, 0.1]))
    fol = _foliage_pixels(sprite)
    rgba[..., :3] = recolor_season(np.ascontiguousarray(rgba[..., :3]), fol, season, rng)
    wood = labels == 2
    if wood.any() and rng.random() < 0.6:
        tint = rng.uniform(0.55, 1.25) * np.clip(rng.normal(1.0, 0.1, 3), 0.75, 1.25)
        rgba[..., :3][wood] = np.clip(rgba[..., :3][wood] * tint, 0, 255).astype(np.uint8)
    if season == "sparse" and labels.max() <= 2 and fol.any():
        # thin the crown: drop blobs of foliage; wood behind a dropped leaf is not in the render, so the
        # dropped pixels become background (gaps in the crown)
        keep = _smooth_noise(rng, *labels.shape, max(3.0, labels.shape[0] / rng.uniform(8, 25)))
        drop = fol & (keep < rng.uniform(0.3, 0.6))
        rgba[drop, 3] = 0
        labels[drop] = 0
    return rgba.astype(np.float32) / 255.0, labels


# ------------------------------------------------------------------------------ pasting
def _resample_labels(labels: np.ndarray, size: tuple, interp: int) -> np.ndarray:
    """``labels`` resized to ``size`` (w, h) as the image is: each class's coverage is resampled
    with the image's interpolation and every pixel takes the labelled class that covers most
    of it (0 where none does).

    Nearest-neighbour resizing would keep or drop a 1-px twig by the sampling phase while the
    image shows it as a half-covered pixel, labels the network cannot learn nor be scored on.
    """
    classes = np.unique(labels)
    classes = classes[classes > 0]
    if len(classes) == 0:
        return np.zeros(size[::-1], labels.dtype)
    cover = np.stack([(labels == c).astype(np.float32) for c in classes], -1)
    cover = cv2.resize(cover, size, interpolation=interp).reshape(size[1], size[0], len(classes))
    best = cover.argmax(-1)
    out = classes[best].astype(labels.dtype)
    out[np.take_along_axis(cover, best[..., None], -1)[..., 0] <= 0.0] = 0
    return out


def _paste(canvas: np.ndarray, lab: np.ndarray | None, rgba: np.ndarray, labels: np.ndarray | None,
           height_px: float, cx: float, base_y: float, *, label_value=None, haze=0.0, haze_col=None,
           blur=0.0) -> None:
    """Scale a sprite to ``height_px`` and composite it with its foot at (cx, base_y), in place.

    ``lab`` receives the sprite's labels (or ``label_value`` where it is opaque); ``haze``
    blends the sprite toward ``haze_col`` (aerial perspective), ``blur`` defocuses it.
    """
    H, W = canvas.shape[:2]
    h0, w0 = rgba.shape[:2]
    s = max(height_px, 4.0) / h0
    nh, nw = max(2, int(round(h0 * s))), max(2, int(round(w0 * s)))
    interp = cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR
    pre = rgba.copy()
    pre[..., :3] *= pre[..., 3:4]  # premultiplied for resampling
    r = cv2.resize(pre, (nw, nh), interpolation=interp)
    if blur > 0.3:
        r = cv2.GaussianBlur(r, (0, 0), blur)
    a = np.clip(r[..., 3:4], 0, 1)
    col = r[..., :3] / np.maximum(a, 1e-4)
    if haze > 0:
        col = col * (1 - haze) + np.asarray(haze_col, np.float32) * haze
    x0, y0 = int(round(cx - nw / 2)), int(round(base_y - nh))
    ys, xs = max(0, y0), max(0, x0)
    ye, xe = min(H, y0 + nh), min(W, x0 + nw)
    if ye <= ys or xe <= xs:
        return
    sl = (slice(ys - y0, ye - y0), slice(xs - x0, xe - x0))
    aa = a[sl]
    canvas[ys:ye, xs:xe] = canvas[ys:ye, xs:xe] * (1 - aa) + col[sl] * aa
    if lab is not None:
        if labels is not None:
            lr = _resample_labels(labels, (nw, nh), interp)[sl]
            opaque = (aa[..., 0] >= 0.5) & (lr > 0)
            lab[ys:ye, xs:xe][opaque] = lr[opaque]
            # a pixel the sprite covers but does not label (coverage < 1/2 at the source) is left as it was
        else:
            opaque = aa[..., 0] >= 0.5
            lab[ys:ye, xs:xe][opaque] = label_value


def _hsv(h, s, v):
    return np.array(colorsys.hsv_to_rgb(h % 1.0, float(np.clip(s, 0, 1)), float(np.clip(v, 0, 1))), np.float32)


def _clutter(img: np.ndarray, horizon: int, rng) -> None:
    """Cars, people-sized figures, hedges, lamp posts and lawn bands on the ground (in place)."""
    H, W = img.shape[:2]
    ground = max(horizon, int(0.5 * H))
    for _ in range(int(rng.integers(0, 4))):
        kind = rng.choice(["car", "person", "hedge", "post", "lawn"], p=[0.3, 0.25, 0.2, 0.1, 0.15])
        y = int(rng.uniform(ground, H * 1.02))
        x = int(rng.uniform(-0.1, 1.1) * W)
        scale = (y - horizon * 0.9) / H + 0.15
        if kind == "car":
            cw, ch = int(W * rng.uniform(0.15, 0.35) * scale * 1.6), int(H * rng.uniform(0.05, 0.09) * scale * 1.6)
            body = _hsv(rng.random(), rng.uniform(0, 0.9), rng.uniform(0.1, 0.95))
            cv2.rectangle(img, (x - cw // 2, y - ch), (x + cw // 2, y - ch // 4), body.tolist(), -1)
            cv2.rectangle(img, (x - cw // 3, y - int(ch * 1.6)), (x + cw // 4, y - ch), (body * 0.8).tolist(), -1)
            cv2.rectangle(img, (x - cw // 3 + 2, y - int(ch * 1.5)), (x + cw // 4 - 2, y - ch),
                          _hsv(0.58, 0.2, rng.uniform(0.15, 0.5)).tolist(), -1)
            for wx in (x - cw // 3, x + cw // 3):
                cv2.circle(img, (wx, y - ch // 4), max(2, ch // 3), (0.05, 0.05, 0.05), -1)
        elif kind == "person":
            ph = int(H * rng.uniform(0.08, 0.2) * scale * 1.5)
            pw = max(2, ph // 4)
            cloth = _hsv(rng.random(), rng.uniform(0, 0.8), rng.uniform(0.1, 0.9))
            cv2.rectangle(img, (x - pw // 2, y - int(ph * 0.85)), (x + pw // 2, y - ph // 2), cloth.tolist(), -1)
            cv2.rectangle(img, (x - pw // 2, y - ph // 2), (x + pw // 2, y), (cloth * 0.6).tolist(), -1)
            cv2.circle(img, (x, y - int(ph * 0.92)), max(1, pw // 2), _hsv(0.07, 0.4, rng.uniform(0.3, 0.9)).tolist(), -1)
        elif kind == "hedge":
            hh = int(H * rng.uniform(0.04, 0.12) * scale * 1.5)
            xs = np.arange(W)
            top = y - hh * (0.8 + 0.2 * np.sin(xs / rng.uniform(3, 12) + rng.uniform(0, 6)))
            x0, x1 = sorted((int(rng.uniform(-0.2, 0.6) * W), int(rng.uniform(0.4, 1.2) * W)))
            col = _hsv(rng.uniform(0.18, 0.4), rng.uniform(0.3, 0.7), rng.uniform(0.15, 0.45))
            rows = np.arange(H)[:, None]
            band = (rows >= top[None, :]) & (rows <= y) & (xs[None, :] >= x0) & (xs[None, :] <= x1)
            tex = 0.8 + 0.4 * rng.random((H, W, 1)).astype(np.float32)
            img[band] = (col * tex)[band]
        elif kind == "post":
            ph = int(H * rng.uniform(0.2, 0.5))
            col = _hsv(0, 0, rng.uniform(0.1, 0.6)).tolist()
            cv2.line(img, (x, y), (x, y - ph), col, max(1, int(W * 0.006)))
            cv2.line(img, (x, y - ph), (x + int(W * 0.04), y - ph), col, max(1, int(W * 0.005)))
        else:  # a band of lawn of another green
            bh = int(H * rng.uniform(0.03, 0.1))
            col = _hsv(rng.uniform(0.17, 0.33), rng.uniform(0.3, 0.7), rng.uniform(0.25, 0.7))
            img[max(0, y - bh):y] = img[max(0, y - bh):y] * 0.3 + col * 0.7


def _bushes(img: np.ndarray, other, rng, horizon: int) -> None:
    """A row of bushes (or a clipped hedge) on the ground, textured with crowns of ``other()`` sprites."""
    H, W = img.shape[:2]
    foot = rng.uniform(max(horizon, 0.55 * H), 1.02 * H)
    hh = H * rng.uniform(0.06, 0.3)
    x = rng.uniform(-0.3, 0.3) * W
    end = x + W * rng.uniform(0.4, 1.6)
    while x < end:
        rgba = other()
        crown = rgba[: max(2, int(rgba.shape[0] * rng.uniform(0.45, 0.75)))]  # the crown, without the trunk
        if crown[..., 3].max() < 0.5:
            break
        bw = hh * rng.uniform(1.2, 4.0)
        bh = hh * rng.uniform(0.7, 1.1)
        # squash the crown into a bush of (bw, bh): paste at height bh, then stretch horizontally
        sx = bw / max(1.0, bh * crown.shape[1] / crown.shape[0])
        wide = cv2.resize(crown, (max(2, int(crown.shape[1] * sx)), crown.shape[0]), interpolation=cv2.INTER_LINEAR)
        _paste(img, None, np.ascontiguousarray(wide), None, bh, x + bw / 2, foot + rng.uniform(-0.02, 0.02) * H,
               blur=rng.uniform(0.0, 1.5))
        x += bw * rng.uniform(0.5, 0.9)


def camera_effects(img: np.ndarray, sky_col, rng) -> np.ndarray:
    """A float RGB image in [0, 1] as a camera might have taken it: haze, defocus, exposure,
    white balance, gamma, noise and JPEG artefacts (each drawn from ``rng``). Returns uint8."""
    if rng.random() < 0.3:
        hz = rng.uniform(0.05, 0.3)
        img = img * (1 - hz) + hz * sky_col
    if rng.random() < 0.3:
        img = cv2.GaussianBlur(img, (0, 0), rng.uniform(0.4, 1.3))
    img = img * rng.uniform(0.55, 1.5) * np.clip(rng.normal(1.0, 0.08, 3), 0.75, 1.25)
    img = np.clip(img, 0, 1) ** rng.uniform(0.75, 1.35)
    img = img * 255.0 + rng.normal(0, rng.uniform(0, 5), img.shape)
    out = np.clip(np.rint(img), 0, 255).astype(np.uint8)
    if rng.random() < 0.6:
        ok, buf = cv2.imencode(".jpg", out[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, int(rng.integers(25, 95))])
        out = np.ascontiguousarray(cv2.imdecode(buf, cv2.IMREAD_COLOR)[..., ::-1])
    return out


def compose_scene(tree: Sprite | None, others: list[Sprite], rng, *, size: int = 256,
                  background: np.ndarray | None = None, bushes: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """One randomised training scene: the main ``tree`` over clutter and other trees.

    Parameters
    ----------
    tree : Sprite or None
        The tree to label; None gives a scene without a main tree (all background).
    others : list of Sprite
        Pool of sprites drawn for background trees and edge neighbours (labelled background).
    rng : numpy.random.Generator
    size : int
        Edge of the square scene.
    background : ndarray, shape (size, size, 3), uint8, optional
        A ready background (e.g. from a pre-drawn pool); default: a new
        :func:`~treeform.dataset.procedural_background`.
    bushes : float
        Probability of a row of bushes or a hedge behind the tree's foot, textured with the
        crown of another sprite (real leaves, labelled background): what a photo of a park
        tree has behind its trunk, and what colour texture alone cannot tell from the crown.

    Returns
    -------
    image : ndarray, shape (size, size, 3), uint8
    labels : ndarray, shape (size, size), uint8
        0 background, 1 foliage, 2 wood, :data:`TREE_ANY` tree of unknown part.
    """
    from treeform.dataset.backgrounds import procedural_background

    S = int(size)
    if background is None:
        background = procedural_background(S, seed=rng)
    img = background.astype(np.float32) / 255.0
    if rng.random() < 0.5:
        img = img[:, ::-1].copy()
    # the horizon: where the background's top rows stop looking like its sky (rough, for placement)
    horizon = int(S * rng.uniform(0.45, 0.8))
    _clutter(img, horizon, rng)
    lab = np.zeros((S, S), np.uint8)
    sky_col = img[: max(2, S // 8)].reshape(-1, 3).mean(0)

    def other():
        sp = others[int(rng.integers(len(others)))]
        rgba, _ = _tree_look(sp, rng)
        if rng.random() < 0.5:
            rgba = rgba[:, ::-1]
        return np.ascontiguousarray(rgba)

    # trees out of focus right behind the subject (a park, a tree line close by): large, blurred
    if others and rng.random() < 0.35:
        for _ in range(int(rng.integers(1, 4))):
            _paste(img, None, other(), None, S * rng.uniform(0.7, 2.0), rng.uniform(-0.2, 1.2) * S,
                   S * rng.uniform(0.8, 1.6), haze=rng.uniform(0.0, 0.3), haze_col=sky_col,
                   blur=S / 256 * rng.uniform(2.0, 7.0))
    # distant trees behind: smaller, hazier, softer
    if others:
        for _ in range(int(rng.choice([0, 1, 2, 3, 5], p=[0.3, 0.25, 0.2, 0.15, 0.1]))):
            _paste(img, None, other(), None, S * rng.uniform(0.12, 0.55), rng.uniform(-0.1, 1.1) * S,
                   horizon + rng.uniform(-0.02, 0.08) * S, haze=rng.uniform(0.1, 0.6), haze_col=sky_col,
                   blur=rng.uniform(0.0, 2.0))
    if others and bushes > 0 and rng.random() < bushes:
        _bushes(img, other, rng, horizon)
    if tree is not None:
        rgba, labels = _tree_look(tree, rng)
        if rng.random() < 0.5:
            rgba, labels = rgba[:, ::-1], labels[:, ::-1]
        # (small photo cut-outs are not blown up into close-ups: they would be blurred beyond any photo)
        close_up = rng.random() < 0.35 and rgba.shape[0] >= 0.6 * S
        if close_up:
            # the photographer stands close: the tree fills the frame and is cut by its edges
            hpx = S * rng.uniform(1.0, 1.9)
            w_px = hpx * rgba.shape[1] / rgba.shape[0]
            cx = S / 2 + rng.uniform(-0.15, 0.15) * S
            base = S * rng.uniform(0.85, 1.3)
        else:
            hpx = S * rng.uniform(0.35, 0.98)
            w_px = hpx * rgba.shape[1] / rgba.shape[0]
            if w_px > 0.98 * S:  # wide crowns: keep the crown (mostly) in the frame
                hpx *= 0.98 * S / w_px
                w_px = 0.98 * S
            slack = max(0.0, (S - w_px) / 2)
            cx = S / 2 + rng.uniform(-1, 1) * min(slack, 0.3 * S)
            base = rng.uniform(max(hpx, 0.6 * S), 1.06 * S)
        # neighbours at the frame edges, behind the main tree, smaller than it, labelled background
        if others and not close_up and rng.random() < 0.35:
            for side in rng.permutation([-1, 1])[: int(rng.integers(1, 3))]:
                nh = min(S * rng.uniform(0.5, 1.1), hpx * rng.uniform(0.6, 1.0))
                ncx = (0 if side < 0 else S) + side * rng.uniform(0.0, 0.3) * nh
                _paste(img, None, other(), None, nh, ncx, rng.uniform(0.85, 1.05) * S,
                       haze=rng.uniform(0.0, 0.25), haze_col=sky_col, blur=rng.uniform(0, 1.0))
        # a soft ground shadow at the foot
        if base < S and rng.random() < 0.6:
            sh = np.zeros((S, S), np.float32)
            cv2.ellipse(sh, (int(cx), int(base)), (int(w_px * rng.uniform(0.3, 0.6)), int(S * 0.03) + 1), 0, 0, 360,
                        1.0, -1)
            sh = cv2.GaussianBlur(sh, (0, 0), 3)[..., None] * rng.uniform(0.2, 0.6)
            img *= 1 - sh
        _paste(img, lab, rgba, labels, hpx, cx, base)
    elif others and rng.random() < 0.3:  # no main tree, but a neighbour cut by an edge
        side = -1 if rng.random() < 0.5 else 1
        nh = S * rng.uniform(0.5, 1.1)
        _paste(img, None, other(), None, nh, (0 if side < 0 else S) + side * rng.uniform(0.05, 0.3) * nh,
               rng.uniform(0.85, 1.05) * S, haze=rng.uniform(0.0, 0.25), haze_col=sky_col)

    # -- camera: haze, defocus, exposure, white balance, gamma, noise, JPEG
    out = camera_effects(img, sky_col, rng)
    return out, lab


def paste_on_photo(sprite: Sprite, photo: np.ndarray, rng, *, size: int = 512,
                   blur: tuple = (2.0, 6.0)) -> tuple[np.ndarray, np.ndarray]:
    """A real-texture test image with an exact mask: ``sprite`` pasted over a blurred photo crop.

    The photo (any RGB uint8 image) is cropped to a random square of at least half its
    short side, scaled to ``size`` and blurred (sigma drawn from ``blur``, in pixels at
    ``size``: the background is out of focus, as behind a photographed tree); the sprite
    is pasted at a random height (40–95 % of the frame) and position, its foot in the
    lower part of the frame. Returns the image (size, size, 3) uint8 and the tree mask
    (size, size) bool (coverage >= 1/2).
    """
    S = int(size)
    img = photo_background(photo, rng, size=S, blur=blur).astype(np.float32) / 255.0
    lab = np.zeros((S, S), np.uint8)
    rgba = sprite.rgba.astype(np.float32) / 255.0
    hpx = S * rng.uniform(0.4, 0.95)
    w_px = hpx * rgba.shape[1] / rgba.shape[0]
    if w_px > 0.95 * S:
        hpx *= 0.95 * S / w_px
        w_px = 0.95 * S
    cx = rng.uniform(w_px / 2, S - w_px / 2) if w_px < S else S / 2
    base = rng.uniform(max(hpx, 0.7 * S), S)
    _paste(img, lab, rgba, np.where(sprite.labels > 0, TREE_ANY, 0).astype(np.uint8), hpx, cx, base)
    out = np.clip(np.rint(img * 255.0), 0, 255).astype(np.uint8)
    return out, lab > 0


def _sprite_foot(a: np.ndarray, rgb: np.ndarray | None = None) -> float:
    """The column of a tree sprite's foot (its trunk's, where the trunk meets the ground).

    Without colour: in its lowest row, the middle of the opaque run whose piece of the
    sprite's lower 30 % is largest (the trunk, which carries the tree; a leaf or a twig hanging
    as low is a small piece of its own there). With ``rgb`` (the sprite's colours, (H, W, 3)):
    the trunk is the bark of the lower 30 %, an upright, narrow piece of opaque pixels that are
    not green (a conifer's skirt or a drooping branch can hang lower than the trunk's foot and
    would pull the foot sideways); where such bark stands, the foot is the median column of
    its lowest rows.

    >>> a = np.zeros((100, 60), bool); a[10:80, 10:50] = True; a[80:95, 28:32] = True; a[90:100, 50:54] = True
    >>> _sprite_foot(a)                          # a green tip hangs lowest, beside the trunk: it wins
    51.5
    >>> rgb = np.zeros((100, 60, 3), np.uint8); rgb[..., 1] = 160; rgb[80:95, 28:32] = (120, 90, 60)
    >>> _sprite_foot(a, rgb)                     # the bark's column
    29.5
    """
    import scipy.ndimage as ndi

    h, w = a.shape
    rows = np.flatnonzero(a.any(1))
    if rows.size == 0:
        return 0.5 * (w - 1)
    y0 = int(0.7 * (rows[-1] + 1))
    if rgb is not None:
        c = np.asarray(rgb, np.int32)[..., :3]
        bark = a & (c[..., 1] <= np.maximum(c[..., 0], c[..., 2]) + 8)
        bark[:y0] = False
        lab, n = ndi.label(bark, structure=np.ones((3, 3)))
        if n:
            # the trunk: the bark piece reaching lowest among the upright, narrow ones (at least 5 % of
            # the sprite's height, twice as tall as wide, at most 15 % of its width: not an autumn crown)
            boxes = ndi.find_objects(lab)
            min_h = 0.05 * (rows[-1] - rows[0] + 1)

            def upright(sl) -> bool:
                bh, bw = sl[0].stop - sl[0].start, sl[1].stop - sl[1].start
                return bh >= min_h and bh >= 2 * bw and bw <= 0.15 * w

            tall = [k + 1 for k, sl in enumerate(boxes) if sl is not None and upright(sl)]
            if tall:
                k = max(tall, key=lambda k: boxes[k - 1][0].stop)
                ys, xs = np.nonzero(lab == k)
                low = ys >= ys.max() - max(1, int(0.02 * h))
                return float(np.median(xs[low]))
    lab, _ = ndi.label(a[y0:rows[-1] + 1], structure=np.ones((3, 3)))
    bottom = lab[-1]
    area = np.bincount(lab.ravel())
    area[0] = 0
    best = int(np.argmax(np.where(np.isin(np.arange(len(area)), bottom), area, 0)))
    return float(np.flatnonzero(bottom == best).mean())


def group_scene(sprites, feet, heights, rng, *, size: tuple = (960, 720), fov_y: float = 40.0,
                camera_height: float = 1.6) -> dict:
    """A photo of several trees standing on flat ground, with each tree's exact pixels and foot.

    The test data of :func:`treeform.segment.instances.find_tree_instances` and of placing the
    trees it finds (``reconstruct --all-trees``): a level pinhole camera (vertical field of view ``fov_y``)
    ``camera_height`` metres above the ground looks along the ground; tree ``k`` (``sprites[k]``,
    ``heights[k]`` metres tall) stands at ``feet[k] = (x, z)``: ``x`` metres to the right, ``z``
    metres ahead: the sprite's lowest row is pasted at that point's row and its trunk's column
    (:func:`_sprite_foot`) at its column. Farther
    trees are pasted first. The ground is a lawn with a little texture, the sky a gradient, the
    horizon the middle row.

    Parameters
    ----------
    sprites : sequence of Sprite
    feet : array_like, shape (N, 2)
    heights : array_like, shape (N,)
    rng : numpy.random.Generator
    size : (width, height)
    fov_y, camera_height : float

    Returns
    -------
    dict
        ``image`` (H, W, 3) uint8; ``instances`` (H, W) uint8 (k + 1 where tree k is seen, 0
        elsewhere); ``feet_px`` (N, 2) (u, v), the pixel of each foot (where its trunk meets the
        ground); ``tops_px`` (N,) each top row; ``areas_px`` (N,) each tree's pixels were it alone
        in the photo (``(instances == k + 1).sum() / areas_px[k]`` is the share of tree ``k`` that
        the trees before it leave visible).
    """
    W, H = (int(x) for x in size)
    feet = np.asarray(feet, np.float64).reshape(-1, 2)
    heights = np.asarray(heights, np.float64).reshape(-1)
    if len(sprites) != len(feet) or len(heights) != len(feet):
        raise InputError(f"sprites, feet, heights: expected as many of each, got {len(sprites)}, {len(feet)}, "
                         f"{len(heights)}")
    if np.any(feet[:, 1] <= 0) or np.any(heights <= 0):
        raise InputError("feet: every tree ahead of the camera (z > 0), heights > 0")
    f = 0.5 * H / np.tan(np.radians(fov_y) / 2)
    horizon = 0.5 * H
    rows = np.arange(H, dtype=np.float32)[:, None, None]
    sky = np.array([0.55, 0.72, 0.92], np.float32) + (rows / H) * np.array([0.25, 0.15, 0.05], np.float32)
    lawn = (np.array([0.30, 0.45, 0.18], np.float32) * (0.85 + 0.15 * rows / H)
            + 0.04 * _smooth_noise(rng, H, W, 6.0)[..., None])
    img = np.ascontiguousarray(np.where(rows < horizon, sky, lawn), np.float32)  # (H, W, 3)
    lab = np.zeros((H, W), np.uint8)
    feet_px = np.zeros((len(feet), 2))
    tops = np.zeros(len(feet))
    areas = np.zeros(len(feet), np.int64)
    for k in np.argsort(-feet[:, 1]):  # far to near
        x, z = feet[k]
        u, v = W / 2 + f * x / z, horizon + f * camera_height / z
        hpx = f * heights[k] / z
        rgba = sprites[k].rgba.astype(np.float32) / 255.0
        fx = _sprite_foot(rgba[..., 3] > 0.5, sprites[k].rgba[..., :3])  # its trunk's column, lowest row at (u, v)
        sc = hpx / rgba.shape[0]
        shift = (0.5 * (rgba.shape[1] - 1) - fx) * sc
        _paste(img, lab, rgba, None, hpx, u + shift, v + 1.0, label_value=k + 1)
        areas[k] = np.count_nonzero(lab == k + 1)  # all of it: the nearer trees come later
        tops[k] = v - hpx + 1.0
        feet_px[k] = (u, v)
    out = np.clip(np.rint(img * 255.0), 0, 255).astype(np.uint8)
    return {"image": out, "instances": lab, "feet_px": feet_px, "tops_px": tops, "areas_px": areas}
