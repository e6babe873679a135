"""The ground plane by a plane sweep over the photos themselves, not the SfM points.

A lawn gives a feature matcher few points, so the RANSAC plane through the lowest SfM points
(:func:`~treeform.sfm.align.ground_plane`) can rest on a handful of them, and the eye-height
scale with it. Every ground pixel, though, says where the ground is: for a level plane ``d``
below the cameras, each photo's ground pixels map into a neighbouring photo by the plane's
homography, and only at the true ``d`` do the two agree. The sweep scores a range of ``d``
by the local normalised cross-correlation of each photo with its neighbours warped onto it
(pixels that look down, below the horizon) and keeps the best (Collins' plane sweep, with one
unknown: the ground's depth under the cameras along their up).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from treeform._shared.errors import InputError
from treeform.sfm.result import SfmResult

__all__ = ["GroundSweep", "sweep_ground", "plane_homography"]


@dataclass(frozen=True)
class GroundSweep:
    """Result of :func:`sweep_ground`.

    Attributes
    ----------
    depth : float
        The ground's distance below the median camera along ``up``, in the world's units.
    depths, scores : ndarray, shape (S,)
        The swept depths (ascending) and their mean correlation.
    contrast : float
        The best score less the median score: how clearly one depth wins (about 0.1 and more on a
        textured ground, near 0 where nothing tells the depths apart).
    pairs : int
        Photo pairs that took part.
    """

    depth: float
    depths: np.ndarray
    scores: np.ndarray
    contrast: float
    pairs: int


def plane_homography(K_i, T_i, K_j, T_j, normal, offset) -> np.ndarray:
    """The 3x3 map of photo ``i``'s pixels to photo ``j``'s for points on the plane ``normal . x = offset``.

    ``T`` are camera-to-world transforms (OpenCV axes), ``K`` intrinsics. For ``X_i`` in camera
    i's frame on the plane (``n_i . X_i = d_i``), ``X_j = (R_ji + t_ji n_i^T / d_i) X_i``.

    Examples
    --------
    Two cameras 1 m apart looking down +z at the plane z = 5: a point on it maps one to the other.

    >>> K = np.array([[100., 0, 50], [0, 100, 50], [0, 0, 1]])
    >>> Ti, Tj = np.eye(4), np.eye(4); Tj[0, 3] = 1.0
    >>> H = plane_homography(K, Ti, K, Tj, np.array([0, 0, 1.]), 5.0)
    >>> x = H @ [50, 50, 1]; (x[:2] / x[2]).round(6).tolist()  # (0, 0, 5) is 1 m left of camera j
    [30.0, 50.0]
    """
    R_i, C_i = T_i[:3, :3], T_i[:3, 3]
    R_j, C_j = T_j[:3, :3], T_j[:3, 3]
    n_i = R_i.T @ normal
    d_i = offset - normal @ C_i
    R_ji = R_j.T @ R_i
    t_ji = R_j.T @ (C_i - C_j)
    return K_j @ (R_ji + np.outer(t_ji, n_i) / d_i) @ np.linalg.inv(K_i)


def _gray(img: np.ndarray, scale: float) -> np.ndarray:
    import cv2

    g = cv2.cvtColor(np.asarray(img, np.uint8), cv2.COLOR_RGB2GRAY).astype(np.float32)
    if scale != 1.0:
        g = cv2.resize(g, (max(8, round(g.shape[1] * scale)), max(8, round(g.shape[0] * scale))),
                       interpolation=cv2.INTER_AREA)
    return g


def _local_stats(a: np.ndarray, win: int) -> tuple[np.ndarray, np.ndarray]:
    """Local mean and standard deviation of an image over a box window."""
    import cv2

    m = cv2.blur(a, (win, win))
    return m, np.sqrt(np.maximum(cv2.blur(a * a, (win, win)) - m * m, 0.0))


def _ncc(a: np.ndarray, a_stats, b: np.ndarray, win: int):
    """Local zero-mean normalised cross-correlation of two images (box window; ``a``'s
    :func:`_local_stats` given) and ``b``'s local standard deviation."""
    import cv2

    ma, sa = a_stats
    mb, sb = _local_stats(b, win)
    cov = cv2.blur(a * b, (win, win)) - ma * mb
    return cov / np.sqrt((sa * sa) * (sb * sb) + 1e-6), sb


