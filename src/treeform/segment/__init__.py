"""Photo -> :class:`~treeform.structures.Segmentation` (background / foliage / wood).

``segment`` finds the one main tree of an ordinary outdoor photo without user input, with
the learned network (:func:`segment_tree_learned`, the :data:`DEFAULT_SEGMENTER`) or the
colour rules of :func:`segment_tree`; ``mask_to_segmentation`` labels a user-supplied tree
mask.
"""

from treeform._shared.defaults import DEFAULT_SEGMENTER, SEGMENTERS
from treeform.segment.classical import mask_to_segmentation, segment_tree, wood_colour_mask
from treeform.segment.learned import segment_tree_learned

__all__ = ["segment", "SEGMENTERS", "DEFAULT_SEGMENTER", "segment_tree", "segment_tree_learned",
           "mask_to_segmentation", "wood_colour_mask"]


def segment(image, *, method: str = DEFAULT_SEGMENTER, seed: int = 0, require_tree: bool = False):
    """Segment the main tree of an (H, W, 3) uint8 photo with ``method`` ('learned' or 'classical').

    The classical graph cut uses ``seed``; the network is deterministic. The colour rules
    find a "tree" in anything green or textured enough, random noise included: with
    ``require_tree`` (what the photo commands ask) the network, without its edge refinement
    (~0.05 s), is asked first whether the photo holds a tree at all, and
    :class:`~treeform._shared.errors.NoTreeFoundError` is raised when it does not (without
    usable weights the rules go on alone).
    """
    from treeform._shared.checks import check_choice
    from treeform._shared.rng import as_rng

    check_choice(method, "segmenter", SEGMENTERS)
    as_rng(seed)  # a negative or non-integer seed is one clear error, whichever segmenter runs
    if method == "learned":
        return segment_tree_learned(image)
    if require_tree:
        from treeform._shared.errors import ModelError

        try:
            segment_tree_learned(image, refine="none")
        except ModelError:
            pass
    return segment_tree(image, seed=seed)


from treeform.segment.matting import alpha_matting, estimate_foreground, make_trimap, matte_tree  # noqa: E402

__all__ += ["make_trimap", "alpha_matting", "estimate_foreground", "matte_tree"]
