"""A flat ground for scenes of trees (forests, a photo's group of trees): one quad at y = 0."""

from __future__ import annotations

import numpy as np

__all__ = ["ground_plane"]


def ground_plane(x0: float, x1: float, z0: float, z1: float, rgb=(0.33, 0.38, 0.22)):
    """A MeshPart: the rectangle [x0, x1] x [z0, z1] of the plane y = 0, facing up, one colour.

    >>> p = ground_plane(-1, 1, -2, 2)
    >>> p.positions[:, 1].tolist(), p.n_triangles
    ([0.0, 0.0, 0.0, 0.0], 2)
    """
    from treeform.structures.mesh import Material, MeshPart

    pos = np.array([[x0, 0, z0], [x1, 0, z0], [x1, 0, z1], [x0, 0, z1]], np.float32)
    return MeshPart(positions=pos, normals=np.tile([0, 1, 0], (4, 1)).astype(np.float32),
                    uvs=np.zeros((4, 2), np.float32), colors=np.ones((4, 4), np.float32),
                    indices=np.array([[0, 2, 1], [0, 3, 2]], np.uint32),
                    material=Material(name="ground", base_color=(*(float(c) for c in rgb), 1.0)))
