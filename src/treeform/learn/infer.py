"""Inference of the shipped perception networks with onnxruntime (no torch).

The weights are ONNX graphs inside the package (``treeform/learn/weights/*.onnx``), built by
``make weights``. A missing or unreadable file raises :class:`ModelError` naming the file
and the command that rebuilds it.
"""

from __future__ import annotations

import functools
import os
from pathlib import Path

import numpy as np

from treeform._shared.errors import InputError, ModelError

__all__ = ["WEIGHTS", "weights_path", "Segmenter", "FeetDetector", "load_session", "main_tree", "focus_map",
           "network_scale", "predict_species", "predict_rbv"]

WEIGHTS = {"seg": "seg.onnx", "species": "species.onnx", "rbv": "rbv.onnx", "feet": "feet.onnx"}
"""File name of each network's shipped weights."""


def weights_path(kind: str) -> Path:
    """Path of the shipped weights of network ``kind`` ('seg', 'species', 'rbv', 'feet')."""
    if kind not in WEIGHTS:
        raise InputError(f"network: expected one of {', '.join(WEIGHTS)}, got {kind!r}")
    return Path(__file__).resolve().parent / "weights" / WEIGHTS[kind]


@functools.lru_cache(maxsize=8)
def _cached_session(path: str, mtime: float):
    try:
        import onnxruntime as ort
    except ImportError:
        raise ModelError("the networks need onnxruntime: pip install onnxruntime") from None
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = max(1, min(4, os.cpu_count() or 1))
    opts.inter_op_num_threads = 1
    opts.log_severity_level = 3
    # the pool's threads sleep between runs instead of spinning: a network runs beside other
    # work (the colour rules, the writers), whose cores a spinning pool would take
    opts.add_session_config_entry("session.intra_op.allow_spinning", "0")
    try:
        sess = ort.InferenceSession(path, sess_options=opts, providers=["CPUExecutionProvider"])
    except Exception as exc:  # onnxruntime raises its own Fail/InvalidProtobuf types
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ModelError(f"{path}: not a readable ONNX model ({first[:120]}); rebuild the weights with `make weights`") from None
    meta = dict(sess.get_modelmeta().custom_metadata_map)
    return sess, meta


def load_session(path) -> tuple:
    """(onnxruntime session, metadata dict) for an ONNX file; cached while the file is unchanged."""
    p = Path(path)
    if not p.is_file():
        raise ModelError(f"{p}: network weights missing; build them with `make weights`")
    return _cached_session(str(p.resolve()), p.stat().st_mtime)


FOCUS_SIGMA = 2.0
"""Gaussian window (px at the network's size) of the local contrast that :func:`focus_map` divides by."""
FOCUS_FLOOR = 4.0
"""Grey levels added to that contrast, so flat sky and noise do not read as sharp."""


def _components(mask: np.ndarray):
    import cv2

    n, lab, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    return n, lab, stats


