"""Load-time augmentation of synthetic samples (seed 003 §4.2.2).

"We then apply image transformations to the input image, including color, brightness, and
contrast changes. Additionally, we apply a random amount of Gaussian blur, randomly apply a
horizontal flip, and crop the image with a randomly sized bounding box with a minimum size
of 256 × 256 pixels." :class:`Augment` does exactly these, keeping the mask and the RBV
consistent with the image (a flip mirrors the RBV's sectors).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

from treeform._shared.checks import check_int
from treeform._shared.errors import InputError

__all__ = ["Augment", "mirror_rbv"]


def mirror_rbv(radii: np.ndarray) -> np.ndarray:
    """The RBV radii (layers, sectors) of the tree mirrored left-right in the canonical view.

    Sector ``j`` spans angles ``[j, j + 1) · 2π / n`` from the camera's right (+X) toward
    +Z; the mirror ``x -> -x`` maps angle θ to π − θ, i.e. sector ``j`` to ``n/2 − 1 − j``
    (mod n). One sector (level 1) is unchanged.

    Examples
    --------
    >>> mirror_rbv(np.array([[0., 1., 2., 3.]])).tolist()
    [[1.0, 0.0, 3.0, 2.0]]
    """
    r = np.asarray(radii)
    n = r.shape[-1]
    if n == 1:
        return r.copy()
    src = (n // 2 - 1 - np.arange(n)) % n
    return r[..., src]


@dataclass(frozen=True)
class Augment:
    """Random photometric and geometric changes applied to (image, mask, rbv) at load time.

    Parameters
    ----------
    brightness : float
        Multiply the image by a factor in ``[1 - brightness, 1 + brightness]``.
    contrast : float
        Scale deviations from the mean grey by ``[1 - contrast, 1 + contrast]``.
    saturation : float
        Scale chroma by ``[1 - saturation, 1 + saturation]`` (the paper's "colour" change).
    hue : float
        Rotate hue by up to ± ``hue`` turns (0.05 = 18°).
    flip : float
        Probability of a horizontal flip (mirrors the mask and the RBV sectors).
    crop_min : int
        Smallest crop edge in pixels (paper: 256); a square crop of random size in
        ``[min(crop_min, S), S]`` at a random position, resized back to ``out_size``.
    blur : float
        Largest Gaussian blur σ in pixels (σ drawn uniformly in [0, blur] with probability
        ``blur_p``).
    blur_p : float
    out_size : int or None
        Output edge (None: the input's).

    Examples
    --------
    >>> aug = Augment(crop_min=48)
    >>> img = np.full((64, 64, 3), 128, np.uint8); mask = np.zeros((64, 64), np.uint8)
    >>> out = aug(img, mask, [np.ones((1, 1)), np.ones((2, 2))], rng=np.random.default_rng(0))
    >>> out["image"].shape, out["mask"].shape
    ((64, 64, 3), (64, 64))
    """

    brightness: float = 0.25
    contrast: float = 0.25
    saturation: float = 0.25
    hue: float = 0.04
    flip: float = 0.5
    crop_min: int = 256
    blur: float = 1.5
    blur_p: float = 0.5
    out_size: int | None = None

    def __post_init__(self):
        for name in ("brightness", "contrast", "saturation"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and 0.0 <= v < 1.0):
                raise InputError(f"Augment.{name}: expected a number in [0, 1), got {v!r}")
        for name, hi in (("hue", 0.5), ("flip", 1.0), ("blur_p", 1.0)):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and 0.0 <= v <= hi):
                raise InputError(f"Augment.{name}: expected a number in [0, {hi}], got {v!r}")
        if not (isinstance(self.blur, (int, float)) and 0.0 <= self.blur <= 20.0):
            raise InputError(f"Augment.blur: expected a sigma in [0, 20] pixels, got {self.blur!r}")
        check_int(self.crop_min, "Augment.crop_min", 8, 2**16)
        if self.out_size is not None:
            check_int(self.out_size, "Augment.out_size", 8, 2**16)

    def to_dict(self) -> dict:
        return asdict(self)

    def __call__(self, image, mask, rbv=None, *, rng) -> dict:
        """Augment one sample.

        Parameters
        ----------
        image : ndarray, shape (S, S, 3), uint8
        mask : ndarray, shape (S, S), uint8
        rbv : list of ndarrays (layers, sectors), optional
        rng : numpy.random.Generator
            Same generator state -> same augmentation.

        Returns
        -------
        dict
            ``image`` (T, T, 3) uint8, ``mask`` (T, T) uint8 (nearest), ``rbv`` (list), ``flipped`` (bool)
            with T = ``out_size`` or S.
        """
        import cv2

        img = np.asarray(image)
        m = np.asarray(mask)
        if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
            raise InputError(f"image: expected an (H, W, 3) uint8 array, got {img.shape} {img.dtype}")
        if m.shape != img.shape[:2]:
            raise InputError(f"mask: expected shape {img.shape[:2]}, got {m.shape}")
        h, w = m.shape
        out = self.out_size or min(h, w)
        # geometry: crop, resize, flip
        side_hi = min(h, w)
        side = int(rng.integers(min(self.crop_min, side_hi), side_hi + 1))
        y0, x0 = int(rng.integers(0, h - side + 1)), int(rng.integers(0, w - side + 1))
        img = img[y0:y0 + side, x0:x0 + side]
        m = m[y0:y0 + side, x0:x0 + side]
        if side != out:
            img = cv2.resize(img, (out, out), interpolation=cv2.INTER_AREA if side > out else cv2.INTER_LINEAR)
            m = cv2.resize(m, (out, out), interpolation=cv2.INTER_NEAREST)
        flipped = bool(rng.random() < self.flip)
        if flipped:
            img, m = img[:, ::-1], m[:, ::-1]
        # photometry: brightness, contrast, saturation, hue, blur
        x = img.astype(np.float32) / 255.0
        x *= rng.uniform(1 - self.brightness, 1 + self.brightness)
        grey = float(x.mean())
        x = (x - grey) * rng.uniform(1 - self.contrast, 1 + self.contrast) + grey
        if self.hue > 0 or self.saturation > 0:
            x = _hue_saturation(np.clip(x, 0, 1), rng.uniform(-self.hue, self.hue),
                                rng.uniform(1 - self.saturation, 1 + self.saturation))
        if self.blur > 0 and rng.random() < self.blur_p:
            sigma = rng.uniform(0.0, self.blur)
            if sigma > 0.05:
                x = cv2.GaussianBlur(x, (0, 0), sigma)
        img = np.clip(np.rint(x * 255.0), 0, 255).astype(np.uint8)
        rbv_out = None if rbv is None else [mirror_rbv(r) if flipped else np.array(r) for r in rbv]
        return {"image": np.ascontiguousarray(img), "mask": np.ascontiguousarray(m), "rbv": rbv_out,
                "flipped": flipped}


def _hue_saturation(x: np.ndarray, turn: float, sat: float) -> np.ndarray:
    """Rotate chroma by ``turn`` turns about the grey axis and scale it by ``sat`` (YIQ space)."""
    to_yiq = np.array([[0.299, 0.587, 0.114], [0.596, -0.274, -0.322], [0.211, -0.523, 0.312]], np.float32)
    a = 2 * np.pi * turn
    c, s = np.cos(a) * sat, np.sin(a) * sat
    rot = np.array([[1, 0, 0], [0, c, -s], [0, s, c]], np.float32)
    m = np.linalg.inv(to_yiq) @ rot @ to_yiq
    return x @ m.T.astype(np.float32)
