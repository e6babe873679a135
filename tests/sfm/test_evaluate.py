"""umeyama and pose_errors against known cameras."""

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.sfm import SfmResult
from treeform.sfm.evaluate import opencv_camera, pose_errors, truth_cameras_json, umeyama
from treeform.structures import Camera


def _rotation(rng):
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return q * np.sign(np.linalg.det(q))


def test_umeyama_recovers_a_similarity():
    rng = np.random.default_rng(0)
    src = rng.normal(size=(20, 3))
    R, t = _rotation(rng), rng.normal(size=3)
    s, R2, t2 = umeyama(src, 2.5 * src @ R.T + t)
    assert s == pytest.approx(2.5) and np.allclose(R2, R) and np.allclose(t2, t)
    s, R2, t2 = umeyama(src, src @ R.T + t, with_scale=False)
    assert s == 1.0 and np.allclose(R2, R)
    # a mirrored target still gives a rotation
    s, R2, _ = umeyama(src, src * [1, 1, -1])
    assert np.linalg.det(R2) == pytest.approx(1.0)
    with pytest.raises(InputError, match="same"):
        umeyama(src, src[:5])


def _cameras(n=8):
    return {f"v{k}.jpg": Camera(400, 300, 50.0, (3 * np.sin(a), 1.6, 3 * np.cos(a)), (0, 0.2, 0))
            for k, a in enumerate(np.linspace(0, 2 * np.pi, n, endpoint=False))}


def _result_from(cams, names, s=1.0, R=np.eye(3), t=np.zeros(3)):
    Ks, Ts = zip(*(opencv_camera(cams[n]) for n in names))
    res = SfmResult(list(names), np.array(Ks), np.array(Ts), np.tile([400, 300], (len(names), 1)), np.zeros((0, 3)),
                    np.zeros((0, 3), np.uint8), np.zeros(0), [])
    return res.transformed(s, R, t)


def test_opencv_camera_projects_like_the_treeform_camera():
    cam = _cameras()["v1.jpg"]
    res = _result_from({"a": cam}, ["a"])
    pts = np.random.default_rng(1).normal(0, 0.5, (10, 3))
    np.testing.assert_allclose(res.project(pts, 0), cam.project(pts), atol=1e-9)


def test_pose_errors_are_zero_for_the_truth_under_a_similarity():
    cams = _cameras()
    rng = np.random.default_rng(2)
    res = _result_from(cams, sorted(cams), 0.3, _rotation(rng), rng.normal(size=3))
    e = pose_errors(res, truth_cameras_json(cams))
    assert e["registration_rate"] == 1.0 and e["scale"] == pytest.approx(1 / 0.3)
    assert e["position_max"] < 1e-9 and e["rotation_max_deg"] < 1e-5 and e["focal_max_rel"] < 1e-12
    assert e["scene_size"] == pytest.approx(6.0)


def test_pose_errors_measure_a_moved_camera_and_missing_ones():
    cams = _cameras()
    names = sorted(cams)[:6]
    res = _result_from(cams, names)
    res.cam_to_world[2, :3, 3] += [0.6, 0, 0]
    e = pose_errors(res, truth_cameras_json(cams))
    assert e["registered"] == 6 and e["registration_rate"] == pytest.approx(0.75)
    assert 0.3 < e["position_max"] < 0.7 and e["position_max_rel"] == pytest.approx(e["position_max"] / 6.0)
    few = pose_errors(_result_from(cams, names[:2]), truth_cameras_json(cams))
    assert few["registered"] == 2 and few["position_median"] is None
    with pytest.raises(InputError, match="truth_cameras_json"):
        pose_errors(res, {})