def focus_map(image: np.ndarray, side: int = 320, *, relative: bool = True) -> np.ndarray:
    """(H, W) float32 local sharpness of an RGB image: |Laplacian| over local contrast, at ``side`` px.

    A photographed tree is in focus; trees behind it are often not. Measured at the
    network's working size so that JPEG noise and the photo's resolution matter little.
    The |Laplacian| of the grey is divided by the grey's local standard deviation (Gaussian
    window of :data:`FOCUS_SIGMA` px, plus :data:`FOCUS_FLOOR` grey levels): blur takes the
    fine scale's energy away faster than the coarse scale's, while a dark crown against the
    light is low in both. With the bare |Laplacian|, a backlit crown (grey about 16 of 255)
    scored a quarter of a sunlit clump beside it, and the clump was taken for the tree (one
    view of the 24-view oak capture: tree IoU 0.08 -> 0.72). ``relative=False`` gives the bare
    |Laplacian| (contrast times sharpness), which :func:`~treeform.segment.classical.trunk_in_mask`
    compares a trunk the mask missed with its crown by: a dark bin or hedge foot beside the trunk is
    as sharp as the crown but far less contrasted (0.42 of the crown against 0.53 relative, where a
    second pine's trunk scores 0.80 and 0.59).

    >>> rng = np.random.default_rng(0)
    >>> leaves = rng.integers(0, 255, (64, 64, 3)).astype(np.uint8)
    >>> f_bright = focus_map(leaves, side=64)
    >>> f_dark = focus_map(leaves // 8, side=64)          # the same texture, backlit
    >>> import cv2; f_blur = focus_map(cv2.GaussianBlur(leaves, (0, 0), 2.0), side=64)
    >>> bool(np.median(f_dark) > 0.5 * np.median(f_bright) > np.median(f_blur))
    True
    """
    import cv2

    img = np.asarray(image)
    H, W = img.shape[:2]
    s = min(1.0, network_scale((H, W), side))
    g = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY).astype(np.float32)
    if s < 1.0:
        g = cv2.resize(g, (max(8, round(W * s)), max(8, round(H * s))), interpolation=cv2.INTER_AREA)
    f = np.abs(cv2.Laplacian(g, cv2.CV_32F, ksize=1))
    if relative:
        mean = cv2.GaussianBlur(g, (0, 0), FOCUS_SIGMA)
        var = cv2.GaussianBlur(g * g, (0, 0), FOCUS_SIGMA) - mean * mean
        f /= np.sqrt(np.maximum(var, 0.0)) + FOCUS_FLOOR
    return cv2.resize(f, (W, H), interpolation=cv2.INTER_LINEAR) if s < 1.0 else f


def main_tree(tree: np.ndarray, *, min_fraction: float = 0.002, focus: np.ndarray | None = None,
              link: float = 0.0) -> np.ndarray:
    """The main tree of a binary tree mask: its largest connected part plus the parts beside it.

    A crown seen through sky gaps falls apart into pieces. With ``link`` > 0, pieces closer
    than ``link`` x the long side to each other count as one part (the mask dilated by that
    distance decides which pieces belong together; the pixels kept are the mask's own). Then
    parts that overlap the main part's bounding box (grown by 10 %) and hold at least 1 % of
    its area are kept too. Parts smaller than ``min_fraction`` of the image are dropped as
    noise.

    With ``focus`` (an (H, W) sharpness map, :func:`focus_map`) the main part is the one
    with the largest area x (median sharpness)^2 instead of the largest area: an
    out-of-focus tree behind the photographed one loses to it unless it is much larger.

    >>> m = np.zeros((20, 20), bool); m[2:15, 2:6] = True; m[5:8, 17:19] = True
    >>> int(main_tree(m).sum())
    52
    >>> m[2:15, 8:11] = True   # a second piece 2 px beside the first: one part when linked
    >>> int(main_tree(m, min_fraction=0.05).sum()), int(main_tree(m, min_fraction=0.05, link=0.1).sum())
    (52, 91)
    """
    tree = np.asarray(tree, bool)
    r = int(round(float(link) * max(tree.shape)))
    if r >= 1:
        import cv2

        near = cv2.dilate(tree.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1,) * 2))
        n, lab, _ = _components(near)
        lab = np.where(tree, lab, 0)
    else:
        n, lab, _ = _components(tree)
    if n <= 1:
        return np.zeros_like(tree)
    import scipy.ndimage as ndi

    areas = np.bincount(lab.ravel(), minlength=n)[1:].astype(np.float64)
    # each part's bounding box (of its own pixels): [y0, y1) x [x0, x1), index = label
    boxes = np.array([(0, 0, 0, 0)] + [(b[0].start, b[0].stop, b[1].start, b[1].stop)
                                       for b in ndi.find_objects(lab, max_label=n - 1)])
    y0, y1, x0, x1 = boxes.T
    score = areas
    cand = np.flatnonzero(areas >= min_fraction * tree.size)
    if focus is not None and len(cand) > 1:
        focus = np.asarray(focus, np.float32)
        score = np.zeros_like(areas)
        for k in cand:  # the few parts large enough to be the tree
            score[k] = areas[k] * float(np.median(focus[lab == k + 1])) ** 2
    big = int(np.argmax(score)) + 1
    x, y, w, h, a = x0[big], y0[big], x1[big] - x0[big], y1[big] - y0[big], areas[big - 1]
    gx, gy = 0.1 * w, 0.1 * h
    keep = np.zeros(n, bool)
    keep[big] = True
    for k in range(1, n):
        ka = areas[k - 1]
        if ka < max(0.01 * a, min_fraction * tree.size):
            continue
        if x0[k] < x + w + gx and x1[k] > x - gx and y0[k] < y + h + gy and y1[k] > y - gy:
            keep[k] = True
    return keep[lab]


