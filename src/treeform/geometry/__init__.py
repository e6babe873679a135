"""Skeleton and foliage to triangle meshes: generalized-cylinder branches, leaf cards, LODs.

- :func:`branch_mesh` — one smooth tube per branch chain (parallel-transport frames).
- :func:`bspline_skeleton` — a coarse skeleton's branches as clamped cubic B-splines, resampled (seed 004 §4).
- :func:`leaf_cards`, :func:`leaf_texture` — alpha-masked leaf quads and their texture.
- :func:`tree_mesh`, :data:`LOD_PRESETS` — both parts under a triangle budget; :func:`foliage_budget` —
  how many (and how large) leaf clusters a budget keeps, to generate only those.
- :func:`tree_textures`, :func:`texture_sizes` — a tree's bark and leaf (broadleaf, needle, scale) textures.
- :func:`normal_map_from_height`, :func:`texture_height` — tangent-space normal maps.
- :mod:`treeform.geometry.billboard_cloud` — superpixel billboards, atlas, placement, cloud mesh (seed 000 §6).
"""

from treeform.geometry.curves import bspline_skeleton
from treeform.geometry.leaves import (CLUSTER_COVERAGE, leaf_cards, leaf_material, leaf_texture, opaque_cards,
                                      texture_coverage)
from treeform.geometry.lod import LOD_PRESETS, foliage_budget, plan_lod, tree_mesh
from treeform.geometry.opacity import opacity_grid
from treeform.geometry.normal_maps import normal_map_from_height, texture_height
from treeform.geometry.textures import FOLIAGE_KINDS, foliage_coverage, texture_sizes, tree_textures
from treeform.geometry.tubes import MIN_RING_RADIUS, bark_material, bark_texture, branch_mesh, tube_triangle_count

__all__ = [
    "CLUSTER_COVERAGE",
    "FOLIAGE_KINDS",
    "LOD_PRESETS",
    "MIN_RING_RADIUS",
    "bark_material",
    "bark_texture",
    "branch_mesh",
    "bspline_skeleton",
    "foliage_budget",
    "foliage_coverage",
    "leaf_cards",
    "leaf_material",
    "leaf_texture",
    "normal_map_from_height",
    "opacity_grid",
    "opaque_cards",
    "plan_lod",
    "texture_coverage",
    "texture_height",
    "texture_sizes",
    "tree_mesh",
    "tree_textures",
    "tube_triangle_count",
]
