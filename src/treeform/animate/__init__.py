"""Animation: rod dynamics of a tree's branches in the wind, exported as a looping skinned glTF."""

from treeform.animate.joints import TreeJoints, tree_joints
from treeform.animate.skin import skin_weights
from treeform.animate.wind import joint_mechanics, wind_sway
from treeform.animate.tree import animate_tree, sway_checks

__all__ = ["TreeJoints", "tree_joints", "skin_weights", "joint_mechanics", "wind_sway", "animate_tree", "sway_checks"]
