"""Rig: the joints of a skinned tree and their looping animation (what the animated GLB writer reads)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from treeform._shared.errors import InputError


@dataclass
class Rig:
    """Joints at branch pivots and their local rotations over one loop.

    Parameters
    ----------
    pivots : ndarray, shape (J, 3), float64
        Rest position of each joint (the point its branch turns about), metres, Y up.
    parent : ndarray, shape (J,), int64
        Parent joint, -1 for the root (joint 0); every parent index is smaller than its
        child's.
    times : ndarray, shape (N,), float64
        Keyframe times in seconds, strictly increasing from 0; the last is the loop's period
        and its pose equals the first.
    rotations : ndarray, shape (N, J, 4), float64
        Each joint's rotation relative to its parent at each keyframe, unit quaternions
        (x, y, z, w) as glTF stores them.

    Examples
    --------
    >>> r = Rig(np.zeros((1, 3)), np.array([-1]), np.array([0.0, 1.0]), np.tile([0, 0, 0, 1.0], (2, 1, 1)))
    >>> r.n_joints, r.period
    (1, 1.0)
    """

    pivots: np.ndarray
    parent: np.ndarray
    times: np.ndarray
    rotations: np.ndarray

    def __post_init__(self):
        self.pivots = np.ascontiguousarray(self.pivots, np.float64).reshape(-1, 3)
        self.parent = np.ascontiguousarray(self.parent, np.int64).reshape(-1)
        self.times = np.ascontiguousarray(self.times, np.float64).reshape(-1)
        self.rotations = np.ascontiguousarray(self.rotations, np.float64)
        self.validate()

    @property
    def n_joints(self) -> int:
        return len(self.pivots)

    @property
    def period(self) -> float:
        return float(self.times[-1])

    def validate(self) -> None:
        j = len(self.pivots)
        if j < 1:
            raise InputError("Rig: needs at least one joint")
        if self.parent.shape != (j,) or self.parent[0] != -1 or np.any(self.parent[1:] < 0) \
                or np.any(self.parent[1:] >= np.arange(1, j)):
            raise InputError("Rig.parent: joint 0 must be the only root and every parent precede its child")
        if len(self.times) < 2 or self.times[0] != 0.0 or np.any(np.diff(self.times) <= 0):
            raise InputError("Rig.times: expected at least two strictly increasing times from 0")
        if self.rotations.shape != (len(self.times), j, 4):
            raise InputError(f"Rig.rotations: expected shape {(len(self.times), j, 4)}, got {self.rotations.shape}")
        if not (np.all(np.isfinite(self.pivots)) and np.all(np.isfinite(self.rotations))):
            raise InputError("Rig: pivots and rotations must be finite")
        if np.any(np.abs(np.linalg.norm(self.rotations, axis=-1) - 1.0) > 1e-6):
            raise InputError("Rig.rotations: expected unit quaternions")

    def pose(self, k: int) -> np.ndarray:
        """(J, 4, 4) world matrices of the joints at keyframe ``k`` relative to the rest pose:
        a rest-pose point ``p`` bound to joint ``j`` moves to ``pose[j] @ [p, 1]``."""
        world = np.empty((self.n_joints, 4, 4))
        for j in range(self.n_joints):
            local = np.eye(4)
            local[:3, :3] = quat_to_matrix(self.rotations[k, j])
            offset = self.pivots[j] - (self.pivots[self.parent[j]] if j else 0.0)
            local[:3, 3] = offset
            world[j] = local if j == 0 else world[self.parent[j]] @ local
        bind = np.tile(np.eye(4), (self.n_joints, 1, 1))
        bind[:, :3, 3] = -self.pivots
        return world @ bind


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """(3, 3) rotation matrix of a unit quaternion (x, y, z, w).

    >>> np.allclose(quat_to_matrix(np.array([0, 0, np.sin(np.pi / 4), np.cos(np.pi / 4)])) @ [1, 0, 0], [0, 1, 0])
    True
    """
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
