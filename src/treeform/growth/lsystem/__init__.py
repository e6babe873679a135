"""Parametric bracketed stochastic L-systems in pure Python: the generative model of seed 004 §4.

- :func:`parse_lsystem`, :func:`load_preset`, :class:`LSystem` — grammar text (species presets in
  ``growth/species/lsystems/*.lsys``) and its derivation.
- :func:`interpret` — the 3D turtle: string -> TreeSkeleton + leaf cards.
- :func:`lsystem_tree` — a whole tree from a preset; :func:`dress_skeleton` — given main
  branches (a photo's skeleton) dressed with the preset's twigs and leaves.
"""

from treeform.growth.lsystem.dress import LSystemTree, dress_skeleton, lsystem_tree
from treeform.growth.lsystem.grammar import LSystem, load_preset, parse_lsystem, preset_names
from treeform.growth.lsystem.turtle import interpret

__all__ = ["LSystem", "LSystemTree", "dress_skeleton", "interpret", "load_preset", "lsystem_tree", "parse_lsystem",
           "preset_names"]
