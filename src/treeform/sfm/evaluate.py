"""How well structure from motion recovered known cameras (seed 002 §3; synthetic cases with truth).

:func:`pose_errors` aligns the registered camera centres to the true ones by a similarity
(:func:`umeyama`: SfM fixes the world only up to scale, rotation and translation) and reports
registration rate, position, rotation and focal-length errors.
"""

from __future__ import annotations

import numpy as np

from treeform._shared.errors import InputError
from treeform.sfm.result import SfmResult

__all__ = ["umeyama", "pose_errors", "opencv_camera", "truth_cameras_json"]


def umeyama(src, dst, with_scale: bool = True) -> tuple[float, np.ndarray, np.ndarray]:
    """Least-squares similarity ``dst ~ s * R @ src + t`` (Umeyama 1991).

    Parameters
    ----------
    src, dst : array_like, shape (N, D)
        Corresponding points, N >= D (not all on one line).
    with_scale : bool
        Estimate ``s``; otherwise ``s = 1`` (a rigid fit).

    Returns
    -------
    s : float
    R : ndarray, shape (D, D)
        A rotation (det +1).
    t : ndarray, shape (D,)

    Examples
    --------
    >>> src = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
    >>> s, R, t = umeyama(src, 2 * src + [1, 2, 3])
    >>> round(s, 6), np.allclose(R, np.eye(3)), np.round(t, 6).tolist()
    (2.0, True, [1.0, 2.0, 3.0])
    """
    src = np.asarray(src, np.float64)
    dst = np.asarray(dst, np.float64)
    if src.ndim != 2 or src.shape != dst.shape:
        raise InputError(f"umeyama: src and dst must have the same (N, D) shape, got {src.shape} and {dst.shape}")
    n, d = src.shape
    if n < 2 or not (np.all(np.isfinite(src)) and np.all(np.isfinite(dst))):
        raise InputError(f"umeyama: need at least 2 finite point pairs, got {n}")
    mu_s, mu_d = src.mean(0), dst.mean(0)
    xs, xd = src - mu_s, dst - mu_d
    cov = xd.T @ xs / n
    U, S, Vt = np.linalg.svd(cov)
    E = np.ones(d)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        E[-1] = -1.0
    R = U @ np.diag(E) @ Vt
    var_s = float((xs ** 2).sum() / n)
    s = float((S * E).sum() / var_s) if (with_scale and var_s > 0) else 1.0
    t = mu_d - s * R @ mu_s
    return s, R, t


def opencv_camera(camera) -> tuple[np.ndarray, np.ndarray]:
    """A treeform :class:`~treeform.structures.Camera` as (K (3, 3), cam_to_world (4, 4), OpenCV axes).

    Pixel convention as :meth:`SfmResult.project` (principal point at the image centre).
    """
    r, u, f = camera.axes()
    T = np.eye(4)
    T[:3, 0], T[:3, 1], T[:3, 2], T[:3, 3] = r, -u, f, np.asarray(camera.position, np.float64)
    fl = camera.focal
    K = np.array([[fl, 0.0, camera.width / 2.0], [0.0, fl, camera.height / 2.0], [0.0, 0.0, 1.0]])
    return K, T


def truth_cameras_json(cameras: dict) -> dict:
    """``{name: Camera}`` -> the :meth:`SfmResult.cameras_json` format (for :func:`pose_errors`)."""
    out = {}
    for name, cam in cameras.items():
        K, T = opencv_camera(cam)
        out[name] = {"K": K.tolist(), "cam_to_world": T.tolist(), "size": [int(cam.width), int(cam.height)]}
    return out


