"""Camera rotations refined by silhouette coherence (treeform.methods.multiview.coherence)."""

import math

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.methods.multiview.coherence import refine_rotations, splat_cells

W, H, F = 240, 180, 200.0
K = np.array([[F, 0.0, W / 2], [0.0, F, H / 2], [0.0, 0.0, 1.0]])

# a lumpy crown on a trunk: (centre, radius) spheres, not symmetric about any axis
SPHERES = np.array([[0.0, 6.0, 0.0, 3.0], [2.2, 7.5, 0.8, 2.0], [-1.8, 5.2, -1.5, 2.2], [0.6, 9.0, -0.9, 1.6],
                    [-2.5, 7.8, 1.6, 1.3]] + [[0.0, y, 0.0, 0.35] for y in np.arange(0.3, 4.0, 0.3)])


def _ring(n=16, radius=22.0):
    """OpenCV cam_to_world of ``n`` cameras on a ring at eye height, looking at the crown."""
    from treeform.sfm.evaluate import opencv_camera
    from treeform.structures import Camera

    fov = math.degrees(2 * math.atan(0.5 * H / F))
    return np.array([opencv_camera(Camera(W, H, fov, (radius * math.sin(a), 1.6, radius * math.cos(a)),
                                          (0.0, 5.5, 0.0)))[1]
                     for a in np.linspace(0, 2 * math.pi, n, endpoint=False)])


def _mask(T):
    """The spheres' silhouette seen by camera ``T`` (ray casting at pixel centres)."""
    u, v = np.meshgrid(np.arange(W) + 0.5, np.arange(H) + 0.5)
    d = np.stack([(u - K[0, 2]) / F, (v - K[1, 2]) / F, np.ones_like(u)], -1) @ T[:3, :3].T
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    m = np.zeros((H, W), bool)
    for c, r in zip(SPHERES[:, :3], SPHERES[:, 3]):
        oc = c - T[:3, 3]
        t = d @ oc
        m |= (t > 0) & (oc @ oc - t * t < r * r)
    return m


def _turn(T, yaw, pitch):
    """``T`` turned about its own centre: image shift of about (F yaw, F pitch) pixels."""
    from scipy.spatial.transform import Rotation

    Wc = np.linalg.inv(T)
    R = Rotation.from_rotvec([-pitch, yaw, 0.0]).as_matrix()
    Wc[:3, :3], Wc[:3, 3] = R @ Wc[:3, :3], R @ Wc[:3, 3]
    return np.linalg.inv(Wc)


def _view_shifts(cams, truth):
    """Per view, the mean image displacement of the spheres' centres against the true camera,
    less what a translation of the tree would explain (the refinement's gauge)."""
    P = SPHERES[:, :3]
    d, J = [], []
    for A, B in zip(cams, truth):
        pa, pb = [], []
        for T, out in ((A, pa), (B, pb)):
            X = P @ np.linalg.inv(T)[:3, :3].T + np.linalg.inv(T)[:3, 3]
            out.append(F * X[:, :2] / X[:, 2:])
        d.append((pa[0] - pb[0]).mean(0))
        Wb = np.linalg.inv(B)
        J.append(F / (Wb[:3, :3] @ P.mean(0) + Wb[:3, 3])[2] * Wb[:2, :3])
    d, J = np.concatenate(d), np.concatenate(J)
    return (d - J @ np.linalg.lstsq(J, d, rcond=None)[0]).reshape(-1, 2)


BOX = (np.array([-6.0, -0.5, -6.0]), np.array([6.0, 12.0, 6.0]))


@pytest.fixture(scope="module")
def scene():
    truth = _ring()
    masks = [_mask(T) for T in truth]
    return truth, masks


def test_splat_cells_squares_and_depth():
    # a cell 0.4 wide at 10 m under focal 100 px: 4 px, a 5x5 square about its centre's pixel
    m = splat_cells(np.array([[0.0, 0.0, 10.0], [0.0, 0.0, -10.0]]), 0.2, np.array(
        [[100.0, 0, 50], [0, 100.0, 50], [0, 0, 1]]), np.eye(4), (100, 100))
    assert m.sum() == 25 and m[48:53, 48:53].all()
    # per-cell sizes; a cell farther away covers fewer pixels
    m2 = splat_cells(np.array([[-1.0, 0.0, 10.0], [1.0, 0.0, 20.0]]), np.array([0.2, 0.2]),
                     np.array([[100.0, 0, 50], [0, 100.0, 50], [0, 0, 1]]), np.eye(4), (100, 100))
    assert m2[:, :50].sum() == 25 and m2[:, 50:].sum() == 9


def test_consistent_yaw_is_undone(scene):
    truth, masks = scene
    rng = np.random.default_rng(3)
    # every camera yawed the same way (what an SfM held by the far scene does) plus a little noise
    yaw = math.radians(0.4) + rng.normal(0, math.radians(0.08), len(truth))
    pitch = rng.normal(0, math.radians(0.08), len(truth))
    start = np.array([_turn(T, a, b) for T, a, b in zip(truth, yaw, pitch)])
    before = np.linalg.norm(_view_shifts(start, truth), axis=1)
    ref = refine_rotations(np.repeat(K[None], len(truth), 0), start, masks, BOX, cells=64)
    after = np.linalg.norm(_view_shifts(ref.cam_to_world, truth), axis=1)
    assert np.median(before) > 1.0
    assert np.median(after) < 0.35 * np.median(before) and np.median(after) < 0.6
    # centres stay, only rotations change; the recorded shifts are what was applied
    np.testing.assert_allclose(ref.cam_to_world[:, :3, 3], start[:, :3, 3], atol=1e-9)
    assert np.all(np.isfinite(ref.shifts)) and np.median(ref.shifts[:, 0]) < -1.0  # undoes +F yaw
    assert np.nanmedian(ref.cost_after) < np.nanmedian(ref.cost_before)


def test_true_cameras_stay(scene):
    truth, masks = scene
    ref = refine_rotations(np.repeat(K[None], len(truth), 0), truth, masks, BOX, cells=64)
    assert np.median(np.linalg.norm(_view_shifts(ref.cam_to_world, truth), axis=1)) < 0.3
    assert np.abs(ref.shifts).max() < 0.6


def test_deterministic(scene):
    truth, masks = scene
    start = np.array([_turn(T, 0.006, 0.0) for T in truth])
    a = refine_rotations(np.repeat(K[None], len(truth), 0), start, masks, BOX, cells=48, iterations=2)
    b = refine_rotations(np.repeat(K[None], len(truth), 0), start, masks, BOX, cells=48, iterations=2)
    np.testing.assert_array_equal(a.cam_to_world, b.cam_to_world)


def test_bad_input(scene):
    truth, masks = scene
    Ks = np.repeat(K[None], len(truth), 0)
    with pytest.raises(InputError, match="at least 4 views"):
        refine_rotations(Ks[:3], truth[:3], masks[:3], BOX)
    with pytest.raises(InputError, match="masks"):
        refine_rotations(Ks, truth, masks[:-1], BOX)
    with pytest.raises(InputError, match="box"):
        refine_rotations(Ks, truth, masks, (BOX[1], BOX[0]))
