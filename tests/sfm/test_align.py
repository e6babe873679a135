"""From COLMAP's world to treeform's frame: up, ground, eye-height scale, the similarity."""

import numpy as np
import pytest
from conftest import EYE

from treeform._shared.errors import InputError, SfmError
from treeform.sfm import SfmResult, to_tree_frame
from treeform.sfm.align import (Plane, camera_height_scale, frame_rotation, ground_plane, similarity_to_frame,
                                up_vector)
from treeform.sfm.evaluate import truth_cameras_json, umeyama


def _rotation(rng):
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.linalg.det(q))


def _scene(rng, n_cams=10, pitch_target=0.5):
    """A truth-frame model: cameras at 1.6 m on a ring facing the centre, points on the ground
    (y = 0, many), on boxes (y 0..0.8) and a few outliers below the ground."""
    c2w = []
    for a in np.linspace(0, 2 * np.pi, n_cams, endpoint=False):
        eye = np.array([4 * np.sin(a), EYE, 4 * np.cos(a)])
        f = np.array([0, pitch_target, 0]) - eye
        f /= np.linalg.norm(f)
        r = np.cross(f, [0, 1, 0])
        r /= np.linalg.norm(r)
        T = np.eye(4)
        T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = r, np.cross(f, r), f, eye
        c2w.append(T)
    ground = np.column_stack([rng.uniform(-5, 5, 600), rng.normal(0, 0.005, 600), rng.uniform(-5, 5, 600)])
    boxes = np.column_stack([rng.uniform(-1, 1, 500), rng.uniform(0.0, 0.8, 500), rng.uniform(-1, 1, 500)])
    below = np.column_stack([rng.uniform(-3, 3, 10), rng.uniform(-1.0, -0.2, 10), rng.uniform(-3, 3, 10)])
    pts = np.concatenate([ground, boxes, below])
    n = len(c2w)
    K = np.tile(np.array([[300.0, 0, 200], [0, 300, 150], [0, 0, 1]]), (n, 1, 1))
    return SfmResult([f"v{i:02d}" for i in range(n)], K, np.array(c2w), np.tile([400, 300], (n, 1)), pts,
                     np.zeros((len(pts), 3), np.uint8), np.zeros(len(pts)), [np.zeros((0, 3))] * len(pts))


@pytest.fixture
def scrambled():
    """The truth scene under a random similarity (as COLMAP would return it), and that similarity."""
    rng = np.random.default_rng(3)
    truth = _scene(rng)
    s, R, t = 0.37, _rotation(rng), rng.normal(0, 5, 3)
    return truth, truth.transformed(s, R, t), (s, R, t)


