"""Small charts drawn with Pillow (no plotting library needed): box plots of distributions."""

from __future__ import annotations

import numpy as np
from PIL import Image, ImageDraw

PALETTE = [(228, 26, 28), (55, 126, 184), (77, 175, 74), (152, 78, 163), (255, 127, 0), (166, 86, 40),
           (247, 129, 191), (153, 153, 153)]


def box_plots(data: dict, metrics: list, *, titles: dict | None = None, panel=(300, 260), cols: int = 3) -> np.ndarray:
    """A grid of box plots: one panel per metric, one box per group.

    Parameters
    ----------
    data : dict
        ``group -> {metric -> 1-D array of values}`` (e.g. species -> metric samples).
    metrics : list of str
        Which metrics to plot, one panel each.
    titles : dict, optional
        ``metric -> panel title``.

    Returns
    -------
    ndarray, shape (H, W, 3), uint8
        Boxes span the quartiles with the median line; whiskers reach the 5th and 95th
        percentiles; dots mark the mean.
    """
    groups = list(data)
    rows = (len(metrics) + cols - 1) // cols
    pw, ph = panel
    img = Image.new("RGB", (cols * pw, rows * ph), "white")
    draw = ImageDraw.Draw(img)
    for k, metric in enumerate(metrics):
        ox, oy = (k % cols) * pw, (k // cols) * ph
        vals = [np.asarray(data[g][metric], float) for g in groups]
        vals = [v[np.isfinite(v)] for v in vals]
        allv = np.concatenate([v for v in vals if len(v)]) if any(len(v) for v in vals) else np.zeros(1)
        lo, hi = float(np.percentile(allv, 1)), float(np.percentile(allv, 99))
        if hi - lo < 1e-12:
            lo, hi = lo - 1, hi + 1
        pad = 0.08 * (hi - lo)
        lo, hi = lo - pad, hi + pad
        left, right, top, bottom = ox + 44, ox + pw - 10, oy + 26, oy + ph - 34
        draw.text((ox + 8, oy + 6), (titles or {}).get(metric, metric), fill=(0, 0, 0))
        draw.rectangle([left, top, right, bottom], outline=(180, 180, 180))

        def y_of(v):
            return bottom - (v - lo) / (hi - lo) * (bottom - top)

        for t in np.linspace(lo + pad, hi - pad, 4):
            y = y_of(t)
            draw.line([left - 3, y, left, y], fill=(120, 120, 120))
            draw.text((ox + 2, y - 6), f"{t:.3g}", fill=(90, 90, 90))
        slot = (right - left) / max(len(groups), 1)
        for i, (g, v) in enumerate(zip(groups, vals)):
            if not len(v):
                continue
            cx = left + (i + 0.5) * slot
            w = slot * 0.3
            q5, q25, q50, q75, q95 = np.percentile(v, [5, 25, 50, 75, 95])
            col = PALETTE[i % len(PALETTE)]
            draw.line([cx, y_of(q5), cx, y_of(q95)], fill=col, width=1)
            draw.rectangle([cx - w, y_of(q75), cx + w, y_of(q25)], outline=col, width=2)
            draw.line([cx - w, y_of(q50), cx + w, y_of(q50)], fill=col, width=2)
            m = y_of(float(v.mean()))
            draw.ellipse([cx - 2, m - 2, cx + 2, m + 2], fill=col)
            draw.text((cx - 3 * len(g), bottom + 6), g, fill=col)
    return np.asarray(img)


def line_plot(series: dict, *, title: str = "", xlabel: str = "", ylabel: str = "", size=(520, 320)) -> np.ndarray:
    """Curves over x = 1, 2, ... (e.g. seed 004 Fig. 13: error against the number of tested models).

    Parameters
    ----------
    series : dict
        ``label -> 1-D sequence of y values``; the first series is drawn as a line, the others
        as dots (several may be lines and dots: the first is the one to read).
    title, xlabel, ylabel : str
    size : (width, height)

    Returns
    -------
    ndarray, shape (height, width, 3), uint8

    Examples
    --------
    >>> line_plot({"best": [0.3, 0.2, 0.2]}, title="t").shape
    (320, 520, 3)
    """
    w, h = size
    img = Image.new("RGB", (w, h), "white")
    draw = ImageDraw.Draw(img)
    ys = [np.asarray(v, float) for v in series.values()]
    allv = np.concatenate([y[np.isfinite(y)] for y in ys if len(y)]) if any(len(y) for y in ys) else np.zeros(1)
    lo, hi = float(allv.min()), float(allv.max())
    if hi - lo < 1e-12:
        lo, hi = lo - 0.5 * abs(lo or 1), hi + 0.5 * abs(hi or 1)
    pad = 0.08 * (hi - lo)
    lo, hi = lo - pad, hi + pad
    n = max((len(y) for y in ys), default=1)
    left, right, top, bottom = 56, w - 14, 30, h - 40
    draw.text((8, 6), title, fill=(0, 0, 0))
    draw.rectangle([left, top, right, bottom], outline=(180, 180, 180))

    def xy(i, v):
        x = left + (i / max(n - 1, 1)) * (right - left)
        return x, bottom - (v - lo) / (hi - lo) * (bottom - top)

    for t in np.linspace(lo + pad, hi - pad, 5):
        _, y = xy(0, t)
        draw.line([left - 3, y, left, y], fill=(120, 120, 120))
        draw.text((4, y - 6), f"{t:.3g}", fill=(90, 90, 90))
    for t in sorted({1, (n + 1) // 2, n}):
        x, _ = xy(t - 1, lo)
        draw.line([x, bottom, x, bottom + 3], fill=(120, 120, 120))
        draw.text((x - 4, bottom + 5), str(t), fill=(90, 90, 90))
    draw.text(((left + right) // 2 - 3 * len(xlabel), h - 18), xlabel, fill=(60, 60, 60))
    draw.text((left + 4, top + 4), ylabel, fill=(60, 60, 60))
    for k, (label, y) in enumerate(zip(series, ys)):
        col = PALETTE[k % len(PALETTE)]
        pts = [xy(i, v) for i, v in enumerate(y) if np.isfinite(v)]
        if k == 0 and len(pts) > 1:
            draw.line(pts, fill=col, width=2)
        for x, yy in pts:
            draw.ellipse([x - 2, yy - 2, x + 2, yy + 2], fill=col)
        draw.text((right - 150, top + 6 + 14 * k), label, fill=col)
    return np.asarray(img)
