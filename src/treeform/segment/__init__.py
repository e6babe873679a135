"""Photo -> :class:`~treeform.structures.Segmentation` (background / foliage / wood).

``segment_tree`` finds the one main tree of an ordinary outdoor photo without user
input; ``mask_to_segmentation`` labels a user-supplied tree mask.
"""

from treeform.segment.classical import mask_to_segmentation, segment_tree, wood_colour_mask

__all__ = ["segment_tree", "mask_to_segmentation", "wood_colour_mask"]

from treeform.segment.matting import alpha_matting, estimate_foreground, make_trimap, matte_tree  # noqa: E402

__all__ += ["make_trimap", "alpha_matting", "estimate_foreground", "matte_tree"]
