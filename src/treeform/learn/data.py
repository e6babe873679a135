"""Training and test data of the perception networks, from our own synthetic datasets.

- :func:`render_sprites` reads the trees alone (``rgba.png`` + ``mask.png``) of a dataset
  made by ``treeform dataset generate``, or a sprite pack of :func:`save_sprites` (the same
  sprites cropped, a tenth of the dataset's size: what travels to a training machine);
- :class:`SceneStream` turns sprites into an endless, reproducible stream of randomised
  scenes (:func:`treeform.dataset.scenes.compose_scene`), one chunk per round, over a pool
  of procedural backgrounds that is refreshed as it goes;
- :func:`test_scenes` is the fixed test split: held-out trees (another dataset seed) and
  held-out cut-out identities over scenes of a fixed seed.

numpy only (no torch): the benchmark and the tests use it too.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from treeform._shared.errors import InputError

__all__ = ["render_sprites", "save_sprites", "load_sprites", "SceneStream", "test_scenes", "default_cutouts"]


def default_cutouts() -> Path | None:
    """``../shared/data/billboards`` next to a source checkout, when it exists (else None)."""
    here = Path(__file__).resolve()
    for parent in here.parents:
        cand = parent.parent / "shared" / "data" / "billboards"
        if cand.is_dir():
            return cand
    return None


def render_sprites(directory, *, limit: int | None = None) -> list:
    """Sprites (tree alone + 0/1/2 labels) of a generated dataset; needs ``rgba.png`` members."""
    from treeform.dataset.loader import SyntheticDataset
    from treeform.dataset.scenes import sprite_from_render
    from treeform.dataset.storage import decode_sample

    if (Path(directory) / _PACK_INDEX).is_file():
        sprites = load_sprites(directory)
        return sprites if limit is None else sprites[:limit]
    ds = SyntheticDataset(directory)
    n = len(ds) if limit is None else min(limit, len(ds))
    out = []
    for i in range(n):
        d = decode_sample(ds.members(i, ("mask.png", "rgba.png")))
        if "rgba" not in d:
            raise InputError(f"{directory}: samples lack the tree-alone rgba.png (regenerate with this version)")
        sp = sprite_from_render(d["rgba"], d["mask"], f"{Path(directory).name}:{i}")
        if sp is not None:
            out.append(sp)
    if not out:
        raise InputError(f"{directory}: no usable samples")
    return out


_PACK_INDEX = "sprites.json"
_PACK_FORMAT = "treeform-sprites/1"


def save_sprites(sprites, folder, *, quality: int | None = None) -> Path:
    """Write sprites as a pack that :func:`render_sprites` / :func:`load_sprites` read back.

    Each sprite is two images: its colour (``NNNNN.rgb.png``, or ``.rgb.webp`` at ``quality``)
    and its alpha + labels, always lossless (``NNNNN.la.png``, grey = labels, alpha = alpha).

    Parameters
    ----------
    sprites : list of Sprite
    folder : path
        Created if missing; an existing pack there is replaced.
    quality : int, optional
        WebP quality 1–100 for the colour (lossy, about 2.4x smaller than PNG at 95); None
        keeps it lossless.

    Returns
    -------
    Path
        ``folder``.
    """
    import json

    from PIL import Image

    if quality is not None and not 1 <= int(quality) <= 100:
        raise InputError(f"sprite pack quality {quality}: expected 1..100")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    ext = "png" if quality is None else "webp"
    names = []
    for i, sp in enumerate(sprites):
        rgb = Image.fromarray(np.ascontiguousarray(sp.rgba[..., :3]))
        if quality is None:
            rgb.save(folder / f"{i:05d}.rgb.png", optimize=False)
        else:
            rgb.save(folder / f"{i:05d}.rgb.webp", quality=int(quality), method=4)
        Image.fromarray(np.dstack([sp.labels, sp.rgba[..., 3]]).astype(np.uint8), "LA").save(folder / f"{i:05d}.la.png")
        names.append(sp.name)
    (folder / _PACK_INDEX).write_text(json.dumps({"format": _PACK_FORMAT, "n": len(names), "colour": ext,
                                                  "quality": quality, "names": names}))
    return folder


def load_sprites(folder) -> list:
    """The sprites of a pack written by :func:`save_sprites`."""
    import json

    from PIL import Image

    from treeform.dataset.scenes import Sprite

    folder = Path(folder)
    try:
        meta = json.loads((folder / _PACK_INDEX).read_text())
    except (OSError, ValueError) as e:
        raise InputError(f"{folder}: not a sprite pack ({e})") from None
    if meta.get("format") != _PACK_FORMAT:
        raise InputError(f"{folder}: sprite pack format {meta.get('format')!r}, expected {_PACK_FORMAT}")
    out = []
    for i, name in enumerate(meta["names"]):
        try:
            with Image.open(folder / f"{i:05d}.rgb.{meta['colour']}") as im:
                rgb = np.asarray(im.convert("RGB"), np.uint8)
            with Image.open(folder / f"{i:05d}.la.png") as im:
                la = np.asarray(im.convert("LA"), np.uint8)
        except OSError as e:
            raise InputError(f"{folder}: sprite {i}: {e}") from None
        if la.shape[:2] != rgb.shape[:2]:
            raise InputError(f"{folder}: sprite {i}: colour {rgb.shape[:2]} and labels {la.shape[:2]} differ")
        out.append(Sprite(np.dstack([rgb, la[..., 1]]), np.ascontiguousarray(la[..., 0]), name))
    if not out:
        raise InputError(f"{folder}: empty sprite pack")
    return out


class SceneStream:
    """Reproducible randomised scenes: chunk ``r`` depends only on (seed, r) and the sprites.

    Parameters
    ----------
    renders, cutouts : list of Sprite
        Main trees: synthetic renders (foliage / wood labels) and photo cut-outs (tree only).
    size : int
    seed : int
    cutout_fraction : float
        Share of scenes whose main tree is a cut-out (when there are any).
    negatives : float
        Share of scenes with no main tree.
    photos : list of ndarray, optional
        Real RGB photos; a share ``photo_fraction`` of the scenes is composed over an
        out-of-focus crop of one of them (:func:`~treeform.dataset.scenes.photo_background`,
        Gaussian sigma 3–8 px at a 512-px frame) instead of a procedural background: real
        parks, streets and trees behind the main tree, labelled background. Only clearly
        blurred: a sharp real tree labelled background teaches the network that real trees
        are background (a run with sigma from 1 px missed whole trees on real photos).
    photo_fraction : float
    photo_trees : list of (ndarray, ndarray), optional
        Real photos with pseudo-labels (:func:`~treeform.dataset.scenes.photo_pseudo_labels`:
        0 background, 3 tree, 255 no loss); a share ``photo_tree_fraction`` of the scenes is a
        crop of one of them (:func:`~treeform.dataset.scenes.photo_scene`) through the same
        camera effects: real, sharp tree texture labelled tree.
    photo_tree_fraction : float
    noise_fraction : float
        Share of scenes that are random noise (:func:`~treeform.dataset.scenes.noise_image`),
        all background.
    pool : int
        Procedural backgrounds kept; ``pool // 8`` are redrawn per chunk.
    bush_fraction : float
        ``bushes`` of :func:`~treeform.dataset.scenes.compose_scene`: share of scenes with a row
        of leafy bushes behind the tree's foot (labelled background).
    sparse_boost : float
        Cut-outs are drawn with weights ``fill ** -sparse_boost``, ``fill`` the share of a
        cut-out's box its tree covers: 0 draws them uniformly; 1 makes a leafless or sparse
        tree (a trunk and twigs, fill ~0.1) as frequent in the scenes as a dense crown's
        pixels are, so thin trees are not a rounding error of the loss.
    """

    def __init__(self, renders, cutouts=(), *, size: int = 224, seed: int = 0, cutout_fraction: float = 0.35,
                 negatives: float = 0.08, photos=(), photo_fraction: float = 0.2, photo_trees=(),
                 photo_tree_fraction: float = 0.0, noise_fraction: float = 0.0, pool: int = 256,
                 bush_fraction: float = 0.0, sparse_boost: float = 0.0):
        self.renders, self.cutouts = list(renders), list(cutouts)
        if not self.renders and not self.cutouts:
            raise InputError("no tree sprites to compose scenes from")
        self.size, self.seed = int(size), int(seed)
        self.cutout_fraction = cutout_fraction if self.cutouts else 0.0
        self.negatives = negatives
        self.photos = list(photos)
        self.photo_fraction = photo_fraction if self.photos else 0.0
        self.photo_trees = list(photo_trees)
        self.photo_tree_fraction = photo_tree_fraction if self.photo_trees else 0.0
        self.noise_fraction = float(noise_fraction)
        self.pool_size = int(pool)
        self.bush_fraction = float(bush_fraction)
        self._cut_p = None
        if sparse_boost and self.cutouts:
            fill = np.array([max(1e-3, float((c.labels > 0).mean())) for c in self.cutouts])
            w = fill ** -float(sparse_boost)
            self._cut_p = w / w.sum()
        self._pool: list | None = None

    def _background(self, k: int):
        from treeform.dataset.backgrounds import procedural_background

        return procedural_background(self.size, seed=np.random.default_rng([self.seed, 8, k]))

    def chunk(self, r: int, n: int) -> tuple[np.ndarray, np.ndarray]:
        """Scenes of round ``r``: images (n, S, S, 3) uint8 and labels (n, S, S) uint8."""
        from treeform.dataset.scenes import camera_effects, compose_scene, noise_image, photo_background, photo_scene

        # the pool after round r holds backgrounds r*step .. r*step + pool - 1 (deterministic per round)
        step = max(1, self.pool_size // 8)
        first = r * step
        keys = list(range(first, first + self.pool_size))
        if self._pool is None or self._pool[0] != keys:
            old = dict(zip(self._pool[0], self._pool[1])) if self._pool else {}
            self._pool = (keys, [old[k] if k in old else self._background(k) for k in keys])
        bgs = self._pool[1]
        rng = np.random.default_rng([self.seed, 7, r])
        others = self.renders + self.cutouts
        imgs = np.empty((n, self.size, self.size, 3), np.uint8)
        labs = np.empty((n, self.size, self.size), np.uint8)
        for i in range(n):
            if self.photo_tree_fraction and rng.random() < self.photo_tree_fraction:
                ph, pl = self.photo_trees[int(rng.integers(len(self.photo_trees)))]
                img, labs[i] = photo_scene(ph, pl, rng, size=self.size)
                sky = img[: max(2, self.size // 8)].reshape(-1, 3).mean(0) / 255.0
                imgs[i] = camera_effects(img.astype(np.float32) / 255.0, sky, rng)
                continue
            if self.noise_fraction and rng.random() < self.noise_fraction:
                imgs[i], labs[i] = noise_image(rng, size=self.size), 0
                continue
            u = rng.random()
            if u < self.negatives:
                tree = None
            elif u < self.negatives + self.cutout_fraction:
                tree = self.cutouts[int(rng.choice(len(self.cutouts), p=self._cut_p) if self._cut_p is not None
                                        else rng.integers(len(self.cutouts)))]
            else:
                pool = self.renders or self.cutouts
                tree = pool[int(rng.integers(len(pool)))]
            if self.photo_fraction and rng.random() < self.photo_fraction:
                bg = photo_background(self.photos[int(rng.integers(len(self.photos)))], rng, size=self.size,
                                      blur=(3.0 * self.size / 512, 8.0 * self.size / 512))
            else:
                bg = bgs[int(rng.integers(len(bgs)))]
            imgs[i], labs[i] = compose_scene(tree, others, rng, size=self.size, background=bg,
                                             bushes=self.bush_fraction)
        return imgs, labs


def test_scenes(renders, cutouts=(), *, n: int = 400, size: int = 224, seed: int = 90210) -> dict:
    """The fixed test split: ``n`` scenes from held-out sprites with a seed training never uses.

    Returns ``{"renders": (images, labels), "cutouts": (images, labels)}``: scenes whose
    main tree is a synthetic render (foliage / wood labels: mean IoU) and scenes whose
    main tree is a real cut-out (tree-vs-background IoU), ``n // 2`` each when both exist.
    """
    out = {}
    groups = [("renders", list(renders)), ("cutouts", list(cutouts))]
    groups = [(k, v) for k, v in groups if v]
    for j, (name, sprites) in enumerate(groups):
        stream = SceneStream(sprites if name == "renders" else [], sprites if name == "cutouts" else [],
                             size=size, seed=seed + j, cutout_fraction=1.0 if name == "cutouts" else 0.0,
                             negatives=0.0, pool=64)
        out[name] = stream.chunk(0, n // len(groups))
    return out