def test_up_vector_is_orthogonal_to_the_level_camera_x_axes(scrambled):
    truth, model, (s, R, t) = scrambled
    np.testing.assert_allclose(up_vector(truth), [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(up_vector(model), R @ [0, 1, 0], atol=1e-12)


def test_up_vector_on_an_arc_is_not_tilted_toward_the_tree():
    """Cameras on a third of a ring, looking up at a tall tree: the mean camera up leans toward the
    tree by degrees; the level x axes give the true up."""
    full = _scene(np.random.default_rng(0), n_cams=12, pitch_target=4.0)
    arc = SfmResult(full.names[:4], full.K[:4], full.cam_to_world[:4], full.sizes[:4], full.points, full.colors,
                    full.errors, full.tracks)
    mean_up = -arc.cam_to_world[:, :3, 1].mean(0)
    mean_up /= np.linalg.norm(mean_up)
    assert np.degrees(np.arccos(mean_up[1])) > 5.0  # the bias the x axes avoid
    np.testing.assert_allclose(up_vector(arc), [0, 1, 0], atol=1e-9)
    # a narrow fan (two cameras 30 degrees apart): a little roll would tilt the x axes' normal far,
    # so the mean camera up
    fan = SfmResult(full.names[:2], full.K[:2], full.cam_to_world[:2], full.sizes[:2], full.points, full.colors,
                    full.errors, full.tracks)
    mean_fan = -fan.cam_to_world[:, :3, 1].mean(0)
    np.testing.assert_allclose(up_vector(fan), mean_fan / np.linalg.norm(mean_fan), atol=1e-12)
    # one camera, or cameras all facing one way: the mean camera up
    one = SfmResult(full.names[:1], full.K[:1], full.cam_to_world[:1], full.sizes[:1], full.points, full.colors,
                    full.errors, full.tracks)
    np.testing.assert_allclose(up_vector(one), -one.cam_to_world[0, :3, 1], atol=1e-12)


def test_ground_plane_finds_the_ground_under_the_boxes(scrambled):
    truth, model, (s, R, t) = scrambled
    plane = ground_plane(model, seed=0)
    assert isinstance(plane, Plane)
    np.testing.assert_allclose(plane.normal, R @ [0, 1, 0], atol=0.01)
    h = plane.height(model.points[:600]) / s  # the ground points, in metres
    assert np.median(np.abs(h)) < 0.01
    assert plane.inliers > 300
    again = ground_plane(model, seed=0)
    assert again.offset == plane.offset and np.array_equal(again.normal, plane.normal)


def test_camera_height_scale_gives_metres(scrambled):
    truth, model, (s, R, t) = scrambled
    plane = ground_plane(model, seed=0)
    assert camera_height_scale(model, plane) == pytest.approx(1 / s, rel=0.02)
    assert camera_height_scale(model, plane, eye_height=3.2) == pytest.approx(2 / s, rel=0.02)
    with pytest.raises(InputError, match="eye_height"):
        camera_height_scale(model, plane, eye_height=0)
    flipped = Plane(-plane.normal, -plane.offset)
    with pytest.raises(SfmError, match="not above the ground"):
        camera_height_scale(model, flipped)


def test_similarity_to_frame_puts_up_on_y_and_origin_at_zero(scrambled):
    truth, model, (s, R, t) = scrambled
    up = up_vector(model)
    origin = s * R @ [0, 0, 0] + t  # the truth origin, in the model
    out = similarity_to_frame(model, origin=origin, up=up, scale=1 / s)
    np.testing.assert_allclose(up_vector(out), [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(np.median(out.centers[:, 1]), EYE, atol=1e-9)
    np.testing.assert_allclose(out.points, truth.points @ frame_rotation(truth, [0, 1, 0]).T, atol=1e-9)
    # camera 0 looks toward -Z
    fwd = out.cam_to_world[0, :3, 2]
    assert fwd[2] < 0 and abs(fwd[0]) < 1e-9
    tf = out.meta["to_frame"]
    np.testing.assert_allclose(tf["scale"] * model.points @ np.array(tf["rotation"]).T + tf["translation"],
                               out.points, atol=1e-6)
    with pytest.raises(InputError, match="scale"):
        similarity_to_frame(model, origin=origin, up=up, scale=-1)
    with pytest.raises(InputError, match="up"):
        similarity_to_frame(model, origin=origin, up=[0, 0, 0], scale=1)


def test_to_tree_frame_on_a_synthetic_model(scrambled):
    truth, model, _ = scrambled
    out = to_tree_frame(model)
    assert out.meta["frame"]["up_source"] == "ground" and out.meta["frame"]["scale_source"] == "eye_height"
    np.testing.assert_allclose(np.median(out.centers[:, 1]), EYE, atol=1e-9)
    assert np.median(np.abs(out.points[:600, 1])) < 0.01  # the ground at y = 0
    s, R, t = umeyama(out.centers, truth.centers)
    assert s == pytest.approx(1.0, rel=0.02) and np.linalg.norm(t) < 0.05  # origin at the ring's centre


def test_to_tree_frame_on_the_rendered_capture(sfm_result, capture):
    out = to_tree_frame(sfm_result, seed=0)
    np.testing.assert_allclose(np.median(out.centers[:, 1]), EYE, atol=1e-9)
    cam_up = up_vector(out)
    assert np.degrees(np.arccos(cam_up[1])) < 2.0
    frame = out.meta["frame"]
    assert frame["up_source"] == "ground" and frame["ground_inliers"] >= 30
    low = out.points[np.abs(out.points[:, 1]) < 0.05]
    assert len(low) >= 30  # a ground at y ~ 0
    tj = truth_cameras_json(capture[1])
    T = np.array([tj[n]["cam_to_world"] for n in out.names])
    s, R, t = umeyama(out.centers, T[:, :3, 3])
    assert s == pytest.approx(1.0, rel=0.05)  # eye height gives metres
    assert np.degrees(np.arccos((np.trace(R) - 1) / 2)) < 2.0  # the truth is Y up with camera 0 on +Z
    assert np.linalg.norm(t) < 0.3  # the origin where the cameras look, on the ground


def test_ground_plane_needs_points_below_the_cameras(scrambled):
    truth, _, _ = scrambled
    high = SfmResult(truth.names, truth.K, truth.cam_to_world, truth.sizes, np.array([[0, 5.0, 0], [1, 5, 0]]),
                     np.zeros((2, 3), np.uint8), np.zeros(2), [np.zeros((0, 3))] * 2)
    with pytest.raises(SfmError, match="cannot find the ground"):
        ground_plane(high)


def test_to_tree_frame_without_a_level_plane_uses_the_lowest_points(scrambled):
    truth, _, _ = scrambled
    rng = np.random.default_rng(5)
    x = rng.uniform(-2, 2, 400)
    slope = np.column_stack([x, 0.8 * (x + 2), rng.uniform(-2, 2, 400)])  # a 39° bank, lowest at y = 0
    model = SfmResult(truth.names, truth.K, truth.cam_to_world, truth.sizes, slope, np.zeros((400, 3), np.uint8),
                      np.zeros(400), [np.zeros((0, 3))] * 400)
    with pytest.raises(SfmError, match="no plane within 30 degrees"):
        ground_plane(model)
    out = to_tree_frame(model)
    assert out.meta["frame"]["ground_source"] == "lowest_points" and out.meta["frame"]["up_source"] == "cameras"
    np.testing.assert_allclose(up_vector(out), [0, 1, 0], atol=1e-9)
    assert np.quantile(out.points[:, 1][out.points[:, 1] < np.median(out.centers[:, 1])], 0.05) == pytest.approx(0)
