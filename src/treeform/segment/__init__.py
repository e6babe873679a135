"""Photo -> :class:`~treeform.structures.Segmentation` (background / foliage / wood).

``segment`` finds the one main tree of an ordinary outdoor photo without user input, with
the learned network (:func:`segment_tree_learned`) or the colour rules of
:func:`segment_tree` (:data:`DEFAULT_SEGMENTER`); ``mask_to_segmentation`` labels a
user-supplied tree mask.
"""

from treeform.segment.classical import mask_to_segmentation, segment_tree, wood_colour_mask
from treeform.segment.learned import segment_tree_learned

__all__ = ["segment", "SEGMENTERS", "DEFAULT_SEGMENTER", "segment_tree", "segment_tree_learned",
           "mask_to_segmentation", "wood_colour_mask"]

SEGMENTERS = ("learned", "classical")
"""Names accepted by :func:`segment` (``--segmenter``)."""

DEFAULT_SEGMENTER = "classical"
"""The segmenter of the commands that segment a photo (reconstruct's envelope method, billboard, cloud,
segment) unless told otherwise. On real photos the colour rules still find the whole main tree
more reliably than the network trained so far (which misses some trees entirely; see
docs/MODELS.md and the README's grid); the learned method and ``treeform species`` use the
network, which their species and RBV networks were trained with."""


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

    check_choice(method, "segmenter", SEGMENTERS)
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
