"""Procedural photo-like backgrounds for synthetic tree images (seed 003 §4.2.1).

The paper composites its renders over "common landscape and urban scene photographs". We
cannot ship photographs, so :func:`procedural_background` paints a varied pool itself:
skies (clear, hazy, overcast, evening; gradients and fBm clouds), a horizon, distant
blurred vegetation, buildings and streets as simple shapes with windows and lane marks,
grass, soil and paving, a depth-of-field blur and a colour cast. :class:`BackgroundPool`
mixes these with a folder of the user's own photos (random crops).

Everything is a function of the generator passed in: same seed -> same image.
"""

from __future__ import annotations

import colorsys
from pathlib import Path

import numpy as np

from treeform._shared.errors import InputError
from treeform._shared.noise import periodic_noise
from treeform.io.images import PHOTO_SUFFIXES

__all__ = ["BACKGROUND_KINDS", "BackgroundPool", "procedural_background"]

BACKGROUND_KINDS = ("park", "field", "street", "city", "forest", "sky")
"""The scene types :func:`procedural_background` paints."""


def _hsv(h: float, s: float, v: float) -> np.ndarray:
    return np.array(colorsys.hsv_to_rgb(h % 1.0, float(np.clip(s, 0, 1)), float(np.clip(v, 0, 1))))


def _fbm(rng, h: int, w: int, base: float, octaves: int = 4, aspect: float = 1.0) -> np.ndarray:
    """Fractal sum of :func:`periodic_noise` octaves (features ~ ``base`` per image height), ~unit std."""
    out = np.zeros((h, w))
    amp, total = 1.0, 0.0
    for k in range(octaves):
        f = base * 2.0**k
        out += amp * periodic_noise(rng, h, w, f, f * aspect * w / h)
        total += amp * amp
        amp *= 0.5
    return out / np.sqrt(total)


def _sky(rng, h: int, w: int) -> np.ndarray:
    """Sky of height ``h``: a zenith-to-horizon gradient plus clouds. (h, w, 3) in [0, 1]."""
    style = rng.choice(["clear", "hazy", "overcast", "evening"], p=[0.4, 0.25, 0.2, 0.15])
    if style == "clear":
        zen, hor = _hsv(rng.uniform(0.55, 0.63), rng.uniform(0.45, 0.75), rng.uniform(0.7, 0.95)), None
        hor = _hsv(rng.uniform(0.55, 0.6), rng.uniform(0.1, 0.3), rng.uniform(0.88, 1.0))
        cover, cloud_v = rng.uniform(0.0, 0.35), 1.0
    elif style == "hazy":
        zen = _hsv(rng.uniform(0.55, 0.62), rng.uniform(0.2, 0.4), rng.uniform(0.78, 0.92))
        hor = _hsv(rng.uniform(0.1, 0.6), rng.uniform(0.03, 0.12), rng.uniform(0.85, 0.97))
        cover, cloud_v = rng.uniform(0.1, 0.5), 0.97
    elif style == "overcast":
        g = rng.uniform(0.6, 0.88)
        zen = np.full(3, g) * _hsv(0.6, 0.05, 1.0)
        hor = np.full(3, min(g + 0.08, 1.0))
        cover, cloud_v = rng.uniform(0.6, 1.0), rng.uniform(0.75, 0.95)
    else:
        zen = _hsv(rng.uniform(0.6, 0.7), rng.uniform(0.3, 0.6), rng.uniform(0.45, 0.7))
        hor = _hsv(rng.uniform(0.03, 0.12), rng.uniform(0.3, 0.6), rng.uniform(0.85, 1.0))
        cover, cloud_v = rng.uniform(0.1, 0.6), rng.uniform(0.7, 0.95)
    t = (np.linspace(0.0, 1.0, h) ** rng.uniform(0.6, 1.6))[:, None, None]  # 0 zenith .. 1 horizon
    img = zen * (1 - t) + hor * t
    img = np.broadcast_to(img, (h, w, 3)).copy()
    if cover > 0.02:
        n = _fbm(rng, max(h, 8), w, rng.uniform(1.5, 4.0), octaves=5, aspect=rng.uniform(0.3, 0.7))
        thr = np.quantile(n, 1.0 - cover)
        c = np.clip((n - thr) / rng.uniform(0.4, 1.2), 0.0, 1.0)[..., None]
        # thick parts bright, thin edges and the far (lower) clouds greyer
        shade = 0.82 + 0.18 * np.sqrt(c) - 0.08 * t[:h]
        cloud = np.clip(cloud_v * shade, 0, 1) * np.array([1.0, 1.0, 1.02])
        img = img * (1 - c) + cloud * c
    return img


