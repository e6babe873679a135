"""Data containers shared by every method: arrays plus ``validate()`` and save/load.

This folder imports numpy and :mod:`treeform._shared.errors` only (a test checks it).
"""

from treeform.structures.camera import Camera
from treeform.structures.foliage import Foliage
from treeform.structures.mesh import Material, Mesh, MeshPart
from treeform.structures.opacity import OpacityGrid
from treeform.structures.photo import Photo
from treeform.structures.rbv import RadialBoundingVolume
from treeform.structures.rdm import RadialDistanceMap
from treeform.structures.rig import Rig
from treeform.structures.segmentation import Segmentation
from treeform.structures.skeleton import TreeSkeleton

__all__ = [
    "Camera",
    "Foliage",
    "Material",
    "Mesh",
    "MeshPart",
    "OpacityGrid",
    "Photo",
    "RadialBoundingVolume",
    "RadialDistanceMap",
    "Rig",
    "Segmentation",
    "TreeSkeleton",
]
