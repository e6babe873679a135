"""2D skeletonisation of foliage silhouettes (seed 004 §3).

The generalized potential field of a shape (:func:`force_field`, Cornea et al. with the
probability map of eq. (1)), Discrete Curve Evolution (:func:`dce`), cuts that split the
silhouette into one area per branch and Catmull-Rom branches through the attracting points
(:func:`foliage_skeleton` -> :class:`Skeleton2D`), the skeleton of visible wood as shortest
paths to the base (:func:`wood_skeleton`, for leafless and sparse crowns; the base is
:func:`trunk_foot`), depth from the revolved convex hull
(:func:`lift_to_3d`) and an overlay for figures (:func:`draw_skeleton`).

Coordinates are pixels ``(x, y)`` = (column, row), ``y`` down, until :func:`lift_to_3d`
turns them into metres (Y up, base at the origin, +z toward the camera).
"""

from treeform.skeleton.dce import dce
from treeform.skeleton.depth import lift_to_3d, revolved_radius, skeleton_hull, touches_hull
from treeform.skeleton.draw import draw_skeleton
from treeform.skeleton.field import force_field
from treeform.skeleton.foliage import Skeleton2D, foliage_skeleton
from treeform.skeleton.wood import WOOD_VISIBLE, trunk_foot, wood_fraction, wood_skeleton, wood_visible

__all__ = ["force_field", "dce", "Skeleton2D", "foliage_skeleton", "lift_to_3d", "draw_skeleton",
           "skeleton_hull", "revolved_radius", "touches_hull", "wood_skeleton", "wood_fraction", "wood_visible",
           "WOOD_VISIBLE", "trunk_foot"]
