"""Conifer foliage textures: pine-like needle clusters and thuja-like scale sprays.

Both are drawn, like the broadleaf textures of :mod:`treeform.geometry.leaves`, as light
grey-green strokes on a transparent square (the card's vertex colour tints them), in texture
units (x right, y down, [0, 1]²), supersampled and box-filtered to antialias the alpha:

* **needles** — four or five shoots fan out from a twig at the bottom of the card; along
  each, pairs (now and then threes) of long, thin, pointed needles (about two texels wide
  at 256²) leave every ~1/95 of the card, swept forward 25–65° from the shoot, with random
  foreshortening; those behind the twig are a quarter darker; the shoot tips end in a tuft. About a third of the card is opaque, dense along the shoots and
  open between the needle tips, so the card reads as a bottle-brush, not a paper square.
* **scales** — a flat, bipinnate spray (as of *Thuja* or *Chamaecyparis*): a main axis with
  alternate side branchlets, longest in the lower middle (an ovate outline), each with
  alternate short sub-branchlets; every axis is a chain of small overlapping scale leaves
  (a facial lozenge and two lateral ones per node, each lighter in its middle and darker at
  its tip edge, so the braided, segmented look survives the tint).
"""

from __future__ import annotations

import numpy as np

from treeform._shared.rng import as_rng
from treeform.geometry.leaves import _downsample, _supersampling

__all__ = ["conifer_texture"]

_NEEDLE_RGB = np.array([0.86, 0.95, 0.84])
_SCALE_RGB = np.array([0.90, 0.97, 0.84])
_TWIG_RGB = np.array([0.86, 0.78, 0.64])  # warm: tinted green it reads as a brownish twig


class _Strokes:
    """A list of tapered strokes: (x0, y0, x1, y1, half-width at 0, at 1, r, g, b, shape)."""

    def __init__(self):
        self.rows: list = []

    def add(self, p0, p1, hw0, hw1, rgb, shape: int = 0):
        """``shape`` 0: a capsule tapering linearly from ``hw0`` to ``hw1`` (round ends);
        1: a lozenge, ``hw0 · sin(π t)^0.7`` (pointed at both ends)."""
        self.rows.append((p0[0], p0[1], p1[0], p1[1], hw0, hw1, *rgb, shape))


def _rasterize(strokes: _Strokes, res: int, texel: float):
    """Paint the strokes in order (later ones on top); returns alpha (res, res) and rgb (res, res, 3).

    Each stroke is shaded as a rounded cross-section: lighter on its centre line, 25 % darker
    at its edges. ``texel`` is the output texel size in texture units: half-widths below
    0.55 texel are widened to it, so no stroke falls apart when box-filtered.
    """
    alpha = np.zeros((res, res))
    rgb = np.empty((res, res, 3))
    rgb[:] = _NEEDLE_RGB
    min_hw = 0.55 * texel
    for x0, y0, x1, y1, hw0, hw1, r, g, b, shape in strokes.rows:
        hw_max = max(hw0, hw1, min_hw)
        lo = np.floor((np.minimum([x0, y0], [x1, y1]) - hw_max) * res).astype(int).clip(0, res)
        hi = np.ceil((np.maximum([x0, y0], [x1, y1]) + hw_max) * res).astype(int).clip(0, res)
        if hi[0] <= lo[0] or hi[1] <= lo[1]:
            continue
        ys, xs = (np.mgrid[lo[1]:hi[1], lo[0]:hi[0]] + 0.5) / res
        dx, dy = x1 - x0, y1 - y0
        t_raw = ((xs - x0) * dx + (ys - y0) * dy) / max(dx * dx + dy * dy, 1e-12)
        t = np.clip(t_raw, 0.0, 1.0)
        dist = np.hypot(xs - x0 - t * dx, ys - y0 - t * dy)
        if shape == 1:
            hw = hw0 * np.sin(np.pi * np.clip(t_raw, 0.0, 1.0)) ** 0.7
            hw = np.where((t_raw > 0) & (t_raw < 1), np.maximum(hw, min_hw * (t_raw > 0.05) * (t_raw < 0.95)), 0.0)
        else:
            hw = np.maximum(hw0 + (hw1 - hw0) * t, min_hw * (t < 0.97))
        inside = dist < hw
        if not inside.any():
            continue
        rel = dist[inside] / hw[inside]
        tone = 1.0 - 0.25 * rel**2
        if shape == 1:  # a scale: darker towards its tip, where the next scale's base overlaps it
            tone = tone * (1.0 - 0.22 * np.clip(t_raw[inside] - 0.55, 0.0, 1.0) / 0.45)
        alpha[lo[1]:hi[1], lo[0]:hi[0]][inside] = 1.0
        rgb[lo[1]:hi[1], lo[0]:hi[0]][inside] = np.array([r, g, b])[None, :] * tone[:, None]
    return alpha, rgb