def network_scale(shape, side: int) -> float:
    """The scale at which an image network sees an (H, W) photo: its long side at ``side`` px,
    but its short side never under ``side / 2``.

    The networks were trained on square scenes and see a photo of up to 2:1 with its long side at
    ``side``. A wider panorama scaled that way would shrink the tree with it (at 6:1 the sample's
    tree is 53 px tall, and no tree is found); past 2:1 the photo is seen as a 2:1 photo of the
    same height would be, the long side growing instead (the network is convolutional).

    >>> network_scale((600, 450), 320), network_scale((400, 1200), 320)  # 4:3, then a 3:1 panorama
    (0.5333333333333333, 0.4)
    """
    H, W = (int(v) for v in shape[:2])
    return max(side / max(H, W), 0.5 * side / min(H, W))


def network_input(image, side: int, multiple: int, border: int) -> tuple:
    """An RGB photo as an image network's input at :func:`network_scale` (long side ``side`` up to
    2:1), padded to a multiple.

    Parameters
    ----------
    image : ndarray, shape (H, W, 3), uint8
    side : int
        Long side of the scaled photo in pixels (of a photo of up to 2:1; see :func:`network_scale`).
    multiple : int
        The network's stride: the scaled photo is padded (bottom, right) to a multiple of it.
    border : int
        OpenCV border mode of the padding.

    Returns
    -------
    x : ndarray, shape (1, 3, h', w'), float32 in [0, 1]
    (h, w) : the scaled photo's size inside ``x``
    (H, W) : the photo's size

    Raises
    ------
    InputError
        ``image`` is not an (H, W, 3) uint8 array.
    """
    import cv2

    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
        raise InputError(f"image: expected an (H, W, 3) uint8 RGB array, got {img.shape} {img.dtype}")
    H, W = img.shape[:2]
    s = network_scale((H, W), side)
    h, w = max(multiple, int(round(H * s))), max(multiple, int(round(W * s)))
    small = cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA if s < 1 else cv2.INTER_LINEAR)
    ph, pw = (-h) % multiple, (-w) % multiple
    if ph or pw:
        small = cv2.copyMakeBorder(small, 0, ph, 0, pw, border)
    return small.astype(np.float32).transpose(2, 0, 1)[None] / 255.0, (h, w), (H, W)


class Segmenter:
    """The learned segmenter (background / foliage / wood) on onnxruntime.

    Parameters
    ----------
    path : path, optional
        ONNX weights; default the shipped ``seg.onnx``.
    side : int, optional
        Long side, in pixels, at which the network sees the photo (default: the model's
        ``infer_side`` metadata, else 320).
    """

    def __init__(self, path=None, *, side: int | None = None):
        self.path = Path(path) if path is not None else weights_path("seg")
        self.session, self.meta = load_session(self.path)
        self.side = int(side or self.meta.get("infer_side", 320))

    def probabilities(self, image: np.ndarray) -> np.ndarray:
        """(H, W, 3) float32 class probabilities of an (H, W, 3) uint8 RGB image, at its size."""
        import cv2

        x, (h, w), (H, W) = network_input(image, self.side, 8, cv2.BORDER_REFLECT_101)
        logits = self.session.run(None, {"image": x})[0][0, :, :h, :w]
        z = logits - logits.max(0, keepdims=True)
        p = np.exp(z)
        p /= p.sum(0, keepdims=True)
        p = np.ascontiguousarray(p.transpose(1, 2, 0))
        return cv2.resize(p, (W, H), interpolation=cv2.INTER_LINEAR) if (h, w) != (H, W) else p

    def predict_labels(self, image: np.ndarray, *, keep_main: bool = True) -> np.ndarray:
        """(H, W) uint8 labels 0 background / 1 foliage / 2 wood; only the main tree when ``keep_main``."""
        p = self.probabilities(image)
        tree = p[..., 0] < 0.5
        if keep_main:
            tree = main_tree(tree)
        lab = np.where(p[..., 2] > p[..., 1], 2, 1).astype(np.uint8)
        return np.where(tree, lab, 0).astype(np.uint8)


