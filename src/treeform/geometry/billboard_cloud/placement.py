"""Stage 4 of the billboard cloud: front, rear, interior and trunk billboards placed in depth (seed 000 §6, Fig. 11)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.ndimage as ndi

from treeform._shared.checks import check_array, check_positive
from treeform._shared.errors import InputError
from treeform._shared.rng import as_rng
from treeform.geometry.billboard_cloud._common import FRONT, INTERIOR, REAR, TRUNK


@dataclass
class Placement:
    """Where each billboard goes, in image pixels (seed 000 §6).

    Attributes
    ----------
    sprite : ndarray, shape (m,), int64
        Index of the billboard's crop (row of the atlas ``rects`` / ``boxes``).
    layer : ndarray, shape (m,), int8
        :data:`FRONT`, :data:`REAR`, :data:`INTERIOR` or :data:`TRUNK`.
    x, y : ndarray, shape (m,), float64
        Image-plane centre of the billboard (pixels; a front billboard's own box centre).
    z : ndarray, shape (m,), float64
        Depth of the centre toward the viewer (pixels; 0 = the picture plane).
    yaw : ndarray, shape (m,), float64
        Rotation about the vertical axis (radians); the depth across the billboard is
        ``z + (x' - x) tan(yaw)`` at image column ``x'``.
    shade : ndarray, shape (m,), float64
        Colour factor (1 = the picture's colour; interior billboards are darker).
    """

    sprite: np.ndarray
    layer: np.ndarray
    x: np.ndarray
    y: np.ndarray
    z: np.ndarray
    yaw: np.ndarray
    shade: np.ndarray

    def __len__(self) -> int:
        return len(self.sprite)

    def counts(self) -> dict:
        """Billboards per layer, e.g. ``{"front": 240, "rear": 231, ...}``."""
        names = ("front", "rear", "interior", "trunk")
        return {name: int((self.layer == k).sum()) for k, name in enumerate(names)}


@dataclass
class _Footprints:
    """Opaque pixels of each crop and the tree's coverage, for leak and depth tests."""

    boxes: np.ndarray
    masks: list
    tree: np.ndarray
    zbuf: np.ndarray = field(init=False)

    def __post_init__(self):
        self.zbuf = np.full(self.tree.shape, -np.inf)

    def window(self, s: int, ox: int, oy: int):
        """(mask part inside the image, image slices) of crop ``s`` with its top-left at (ox, oy)."""
        w, h = self.boxes[s, 2], self.boxes[s, 3]
        hh, ww = self.tree.shape
        xa, ya, xb, yb = max(ox, 0), max(oy, 0), min(ox + w, ww), min(oy + h, hh)
        if xa >= xb or ya >= yb:
            return None, None
        return self.masks[s][ya - oy:yb - oy, xa - ox:xb - ox], (slice(ya, yb), slice(xa, xb))

    def leak(self, s: int, ox: int, oy: int) -> float:
        """Fraction of crop ``s``'s opaque pixels falling outside the tree (or the image)."""
        m, win = self.window(s, ox, oy)
        total = self.masks[s].sum()
        inside = 0 if m is None else int((m & self.tree[win]).sum())
        return 1.0 - inside / max(total, 1)

    def paint(self, s: int, ox: int, oy: int, xc: float, z: float, yaw: float) -> None:
        """Record crop ``s`` (a front billboard) in the front depth buffer."""
        m, win = self.window(s, ox, oy)
        if m is None:
            return
        depth = z + _tilt(win, xc, yaw)[None, :]
        self.zbuf[win] = np.where(m, np.maximum(self.zbuf[win], depth), self.zbuf[win])

    def deepest(self, s: int, ox: int, oy: int, xc: float, yaw: float, gap: float) -> float:
        """Largest centre depth that keeps crop ``s`` ``gap`` behind the front layer at all its pixels."""
        m, win = self.window(s, ox, oy)
        if m is None:
            return np.inf
        front = self.zbuf[win]
        sel = m & np.isfinite(front)
        if not sel.any():
            return np.inf
        offs = np.broadcast_to(_tilt(win, xc, yaw)[None, :], m.shape)
        return float((front[sel] - offs[sel]).min() - gap)


def _tilt(win, xc: float, yaw: float) -> np.ndarray:
    """Depth offset, relative to the centre, of a billboard turned by ``yaw`` at the window's columns."""
    cols = np.arange(win[1].start, win[1].stop) + 0.5
    return (cols - xc) * math.tan(yaw)


def place_billboards(boxes, masks, luminance, height, tree, *, crown=None, trunk: int | None = None,
                     push: float = 0.5, interior: float = 0.5, darken: float = 0.5, yaw=(20.0, 50.0),
                     max_leak: float = 0.02, seed=0) -> Placement:
    """Populate the crown with billboards (seed 000 §6).

    * **Front layer** — every region at its own image position; depth = the envelope's
      height ``height`` at the region's centroid, minus ``push`` times the largest height
      scaled by how much darker than the mean luminance the region is (dark regions are
      read as occluded and sent into the crown, leaving cavities to see deeper layers).
    * **Rear layer** — every region again, its position mirrored within its row's crown
      span (textures are not mirrored), at the mirrored depth; moved toward the row's
      centre in quarter-widths until at most ``max_leak`` of its pixels fall outside the
      tree (else dropped).
    * **Interior** — ``interior`` × n extra billboards at blue-noise positions inside the
      crown volume ``|z| < height(x, y)``, each a random region that fits inside the tree
      (4 tries), darkened by ``1 - darken·(1 - |z| / height)``.
    * **Trunk** — crop ``trunk`` at its image position, depth 0, turned 45°.

    Every billboard gets a random yaw of ``±U(yaw)`` degrees; rear and interior ones are
    kept at least a pixel behind the front layer (and the trunk) at each of their pixels,
    so the front view is the picture.

    Parameters
    ----------
    boxes : ndarray, shape (n, 4), int
        ``(x0, y0, w, h)`` crop boxes (regions, then the trunk crop if any).
    masks : sequence of ndarray, each shape (h_i, w_i), bool
        Opaque pixels of each crop.
    luminance : ndarray, shape (n,)
        Mean luminance of each crop (:func:`luminance`).
    height : ndarray, shape (H, W), float
        Front height of the crown envelope in pixels (0 outside;
        :func:`treeform.crown.inflate_envelope`'s ``front_z``).
    tree : ndarray, shape (H, W), bool
        The picture's opaque pixels (crown and trunk).
    crown : ndarray, shape (H, W), bool, optional
        Crown pixels, whose filled row spans mirror the rear layer (default ``height > 0``).
    trunk : int, optional
        Index of the trunk crop in ``boxes``.
    push, interior, darken : float
        Depth push of the darkest region (fraction of the largest height), extra
        billboards per region, darkening at the crown's centre plane.
    yaw : (float, float)
        Range of the absolute yaw angle in degrees (0 ≤ low ≤ high < 80).
    max_leak : float
        Largest fraction of a rear or interior billboard's pixels allowed outside the tree.
    seed : int or Generator

    Returns
    -------
    Placement
        Front billboards first (in region order), then trunk, rear and interior ones.
    """
    from treeform.growth.sampling import blue_noise_points

    boxes = check_array(boxes, "boxes", shape=(None, 4), dtype_kind="iu").astype(np.int64)
    n = len(boxes)
    lum = check_array(luminance, "luminance", shape=(n,), dtype_kind="iuf").astype(np.float64)
    height = check_array(height, "height", ndim=2, dtype_kind="iuf").astype(np.float64)
    tree = check_array(tree, "tree", shape=height.shape).astype(bool)
    if len(masks) != n or n == 0:
        raise InputError(f"masks: expected one mask per box ({n}, at least one), got {len(masks)}")
    lo, hi = (float(a) for a in yaw)
    if not 0 <= lo <= hi < 80:
        raise InputError(f"yaw: expected (low, high) degrees with 0 <= low <= high < 80, got {yaw!r}")
    for name, val in (("push", push), ("interior", interior), ("darken", darken), ("max_leak", max_leak)):
        check_positive(val, name, allow_zero=True)
    if trunk is not None and not 0 <= trunk < n:
        raise InputError(f"trunk: expected an index in [0, {n}), got {trunk!r}")
    rng = as_rng(seed)
    crown = height > 0 if crown is None else check_array(crown, "crown", shape=height.shape).astype(bool)
    filled = ndi.binary_fill_holes(crown)
    hh, ww = height.shape
    fp = _Footprints(boxes, [np.asarray(m, bool) for m in masks], tree)
    regions = [i for i in range(n) if i != trunk]
    h_max = float(height.max())
    gap = 1.0

    def random_yaw(k):
        return np.radians(rng.uniform(lo, hi, k) * rng.choice([-1.0, 1.0], k))

    out = []  # (sprite, layer, x, y, z, yaw, shade) per billboard
    # front layer: own position, envelope depth, darker than average -> deeper
    reg = np.array(regions, np.int64)
    cx = boxes[reg, 0] + boxes[reg, 2] / 2.0
    cy = boxes[reg, 1] + boxes[reg, 3] / 2.0
    cent = np.array([_centroid(boxes[i], fp.masks[i]) for i in reg]).reshape(-1, 2)
    base = height[cent[:, 1], cent[:, 0]]
    mean = lum[reg].mean() if reg.size else 0.0
    dark = np.clip(mean - lum[reg], 0.0, None)
    dark = dark / dark.max() if dark.size and dark.max() > 0 else dark
    z_front = np.maximum(base - push * h_max * dark, 0.0)
    a_front = random_yaw(len(reg))
    for k, i in enumerate(reg):
        out.append((i, FRONT, cx[k], cy[k], z_front[k], a_front[k], 1.0))
        fp.paint(i, boxes[i, 0], boxes[i, 1], cx[k], z_front[k], a_front[k])
    if trunk is not None:
        tx, ty = boxes[trunk, 0] + boxes[trunk, 2] / 2.0, boxes[trunk, 1] + boxes[trunk, 3] / 2.0
        out.append((trunk, TRUNK, tx, ty, 0.0, math.radians(45.0), 1.0))
        fp.paint(trunk, boxes[trunk, 0], boxes[trunk, 1], tx, 0.0, math.radians(45.0))

    # rear layer: positions mirrored within the crown's row span, textures as they are
    rows = np.nonzero(filled.any(1))[0]
    left = np.where(filled.any(1), filled.argmax(1), 0)
    right = np.where(filled.any(1), ww - filled[:, ::-1].argmax(1), ww)
    a_rear = random_yaw(len(reg))
    for k, i in enumerate(reg):
        r = int(np.clip(round(cy[k] - 0.5), rows.min(), rows.max())) if rows.size else 0
        mid = (left[r] + right[r]) / 2.0
        w, h = boxes[i, 2], boxes[i, 3]
        oy = boxes[i, 1]
        x_mir = left[r] + right[r] - cx[k]
        towards = 1.0 if mid >= x_mir else -1.0
        for step in range(5):
            x = x_mir + towards * step * w / 4.0
            if step and (x - mid) * (x_mir - mid) < 0:  # moved past the centre: give up
                break
            ox = int(round(x - w / 2.0))
            if fp.leak(i, ox, oy) <= max_leak:
                xc = ox + w / 2.0
                col = int(np.clip(math.floor(xc), 0, ww - 1))
                want = -max(height[cent[k, 1], col] - push * h_max * dark[k], 0.0) - gap
                z = min(want, fp.deepest(i, ox, oy, xc, a_rear[k], gap))
                out.append((i, REAR, xc, oy + h / 2.0, z, a_rear[k], 1.0))
                break

    # interior: blue-noise points in |z| < height, random regions that fit, darker inside
    m_extra = int(round(interior * len(reg)))
    if m_extra and h_max > 0 and reg.size:
        py, px = np.nonzero(height > 0)
        lo3 = np.array([px.min(), py.min(), -h_max], np.float64)
        hi3 = np.array([px.max() + 1.0, py.max() + 1.0, h_max])

        def inside(p):
            j = np.clip(np.floor(p[:, 0]).astype(np.int64), 0, ww - 1)
            i = np.clip(np.floor(p[:, 1]).astype(np.int64), 0, hh - 1)
            return np.abs(p[:, 2]) < height[i, j]

        pts = blue_noise_points(inside, (lo3, hi3), m_extra, seed=rng)
        picks = rng.choice(reg, size=(len(pts), 4))
        a_int = random_yaw(len(pts))
        for p, cand, a in zip(pts, picks, a_int):
            for i in cand:
                w, h = boxes[i, 2], boxes[i, 3]
                ox, oy = int(round(p[0] - w / 2.0)), int(round(p[1] - h / 2.0))
                if fp.leak(i, ox, oy) > max_leak:
                    continue
                xc, yc = ox + w / 2.0, oy + h / 2.0
                z = min(float(p[2]), fp.deepest(i, ox, oy, xc, a, gap))
                hz = height[int(np.clip(math.floor(p[1]), 0, hh - 1)), int(np.clip(math.floor(p[0]), 0, ww - 1))]
                inner = 1.0 - min(abs(z) / hz, 1.0) if hz > 0 else 0.0
                out.append((int(i), INTERIOR, xc, yc, z, a, 1.0 - darken * inner))
                break
    cols = list(zip(*out))
    return Placement(np.array(cols[0], np.int64), np.array(cols[1], np.int8),
                     *(np.array(c, np.float64) for c in cols[2:]))


def _centroid(box, mask) -> tuple[int, int]:
    """Pixel (column, row) nearest the centroid of a crop's mask, in image coordinates."""
    ys, xs = np.nonzero(mask)
    if ys.size == 0:
        return int(box[0]), int(box[1])
    k = int(np.argmin((xs - xs.mean()) ** 2 + (ys - ys.mean()) ** 2))  # a mask pixel, even for a crescent
    return int(box[0] + xs[k]), int(box[1] + ys[k])