def _ground(rng, h: int, w: int, kind: str) -> np.ndarray:
    """Ground of height ``h`` (horizon at row 0, near at the bottom): (h, w, 3) in [0, 1]."""
    if h <= 0:
        return np.zeros((0, w, 3))
    depth = np.linspace(0.02, 1.0, h)[:, None]  # 0 far .. 1 near
    if kind == "grass":
        base = _hsv(rng.uniform(0.18, 0.3), rng.uniform(0.35, 0.7), rng.uniform(0.3, 0.6))
    elif kind == "dry":
        base = _hsv(rng.uniform(0.1, 0.16), rng.uniform(0.3, 0.55), rng.uniform(0.45, 0.7))
    elif kind == "soil":
        base = _hsv(rng.uniform(0.05, 0.1), rng.uniform(0.25, 0.5), rng.uniform(0.3, 0.5))
    else:  # paving
        base = np.full(3, rng.uniform(0.4, 0.7)) * _hsv(rng.uniform(0, 1), 0.05, 1.0)
    # texture gets finer toward the horizon: blend a coarse (near) and a fine (far) noise
    coarse = _fbm(rng, h, w, 12.0, octaves=3)
    fine = _fbm(rng, h, w, 40.0, octaves=2)
    tex = (depth * coarse + (1 - depth) * fine)[..., None]
    patches = _fbm(rng, h, w, 2.0, octaves=2)[..., None]
    img = base * (1.0 + rng.uniform(0.08, 0.2) * tex + rng.uniform(0.05, 0.15) * patches)
    haze = np.clip(1.0 - depth * 4.0, 0.0, 1.0)[..., None] * rng.uniform(0.1, 0.4)
    return img * (1 - haze) + haze * np.array([0.75, 0.78, 0.82])


def _treeline(rng, img: np.ndarray, horizon: int, height: float) -> None:
    """Distant blurred vegetation: a bumpy silhouette band standing on the horizon (in place)."""
    import cv2

    h, w, _ = img.shape
    prof = _fbm(rng, 8, w, 1.0, octaves=4, aspect=rng.uniform(2.0, 6.0))[0]
    top = horizon - height * h * (0.55 + 0.35 * np.clip(prof, -1.5, 1.5) / 1.5)
    rows = np.arange(h)[:, None]
    band = (rows >= top[None, :]) & (rows <= horizon + 2)
    col = _hsv(rng.uniform(0.2, 0.38), rng.uniform(0.25, 0.6), rng.uniform(0.18, 0.42))
    leaf = _fbm(rng, h, w, 20.0, octaves=3)[..., None]
    veg = col * (1.0 + 0.25 * leaf)
    haze = rng.uniform(0.0, 0.45)
    veg = veg * (1 - haze) + haze * img[max(horizon - 1, 0)].mean(axis=0)  # aerial perspective: horizon colour
    a = cv2.GaussianBlur(band.astype(np.float32), (0, 0), 1.0 + 2.0 * rng.random())[..., None]
    img[:] = img * (1 - a) + veg * a