class FeetDetector:
    """The trunk-foot detector (:class:`~treeform.learn.nets.feetnet.FeetNet`) on onnxruntime.

    The photo is seen with its long side at ``side`` pixels (padded to a multiple of 16);
    the heatmap's peaks (:func:`~treeform.learn.feet.heatmap_peaks`) are the feet.

    Parameters
    ----------
    path : path, optional
        ONNX weights; default the shipped ``feet.onnx``.
    side : int, optional
        Long side at which the network sees the photo (default: the model's ``infer_side``, else 384).
    """

    def __init__(self, path=None, *, side: int | None = None):
        self.path = Path(path) if path is not None else weights_path("feet")
        self.session, self.meta = load_session(self.path)
        if self.meta.get("treeform_kind", "feet") != "feet":
            raise ModelError(f"{self.path}: holds a {self.meta['treeform_kind']!r} network, not the foot detector; "
                             "rebuild the weights with `make weights`")
        self.side = int(side or self.meta.get("infer_side", 384))

    def heatmap(self, image: np.ndarray) -> tuple[np.ndarray, np.ndarray, tuple]:
        """Foot probabilities (h, w) and offsets (2, h, w) at stride 4 of the scaled photo, and its scale (sx, sy).

        A cell (i, j) with offset (ox, oy) is the scaled photo's pixel ((j + ox) * 4, (i + oy) * 4).
        """
        import cv2

        from treeform.learn.feet import STRIDE

        x, (h, w), (H, W) = network_input(image, self.side, 16, cv2.BORDER_REPLICATE)
        out = self.session.run(None, {"image": x})[0][0].astype(np.float64)
        hh, ww = -(-h // STRIDE), -(-w // STRIDE)
        prob = 1.0 / (1.0 + np.exp(-out[0, :hh, :ww]))
        offset = 1.0 / (1.0 + np.exp(-out[1:3, :hh, :ww]))
        return prob, offset, (w / W, h / H)

    def detect(self, image: np.ndarray, *, threshold: float = 0.3, min_distance: float = 2.0) -> np.ndarray:
        """Feet of an (H, W, 3) uint8 RGB photo: (N, 3) rows (u, v, score) in its pixels, strongest first."""
        from treeform.learn.feet import heatmap_peaks

        prob, offset, scale = self.heatmap(image)
        peaks = heatmap_peaks(prob, offset, threshold=threshold, min_distance=min_distance)
        peaks[:, :2] = (peaks[:, :2] + 0.5) / np.asarray(scale) - 0.5  # the scaled photo's pixel centres back to the photo's
        return peaks


def _mask_run(kind: str, labels: np.ndarray, weights=None) -> np.ndarray:
    from treeform.learn.masks import mask_input

    sess, _ = load_session(weights if weights is not None else weights_path(kind))
    x = mask_input(labels)[None]
    return sess.run(None, {"mask": x})[0][0]


def predict_species(labels: np.ndarray, *, weights=None) -> dict:
    """Species probabilities ``{name: p}`` (best first) of a 0/1/2 label image (seed 003 §4.2.4)."""
    from treeform.growth.species import SPECIES

    z = _mask_run("species", labels, weights).astype(np.float64)
    p = np.exp(z - z.max())
    p /= p.sum()
    order = np.argsort(-p, kind="stable")
    return {SPECIES[i]: float(p[i]) for i in order}


def predict_rbv(labels: np.ndarray, *, weights=None) -> list:
    """RBV levels 1..5 (height-normalised radii, (1, 1) .. (16, 16)) of a 0/1/2 label image (seed 003 §4.2.3)."""
    flat = _mask_run("rbv", labels, weights)
    out, i = [], 0
    for s in (1, 2, 4, 8, 16):
        out.append(np.clip(flat[i:i + s * s].reshape(s, s).astype(np.float64), 0.0, None))
        i += s * s
    return out