def sweep_ground(result: SfmResult, images, up, *, size: int = 320, steps: int = 48, neighbours: int = 2,
                 min_depression_deg: float = 8.0, window: int = 9, range_=(0.01, 0.6)) -> GroundSweep:
    """The level ground under the cameras by a plane sweep over the photos.

    Parameters
    ----------
    result : SfmResult
    images : list of ndarray, each (H, W, 3) uint8
        The registered photos in ``result.names`` order, at ``result.sizes``.
    up : ndarray, shape (3,)
        The world's up (e.g. :func:`~treeform.sfm.align.up_vector`); the ground is level.
    size : int
        Long side the photos are reduced to.
    steps : int
        Depths swept, log-spaced over ``range_`` times the cameras' spread (their median distance
        from their centroid), then as many again around the best.
    neighbours : int
        Each photo is compared with this many nearest cameras.
    min_depression_deg : float
        Only pixels looking at least this far below the horizon count (the far ground barely
        moves between neighbours; the sky and the trees' crowns are above).
    window : int
        Side of the correlation window in pixels (at ``size``).
    range_ : (float, float)

    Returns
    -------
    GroundSweep

    Raises
    ------
    InputError
        ``images`` do not match the result's cameras, or fewer than 2 cameras.
    """
    import cv2

    C = result.n_cameras
    if C < 2:
        raise InputError("sweep_ground: needs at least 2 registered cameras")
    if len(images) != C:
        raise InputError(f"sweep_ground: expected {C} images (one per registered camera), got {len(images)}")
    up = np.asarray(up, np.float64)
    up = up / np.linalg.norm(up)
    centers = result.centers
    heights = centers @ up
    top = float(np.median(heights))
    spread = float(np.median(np.linalg.norm(centers - centers.mean(0), axis=1)))
    if not spread > 0:
        raise InputError("sweep_ground: the cameras do not move (no baseline to sweep with)")
    grays, Ks, downs = [], [], []
    sin_min = np.sin(np.radians(min_depression_deg))
    for i in range(C):
        w, h = (int(v) for v in result.sizes[i])
        img = np.asarray(images[i])
        if img.shape[:2] != (h, w):
            raise InputError(f"sweep_ground: image {i} is {img.shape[1]}x{img.shape[0]}, the camera's {w}x{h}")
        s = min(1.0, size / max(w, h))
        g = _gray(img, s)
        sx, sy = g.shape[1] / w, g.shape[0] / h
        K = np.diag([sx, sy, 1.0]) @ result.K[i]
        # pixels whose ray looks down by at least min_depression_deg
        ys, xs = np.mgrid[0:g.shape[0], 0:g.shape[1]]
        rays = np.stack([xs + 0.5, ys + 0.5, np.ones_like(xs)], -1).reshape(-1, 3) @ np.linalg.inv(K).T
        rays = rays @ result.cam_to_world[i, :3, :3].T
        rays /= np.linalg.norm(rays, axis=1, keepdims=True)
        stats = _local_stats(g, window)
        # the photo's own textured pixels that look down: what each depth is scored on
        downs.append((rays @ up < -sin_min).reshape(g.shape) & (stats[1] > 2.0))
        grays.append((g, stats))
        Ks.append(K)
    d = np.linalg.norm(centers[:, None] - centers[None], axis=2)
    np.fill_diagonal(d, np.inf)
    pairs = sorted({(i, int(j)) for i in range(C) for j in np.argsort(d[i])[:neighbours]})

    def score(depth: float) -> float:
        # the correlation summed over every textured, down-looking pixel of the photos, those the
        # neighbour does not see at this depth counted as 0: a depth is not rewarded for leaving
        # only a sliver to compare (a plane just under the cameras maps the ground off the frame)
        offset = top - depth
        total, count = 0.0, 0
        for i, j in pairs:
            if not downs[i].any():
                continue
            H = plane_homography(Ks[i], result.cam_to_world[i], Ks[j], result.cam_to_world[j], up, offset)
            (gi, stats), gj = grays[i], grays[j][0]
            hh, ww = gi.shape
            warped = cv2.warpPerspective(gj, H, (ww, hh), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                                         borderMode=cv2.BORDER_CONSTANT, borderValue=-1.0)
            inside = cv2.erode((warped >= 0).astype(np.uint8), np.ones((window, window), np.uint8)) > 0
            ncc, sb = _ncc(gi, stats, warped, window)
            ok = inside & downs[i] & (sb > 2.0)
            total += float(ncc[ok].sum())
            count += int(downs[i].sum())
        return total / count if count else 0.0

    lo, hi = range_
    depths = spread * np.geomspace(lo, hi, steps)
    scores = np.array([score(x) for x in depths])
    k = int(np.argmax(scores))
    a, b = depths[max(k - 1, 0)], depths[min(k + 1, steps - 1)]
    fine = np.linspace(a, b, steps)
    fine_scores = np.array([score(x) for x in fine])
    all_d = np.concatenate([depths, fine])
    all_s = np.concatenate([scores, fine_scores])
    order = np.argsort(all_d)
    all_d, all_s = all_d[order], all_s[order]
    best = int(np.argmax(all_s))
    return GroundSweep(float(all_d[best]), all_d, all_s, float(all_s[best] - np.median(scores)), len(pairs))