def _curve(p0, direction, length: float, bend: float, n: int) -> np.ndarray:
    """(n + 1, 2) points of a gently bending path from ``p0`` along ``direction`` (unit)."""
    ang0 = np.arctan2(direction[1], direction[0])
    s = np.linspace(0.0, 1.0, n + 1)
    ang = ang0 + bend * s
    step = length / n
    d = np.stack([np.cos(ang), np.sin(ang)], axis=1)
    pts = np.concatenate([[np.asarray(p0, float)], np.asarray(p0, float) + np.cumsum(d[:-1] * step, axis=0)])
    return pts


def _tangents(path: np.ndarray) -> np.ndarray:
    d = np.gradient(path, axis=0)
    return d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)


def _room(p: np.ndarray, d: np.ndarray, margin: float = 0.02) -> float:
    """How far from ``p`` along the unit ``d`` one can go and stay ``margin`` inside the card."""
    room = np.inf
    for k in (0, 1):
        if d[k] > 1e-9:
            room = min(room, (1.0 - margin - p[k]) / d[k])
        elif d[k] < -1e-9:
            room = min(room, (margin - p[k]) / d[k])
    return max(float(room), 0.0)


def _needle_layout(rng: np.random.Generator) -> _Strokes:
    """Shoots fanning up from a twig at the card's bottom, each a bottle-brush of needle pairs."""
    back, front = _Strokes(), _Strokes()
    twig = _Strokes()
    base = np.array([0.5 + rng.uniform(-0.03, 0.03), 0.97])
    n_shoots = int(rng.integers(4, 6))
    # fan of shoot directions around "up" (-y), the middle one the leader
    spread = np.linspace(-1.0, 1.0, n_shoots) * rng.uniform(0.85, 1.05)
    for k, a in enumerate(spread):
        leader = abs(a) < 1e-9 or (n_shoots % 2 == 0 and k == n_shoots // 2)
        ang = -np.pi / 2 + a + rng.uniform(-0.08, 0.08)
        d = np.array([np.cos(ang), np.sin(ang)])
        start = base + d * rng.uniform(0.02, 0.08)
        # length: reach about 90 % of the way to the border along d
        with np.errstate(divide="ignore"):
            tx = np.where(d[0] > 0, (0.96 - start[0]) / d[0], np.where(d[0] < 0, (0.04 - start[0]) / d[0], np.inf))
            ty = np.where(d[1] < 0, (0.04 - start[1]) / d[1], np.inf)
        reach = float(min(tx, ty))
        length = reach * (rng.uniform(0.80, 0.88) if leader else rng.uniform(0.70, 0.84))
        n_seg = 24
        bend = rng.uniform(-0.25, 0.25) + 0.3 * a
        path = _curve(start, d, length, bend, n_seg)
        while np.any((path < 0.04) | (path > 0.96)) and length > 0.1:  # a bend must not leave the card
            length *= 0.93
            path = _curve(start, d, length, bend, n_seg)
        tan = _tangents(path)
        for j in range(n_seg):  # the twig, thinning toward the shoot tip
            f = j / n_seg
            twig.add(path[j], path[j + 1], 0.0075 * (1 - 0.5 * f), 0.0075 * (1 - 0.5 * (f + 1 / n_seg)), _TWIG_RGB)
        twig.add(base, start, 0.009, 0.0075, _TWIG_RGB)
        # needle pairs every ~1/80 of the card, from 15 % of the shoot to its tip
        s_arc = np.linspace(0.0, 1.0, n_seg + 1)
        n_fasc = int(length / 0.0105)
        for i in range(n_fasc):
            s = 0.15 + 0.85 * (i + rng.uniform(-0.3, 0.3)) / max(n_fasc - 1, 1)
            s = float(np.clip(s, 0.0, 1.0))
            p = np.array([np.interp(s, s_arc, path[:, 0]), np.interp(s, s_arc, path[:, 1])])
            t = np.array([np.interp(s, s_arc, tan[:, 0]), np.interp(s, s_arc, tan[:, 1])])
            t /= np.linalg.norm(t)
            nrm = np.array([-t[1], t[0]])
            tip_fade = 1.0 - 0.45 * max(s - 0.8, 0.0) / 0.2  # shorter needles toward the bud
            sides = (-1.0, 1.0, -1.0 if rng.random() < 0.5 else 1.0) if rng.random() < 0.5 else (-1.0, 1.0)
            for side in sides:
                sweep = rng.uniform(0.45, 1.15)  # angle from the shoot, forward
                fore = rng.uniform(0.45, 1.0)  # foreshortening of needles leaning out of the card
                nl = rng.uniform(0.17, 0.24) * fore * tip_fade
                dirn = np.cos(sweep) * t + side * np.sin(sweep) * nrm
                tip = p + min(nl, _room(p, dirn)) * dirn
                rgb = _NEEDLE_RGB * rng.uniform(0.82, 1.0) + rng.uniform(-0.03, 0.03, 3)
                if rng.random() < 0.4:  # behind the twig, in its shade
                    back.add(p, tip, 0.0042, 0.0006, 0.74 * rgb)
                else:
                    front.add(p, tip, 0.0042, 0.0006, rgb)
        # terminal tuft: a few needles fanning around the bud
        for a_t in np.linspace(-0.55, 0.55, 5) + rng.uniform(-0.1, 0.1, 5):
            t = tan[-1]
            dirn = np.array([np.cos(a_t) * t[0] - np.sin(a_t) * t[1], np.sin(a_t) * t[0] + np.cos(a_t) * t[1]])
            front.add(path[-1], path[-1] + min(rng.uniform(0.08, 0.13), _room(path[-1], dirn)) * dirn, 0.0042,
                      0.0006, _NEEDLE_RGB * rng.uniform(0.85, 1.0))
    out = _Strokes()
    out.rows = back.rows + twig.rows + front.rows
    return out


def _scale_axis(strokes: _Strokes, path: np.ndarray, width: float, rng: np.random.Generator) -> None:
    """A chain of overlapping scale leaves along ``path``: per node a facial lozenge and two
    lateral ones, painted tip first so each basal scale overlaps the one above it."""
    seg = np.linalg.norm(np.diff(path, axis=0), axis=1)
    s_arc = np.concatenate([[0.0], np.cumsum(seg)])
    total = float(s_arc[-1])
    if total <= 0:
        return
    tan = _tangents(path)
    spacing = 2.3 * width
    n = max(int(total / spacing), 1)
    for i in range(n - 1, -1, -1):
        s0 = i * spacing
        s1 = min(s0 + 1.7 * spacing, total)
        p0 = np.array([np.interp(s0, s_arc, path[:, 0]), np.interp(s0, s_arc, path[:, 1])])
        p1 = np.array([np.interp(s1, s_arc, path[:, 0]), np.interp(s1, s_arc, path[:, 1])])
        t = np.array([np.interp(s0, s_arc, tan[:, 0]), np.interp(s0, s_arc, tan[:, 1])])
        t /= max(np.linalg.norm(t), 1e-12)
        nrm = np.array([-t[1], t[0]])
        taper = 1.0 - 0.35 * s0 / total
        w = width * taper
        shade = rng.uniform(0.88, 1.0)
        for side in (-1.0, 1.0):  # lateral scales, folded along the sides
            q0 = p0 + side * 0.55 * w * nrm
            q1 = q0 + (p1 - p0) * 0.9 + side * 0.45 * w * nrm
            strokes.add(q0, q1, 0.62 * w, 0.0, _SCALE_RGB * shade * 0.9, shape=1)
        strokes.add(p0, p1, 0.85 * w, 0.0, _SCALE_RGB * shade, shape=1)  # facial scale on top


def _frond(strokes: _Strokes, p0, direction, length: float, order: int, rng: np.random.Generator,
           bend: float) -> None:
    """One axis of a flat spray and, recursively, its alternate side axes (orders 0, 1, 2).

    Side axes leave at 40-55° forward, alternately left and right; those of the main axis are
    longest in its lower middle (an ovate outline), those of a branchlet shorten toward its tip,
    inner ones (toward the parent axis) half as long. Children are painted first, so every
    axis lies on top of its side axes.
    """
    n = 24 if order == 0 else 12 if order == 1 else 5
    path = _curve(p0, direction, length, bend, n)
    if order < 2:
        tan = _tangents(path)
        s_arc = np.linspace(0.0, 1.0, n + 1)
        spacing = 0.052 if order == 0 else 0.030
        n_child = max(int(length / spacing), 1)
        first = 1.0 if rng.random() < 0.5 else -1.0
        for i in range(n_child):
            s = (0.10 if order == 0 else 0.14) + (0.84 if order == 0 else 0.80) * i / max(n_child - 1, 1)
            s = float(np.clip(s + rng.uniform(-0.01, 0.01), 0.0, 1.0))
            p = np.array([np.interp(s, s_arc, path[:, 0]), np.interp(s, s_arc, path[:, 1])])
            t = np.array([np.interp(s, s_arc, tan[:, 0]), np.interp(s, s_arc, tan[:, 1])])
            t /= np.linalg.norm(t)
            side = first * (1.0 if i % 2 == 0 else -1.0)
            nrm = np.array([-t[1], t[0]])
            ang = rng.uniform(0.72, 0.95)
            d = np.cos(ang) * t + side * np.sin(ang) * nrm
            if order == 0:
                child = 0.55 * np.sin(np.pi * min(s / 0.93, 1.0) ** 0.75) * rng.uniform(0.9, 1.05)
            else:
                inner = side * bend < 0  # curving toward this side: the inner side of the branchlet
                child = (0.30 * length * (1.0 - s) + 0.035) * (0.55 if inner else 1.0) * rng.uniform(0.85, 1.1)
            with np.errstate(divide="ignore"):  # stay inside the card
                tx = np.where(d[0] > 0, (0.975 - p[0]) / d[0], np.where(d[0] < 0, (0.025 - p[0]) / d[0], np.inf))
                ty = np.where(d[1] > 0, (0.975 - p[1]) / d[1], np.where(d[1] < 0, (0.025 - p[1]) / d[1], np.inf))
            child = float(min(child, 0.9 * min(tx, ty)))
            if child > 0.02:
                _frond(strokes, p, d, child, order + 1, rng, -side * rng.uniform(0.1, 0.3))
    _scale_axis(strokes, path, (0.0135, 0.0100, 0.0078)[order], rng)


def _scale_layout(rng: np.random.Generator) -> _Strokes:
    """A flat bipinnate spray: main axis, alternate branchlets (ovate outline), sub-branchlets."""
    strokes = _Strokes()
    base = np.array([0.5 + rng.uniform(-0.03, 0.03), 0.985])
    d = np.array([rng.uniform(-0.08, 0.08), -1.0])
    _frond(strokes, base, d / np.linalg.norm(d), 0.90, 0, rng, rng.uniform(-0.2, 0.2))
    return strokes


def conifer_texture(size: int, *, seed=0, kind: str = "needles") -> np.ndarray:
    """A needle-cluster or scale-spray texture with an alpha mask (see the module docstring).

    Parameters
    ----------
    size : int
        Edge length in texels (>= 8; checked by :func:`~treeform.geometry.leaf_texture`).
    seed : int or numpy.random.Generator
        Same seed -> identical texture.
    kind : {"needles", "scales"}

    Returns
    -------
    ndarray, shape (size, size, 4), uint8
        sRGB colour and alpha; light grey-green (the card colour tints it); transparent
        texels carry the mean foliage colour.
    """
    rng = as_rng(seed)
    strokes = _needle_layout(rng) if kind == "needles" else _scale_layout(rng)
    ss = _supersampling(size)
    alpha, rgb = _rasterize(strokes, size * ss, 1.0 / size)
    return _downsample(alpha, rgb, size, ss)
