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


def segment(image, *, method: str = DEFAULT_SEGMENTER, seed: int = 0, require_tree: bool = False,
            side: int | None = None, gaps: bool = True):
    """Segment the main tree of an (H, W, 3) uint8 photo with ``method`` ('learned' or 'classical').

    The classical graph cut uses ``seed``; the network is deterministic and sees the photo with
    its long side at ``side`` pixels (None: its weights' own, 320; the colour rules ignore it). The colour rules
    find a "tree" in anything green or textured enough, random noise included: with
    ``require_tree`` (what the photo commands ask) the network is also asked whether the photo
    holds a tree at all (its mask and the main part only: no edge refinement, trunk or holes;
    ~0.06 s, run beside the colour rules on a second core), and
    :class:`~treeform._shared.errors.NoTreeFoundError` is raised when it does not (without
    usable weights the rules go on alone). ``gaps`` is the network's: whether the gaps of the
    crown it filled are opened (:func:`segment_tree_learned`).
    """
    from treeform._shared.checks import check_choice
    from treeform._shared.rng import as_rng

    check_choice(method, "segmenter", SEGMENTERS)
    as_rng(seed)  # a negative or non-integer seed is one clear error, whichever segmenter runs
    if method == "learned":
        return segment_tree_learned(image, side=side, gaps=gaps)
    if not require_tree:
        return segment_tree(image, seed=seed)
    from concurrent.futures import ThreadPoolExecutor

    from treeform._shared.errors import ModelError

    def tree_present():
        try:
            segment_tree_learned(image, refine="none", trunk=False, fill_holes=0)
        except ModelError:
            pass

    # onnxruntime and the graph cut release the GIL: the two run side by side
    with ThreadPoolExecutor(max_workers=1) as pool:
        check = pool.submit(tree_present)
        try:
            seg, failure = segment_tree(image, seed=seed), None
        except Exception as exc:  # noqa: BLE001 -- the network's verdict comes first
            seg, failure = None, exc
        check.result()  # NoTreeFoundError (or a bad image) from the network
    if failure is not None:
        raise failure
    return seg


from treeform.segment.matting import alpha_matting, estimate_foreground, make_trimap, matte_tree  # noqa: E402

__all__ += ["make_trimap", "alpha_matting", "estimate_foreground", "matte_tree"]