def _buildings(rng, img: np.ndarray, horizon: int) -> None:
    """Blocks with window grids along the horizon (in place)."""
    h, w, _ = img.shape
    x = int(rng.integers(-w // 8, w // 8))
    while x < w:
        bw = int(rng.integers(max(w // 10, 4), max(w // 3, 6)))
        bh = int(rng.uniform(0.12, 0.55) * h)
        top = max(horizon - bh, 0)
        x0, x1 = max(x, 0), min(x + bw, w)
        if x1 > x0 and horizon > top:
            facade = _hsv(rng.uniform(0.0, 0.15) if rng.random() < 0.6 else rng.uniform(0, 1),
                          rng.uniform(0.0, 0.35), rng.uniform(0.35, 0.9))
            block = np.broadcast_to(facade, (horizon - top, x1 - x0, 3)).copy()
            block *= 1.0 - 0.12 * np.linspace(0, 1, x1 - x0)[None, :, None] * rng.random()
            step_x, step_y = int(rng.integers(5, 12)), int(rng.integers(6, 14))
            glass = _hsv(rng.uniform(0.5, 0.65), rng.uniform(0.1, 0.4), rng.uniform(0.15, 0.55))
            ww, wh = max(step_x // 2, 2), max(step_y // 2, 2)
            for yy in range(int(rng.integers(2, 6)), block.shape[0] - wh, step_y):
                for xx in range(int(rng.integers(1, 4)), block.shape[1] - ww, step_x):
                    block[yy:yy + wh, xx:xx + ww] = glass
            img[top:horizon, x0:x1] = block
        x += bw + int(rng.integers(0, max(w // 12, 2)))


def _road(rng, img: np.ndarray, horizon: int) -> None:
    """A road in perspective toward a vanishing point on the horizon, with lane marks (in place)."""
    import cv2

    h, w, _ = img.shape
    if horizon >= h - 2:
        return
    vx = rng.uniform(0.2, 0.8) * w
    spread = rng.uniform(0.6, 1.6) * w
    cx = rng.uniform(0.2, 0.8) * w
    pts = np.array([[vx - 1, horizon], [vx + 1, horizon], [cx + spread / 2, h], [cx - spread / 2, h]], np.int32)
    grey = np.full(3, rng.uniform(0.25, 0.45))
    cv2.fillPoly(img, [pts], tuple(float(c) for c in grey))
    walk = np.array([[vx + 1, horizon], [vx + 3, horizon], [cx + spread / 2 + spread * 0.25, h], [cx + spread / 2, h]],
                    np.int32)
    cv2.fillPoly(img, [walk], tuple(float(c) for c in np.full(3, rng.uniform(0.55, 0.75))))
    mark = (0.9, 0.9, 0.85) if rng.random() < 0.7 else (0.85, 0.75, 0.3)
    n = 12
    for k in range(0, n, 2):  # dashes, longer near the camera
        t0, t1 = (k / n) ** 2, ((k + 1) / n) ** 2
        p0 = (int(vx + (cx - vx) * t0), int(horizon + (h - horizon) * t0))
        p1 = (int(vx + (cx - vx) * t1), int(horizon + (h - horizon) * t1))
        cv2.line(img, p0, p1, mark, max(1, int(1 + 3 * t1)))


def procedural_background(size, *, seed=0, kind: str | None = None) -> np.ndarray:
    """A photo-like outdoor background painted from scratch.

    Parameters
    ----------
    size : int or (int, int)
        Edge in pixels, or (height, width); >= 16.
    seed : int or numpy.random.Generator
    kind : str, optional
        One of :data:`BACKGROUND_KINDS`; random when None.

    Returns
    -------
    ndarray, shape (H, W, 3), uint8

    Examples
    --------
    >>> img = procedural_background(64, seed=1, kind="street")
    >>> img.shape, img.dtype
    ((64, 64, 3), dtype('uint8'))
    >>> bool((procedural_background(64, seed=1) == procedural_background(64, seed=1)).all())
    True
    """
    import cv2

    from treeform._shared.rng import as_rng

    h, w = (size, size) if np.isscalar(size) else tuple(size)
    if min(int(h), int(w)) < 16:
        raise InputError(f"size: expected at least 16 pixels, got {size!r}")
    h, w = int(h), int(w)
    rng = as_rng(seed)
    if kind is None:
        kind = str(rng.choice(BACKGROUND_KINDS, p=[0.3, 0.15, 0.15, 0.1, 0.15, 0.15]))
    elif kind not in BACKGROUND_KINDS:
        raise InputError(f"kind: expected one of {', '.join(BACKGROUND_KINDS)}, got {kind!r}")
    lo, hi = {"sky": (0.85, 1.1), "forest": (0.5, 0.85)}.get(kind, (0.45, 0.8))
    horizon = int(np.clip(rng.uniform(lo, hi) * h, 2, h))
    img = np.empty((h, w, 3))
    img[:horizon] = _sky(rng, horizon, w)
    ground = {"park": "grass", "field": str(rng.choice(["grass", "dry", "soil"])), "street": "paving",
              "city": "paving", "forest": "grass", "sky": "grass"}[kind]
    img[horizon:] = _ground(rng, h - horizon, w, ground)
    if kind in ("park", "field", "forest") or (kind == "street" and rng.random() < 0.5):
        _treeline(rng, img, horizon, {"forest": rng.uniform(0.45, 0.8)}.get(kind, rng.uniform(0.05, 0.3)))
    if kind in ("street", "city"):
        _buildings(rng, img, horizon)
        if kind == "street" or rng.random() < 0.5:
            _road(rng, img, horizon)
        if rng.random() < 0.5:
            _treeline(rng, img, horizon, rng.uniform(0.03, 0.12))
    # camera: depth-of-field blur, colour cast, exposure
    sigma = rng.choice([0.0, rng.uniform(0.5, 1.5), rng.uniform(1.5, 4.0)], p=[0.3, 0.4, 0.3]) * w / 256
    if sigma > 0.3:
        img = cv2.GaussianBlur(img, (0, 0), sigma)
    img = img * rng.uniform(0.92, 1.08, 3) * rng.uniform(0.75, 1.15)
    return np.clip(np.rint(img * 255.0), 0, 255).astype(np.uint8)


class BackgroundPool:
    """Backgrounds for synthetic samples: procedural scenes, optionally mixed with photos.

    Parameters
    ----------
    folder : path, optional
        A directory of the user's own photos (JPEG, PNG, WebP, BMP, TIFF; searched
        recursively). Each use takes a random crop (half to all of the shorter side) scaled
        to the sample size.
    photo_fraction : float in [0, 1]
        Share of samples that use a photo when ``folder`` is given.

    Raises
    ------
    InputError
        ``folder`` does not exist or holds no images.
    """

    def __init__(self, folder=None, *, photo_fraction: float = 0.5):
        self.folder = None if folder is None else Path(folder)
        self.photos: list[Path] = []
        if not 0.0 <= float(photo_fraction) <= 1.0:
            raise InputError(f"photo_fraction: expected a number in [0, 1], got {photo_fraction!r}")
        self.photo_fraction = float(photo_fraction)
        if self.folder is not None:
            if not self.folder.is_dir():
                raise InputError(f"backgrounds {self.folder}: not a directory")
            self.photos = sorted(p for p in self.folder.rglob("*") if p.suffix.lower() in PHOTO_SUFFIXES)
            if not self.photos:
                raise InputError(f"backgrounds {self.folder}: no images ({', '.join(PHOTO_SUFFIXES)})")

    def sample(self, size: int, rng: np.random.Generator) -> tuple[np.ndarray, str]:
        """A (size, size, 3) uint8 background and a description ("procedural:<kind>" or the photo's name)."""
        if self.photos and rng.random() < self.photo_fraction:
            path = self.photos[int(rng.integers(len(self.photos)))]
            return self._crop(path, size, rng), f"photo:{path.name}"
        kind = str(rng.choice(BACKGROUND_KINDS, p=[0.3, 0.15, 0.15, 0.1, 0.15, 0.15]))
        return procedural_background(size, seed=rng, kind=kind), f"procedural:{kind}"

    @staticmethod
    def _crop(path: Path, size: int, rng) -> np.ndarray:
        from treeform.io.images import pil_image

        Image = pil_image()

        try:
            with Image.open(path) as im:
                im = im.convert("RGB")
                w, h = im.size
                side = int(min(w, h) * rng.uniform(0.5, 1.0))
                x, y = int(rng.integers(0, w - side + 1)), int(rng.integers(0, h - side + 1))
                im = im.resize((size, size), Image.BILINEAR, box=(x, y, x + side, y + side))
                return np.asarray(im, np.uint8).copy()
        except (OSError, ValueError) as exc:
            raise InputError(f"background {path}: not a readable image ({exc})") from None

    def to_dict(self) -> dict:
        return {"folder": None if self.folder is None else str(self.folder), "photos": len(self.photos),
                "photo_fraction": self.photo_fraction}
