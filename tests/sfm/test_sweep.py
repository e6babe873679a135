"""The ground by a plane sweep over the photos (treeform.sfm.sweep), on views of a textured plane."""

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.sfm.result import SfmResult
from treeform.sfm.sweep import plane_homography, sweep_ground


def _look_at(c, target):
    """Camera-to-world (OpenCV axes: x right, y down, z forward) of a camera at c looking at target, Y up."""
    z = target - c
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 1.0, 0.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = x, y, z, c
    return T


def _ground_views(n=8, eye=1.6, ring=10.0, scale=1.0, size=(320, 240), target_y=3.0):
    """Photos of a textured ground plane (y = 0) from a ring of cameras at eye height looking at the
    axis ``target_y`` metres up, in a world ``scale`` times the metric one (an SfM model's units)."""
    import cv2

    rng = np.random.default_rng(0)
    tex = cv2.GaussianBlur(rng.integers(0, 255, (1024, 1024)).astype(np.float32), (0, 0), 1.5)
    tex = cv2.normalize(tex, None, 20, 235, cv2.NORM_MINMAX).astype(np.uint8)
    half = 40.0  # the texture covers [-40, 40] m squared
    M = np.array([[2 * half / 1024, 0, -half], [0, 0, 0], [0, 2 * half / 1024, -half]])  # texel -> (X, 0, Z)
    w, h = size
    K = np.array([[260.0, 0, w / 2], [0, 260.0, h / 2], [0, 0, 1]])
    Ts, imgs = [], []
    for a in np.linspace(0, 2 * np.pi, n, endpoint=False):
        c = np.array([ring * np.cos(a), eye, ring * np.sin(a)])
        T = _look_at(c, np.array([0.0, target_y, 0.0]))  # at a crown's height: the ground fills the bottom
        R, C = T[:3, :3], T[:3, 3]
        H = K @ (R.T @ M - np.outer(R.T @ C, [0, 0, 1]))  # texel -> pixel
        img = cv2.warpPerspective(tex, H, (w, h), flags=cv2.INTER_LINEAR, borderValue=128)
        ys, xs = np.mgrid[0:h, 0:w]
        rays = np.stack([xs + 0.5, ys + 0.5, np.ones_like(xs)], -1) @ np.linalg.inv(K).T @ R.T
        img[rays[..., 1] >= -0.02] = 200  # sky (and the far horizon) where the ray does not reach the ground
        imgs.append(np.repeat(img[..., None], 3, axis=2))
        T = T.copy()
        T[:3, 3] *= scale
        Ts.append(T)
    res = SfmResult(names=[f"v{i:02d}.jpg" for i in range(n)], K=np.repeat(K[None], n, 0), cam_to_world=np.array(Ts),
                    sizes=np.repeat([[w, h]], n, 0), points=np.zeros((0, 3)), colors=np.zeros((0, 3)),
                    errors=np.zeros(0), tracks=[])
    return res, imgs


@pytest.mark.parametrize("scale", [1.0, 0.07])
def test_the_sweep_finds_the_ground_under_the_cameras(scale):
    res, imgs = _ground_views(scale=scale)
    g = sweep_ground(res, imgs, [0.0, 1.0, 0.0])
    assert g.depth == pytest.approx(1.6 * scale, rel=0.03)  # the cameras stand 1.6 m above the ground
    assert g.contrast > 0.1 and g.pairs == 16  # each camera with its 2 nearest
    assert np.all(np.diff(g.depths) >= 0) and g.scores.max() == pytest.approx(g.scores[np.argmax(g.scores)])
    again = sweep_ground(res, imgs, [0.0, 1.0, 0.0])  # the same photos, the same ground (the multi-view tests reuse it)
    assert again.depth == g.depth and np.array_equal(again.scores, g.scores)


def test_a_ground_without_texture_tells_no_depth_apart():
    res, imgs = _ground_views()
    flat = [np.full_like(im, 90) for im in imgs]
    assert sweep_ground(res, flat, [0.0, 1.0, 0.0]).contrast < 0.01


def test_homography_maps_plane_points_between_the_cameras():
    res, _ = _ground_views(n=4)
    K, T = res.K, res.cam_to_world
    X = np.array([1.5, 0.0, -2.0, 1.0])  # a point on the ground
    H = plane_homography(K[0], T[0], K[1], T[1], np.array([0.0, 1.0, 0.0]), 0.0)

    def project(i):
        p = K[i] @ (np.linalg.inv(T[i]) @ X)[:3]
        return p[:2] / p[2]

    x = H @ np.r_[project(0), 1.0]
    assert np.allclose(x[:2] / x[2], project(1), atol=1e-6)


def test_bad_input():
    res, imgs = _ground_views(n=3)
    with pytest.raises(InputError, match="expected 3 images"):
        sweep_ground(res, imgs[:2], [0, 1, 0])
    with pytest.raises(InputError, match="camera's"):
        sweep_ground(res, [im[:100] for im in imgs], [0, 1, 0])


def test_a_phone_tilted_up_at_a_tall_tree_still_finds_the_ground():
    """Framing a tall tree leaves no ground 8 degrees below the horizon in the photos: the sweep widens
    to shallower rays (SWEEP_DEPRESSIONS) instead of leaving the metric scale to a few stray SfM points."""
    from dataclasses import replace

    from treeform.sfm import to_tree_frame

    res, imgs = _ground_views(target_y=4.8)  # the frame's bottom row looks 7 degrees down
    assert sweep_ground(res, imgs, [0.0, 1.0, 0.0], min_depression_deg=8.0).contrast < 0.04
    rng = np.random.default_rng(1)
    stray = np.c_[rng.uniform(-5, 5, 8), np.full(8, -4.0), rng.uniform(-5, 5, 8)]  # a sparse model's points, 4 m low
    res = replace(res, points=stray, colors=np.zeros((8, 3), np.uint8), errors=np.zeros(8),
                  tracks=[np.zeros((2, 3))] * 8)
    out = to_tree_frame(res, images=imgs)
    frame = out.meta["frame"]
    assert frame["ground_source"] == "sweep" and frame["sweep_depression_deg"] == 5.0
    # metres: the cameras 1.6 m above the true ground put the 10-m ring at 10 m (on the stray points' plane: 2.9 m)
    assert np.median(np.hypot(out.centers[:, 0], out.centers[:, 2])) == pytest.approx(10.0, rel=0.03)