def _angle_deg(Ra, Rb) -> float:
    """The angle of the rotation between ``Ra`` and ``Rb`` in degrees, precise near zero.

    ``arccos`` of the trace loses precision there (a rounding of 1e-7 in the trace reads as
    0.04 degrees); the sine from the skew part keeps it.

    >>> a = np.radians(1e-4); R = np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
    >>> round(_angle_deg(np.eye(3), R), 8)
    0.0001
    """
    M = np.asarray(Ra, np.float64).T @ np.asarray(Rb, np.float64)
    s = 0.5 * np.linalg.norm([M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1]])
    c = (np.trace(M) - 1.0) / 2.0
    return float(np.degrees(np.arctan2(s, c)))


def pose_errors(result: SfmResult, truth_cameras_json: dict) -> dict:
    """Registered cameras against the true ones, after a similarity alignment of the centres.

    Parameters
    ----------
    result : SfmResult
    truth_cameras_json : dict
        ``{name: {"K": 3x3, "cam_to_world": 4x4 (OpenCV axes), "size": [w, h]}}`` (the
        format of :meth:`SfmResult.cameras_json`; see :func:`truth_cameras_json`).

    Returns
    -------
    dict
        ``registered`` (count of true photos registered), ``total``, ``registration_rate``;
        ``scale``, ``rotation``, ``translation`` (the similarity result -> truth);
        ``scene_size`` (largest distance between two true camera centres);
        ``position_median``, ``position_max`` (truth units) and ``position_median_rel``,
        ``position_max_rel`` (fractions of ``scene_size``); ``rotation_median_deg``,
        ``rotation_max_deg``; ``focal_median_rel``, ``focal_max_rel`` (relative focal error,
        in pixels of the true image size). Error entries are None with fewer than 3 common
        cameras.
    """
    if not isinstance(truth_cameras_json, dict) or not truth_cameras_json:
        raise InputError("truth_cameras_json: expected a non-empty {name: {K, cam_to_world, size}} mapping")
    names = [n for n in result.names if n in truth_cameras_json]
    total = len(truth_cameras_json)
    out = {"registered": len(names), "total": total, "registration_rate": len(names) / total}
    keys = ("scale", "rotation", "translation", "scene_size", "position_median", "position_max",
            "position_median_rel", "position_max_rel", "rotation_median_deg", "rotation_max_deg",
            "focal_median_rel", "focal_max_rel")
    out.update(dict.fromkeys(keys))
    if len(names) < 3:
        return out
    idx = [result.names.index(n) for n in names]
    T_true = np.array([np.asarray(truth_cameras_json[n]["cam_to_world"], np.float64) for n in names])
    T_est = result.cam_to_world[idx]
    c_true, c_est = T_true[:, :3, 3], T_est[:, :3, 3]
    s, R, t = umeyama(c_est, c_true)
    pos = np.linalg.norm(s * c_est @ R.T + t - c_true, axis=1)
    rot = np.array([_angle_deg(R @ T_est[k, :3, :3], T_true[k, :3, :3]) for k in range(len(names))])
    foc = []
    for k, n in zip(idx, names):
        K_true = np.asarray(truth_cameras_json[n]["K"], np.float64)
        w_true = float(truth_cameras_json[n].get("size", result.sizes[k])[0])
        f_est = result.K[k, 0, 0] * w_true / float(result.sizes[k, 0])
        foc.append(abs(f_est - K_true[0, 0]) / K_true[0, 0])
    allc = np.array([np.asarray(v["cam_to_world"], np.float64)[:3, 3] for v in truth_cameras_json.values()])
    size = float(np.max(np.linalg.norm(allc[:, None] - allc[None], axis=2)))
    out.update({
        "scale": s, "rotation": R.tolist(), "translation": t.tolist(), "scene_size": size,
        "position_median": float(np.median(pos)), "position_max": float(pos.max()),
        "position_median_rel": float(np.median(pos)) / size if size > 0 else None,
        "position_max_rel": float(pos.max()) / size if size > 0 else None,
        "rotation_median_deg": float(np.median(rot)), "rotation_max_deg": float(rot.max()),
        "focal_median_rel": float(np.median(foc)), "focal_max_rel": float(np.max(foc)),
    })
    return out
