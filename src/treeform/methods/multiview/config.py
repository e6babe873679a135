"""Configuration of the multi-view route (seed 002)."""

from __future__ import annotations

from dataclasses import asdict, dataclass

from treeform._shared.checks import check_choice, check_height, check_int, check_positive
from treeform._shared.errors import InputError

__all__ = ["MultiviewConfig", "HIDDEN_GROWTHS", "LEAF_PLACEMENTS", "LEAF_TEXTURES", "MATTE_ZOOM"]

LEAF_TEXTURES = ("photo", "procedural")
"""Leaf card textures of the multi-view route."""

HIDDEN_GROWTHS = ("colonization", "replication")
"""Growths of the hidden branches (``MultiviewConfig.hidden_growth``)."""

LEAF_PLACEMENTS = ("surface", "segments")
"""Leaf placements of the multi-view route (``MultiviewConfig.leaf_placement``)."""

MATTE_ZOOM = 1.25
"""Default of ``matte_side``: the network sees each matte at this many times its long side."""


@dataclass
class MultiviewConfig:
    """Options of :func:`treeform.methods.multiview.pipeline.reconstruct_multiview`."""

    seed: int = 0
    """Random seed (growth of the hidden branches, leaves)."""
    height: float | None = None
    """Tree height in metres; None: metric scale from the cameras at eye height (``eye_height``)."""
    eye_height: float = 1.6
    """Height of the camera above the ground in metres when no ``height`` is given (a phone at eye level)."""
    max_size: int = 1024
    """Long side of the photos for structure from motion (pixels)."""
    mask_size: int = 768
    """Long side of the photos for segmentation and carving (pixels). Finer mattes carve a finer hull
    and open more of the crown's gaps (on the 24-view 1024-px oak capture, with ``matte_side`` the
    same, novel-view IoU 0.775 at 512 (``matte_side`` 640), 0.782 at 640, 0.787 at 768, 0.797 at 1024,
    which costs 60 s more than 768; BENCHMARKS.md)."""
    segmenter: str = "learned"
    """Tree matting per view: 'learned' (the network) or 'classical' (the colour rules)."""
    matte_side: int | None = None
    """Long side, in pixels, at which the learned segmenter sees each view (its own default for a
    single photo is 320). None: ``MATTE_ZOOM`` (1.25) times the matte's own long side, so a tree that
    fills most of a capture's frame is seen closer to the scale of its gaps and limbs (on the 24-view
    1024-px oak capture, 512-px mattes: novel-view IoU 0.748 when the network sees them at 320, 0.775
    at 640; 768-px mattes: 0.787 at 768, 0.792 at 960; BENCHMARKS.md). 0: the segmenter's default."""
    sky_gaps: bool = True
    """Foliage pixels of each matte coloured like the sky above the tree become background
    (:func:`~treeform.segment.matting.sky_gaps`): the small sky gaps the segmenter fills in are
    carved through the crown (on the 24-view oak capture the mattes' IoU with the true tree rises
    from 0.758 to 0.790, novel-view IoU from 0.792 to 0.802). Not applied to ``--masks``."""
    thin_wood: bool = True
    """Add thin dark ridges against the sky near the tree to the segmenter's mattes as wood (the twigs
    its stride loses; the carving keeps those the views agree on). Not applied to ``--masks``."""
    tile_wood: bool = True
    """Add the wood the learned segmenter sees on tiles of each photo at its own resolution (inside and
    outside the matte; the carving keeps what the views agree on in 3D), for photos at least twice the
    network's view (``pipeline.TILE_WOOD_FROM``). Only with ``segmenter`` 'learned', not applied to
    ``--masks``."""
    refine_poses: bool = True
    """Turn each camera about its centre so that the visual hull of the other views' mattes fills its
    own (silhouette coherence, :mod:`treeform.methods.multiview.coherence`): the SfM registers the photos
    on the far scene and can leave every camera a few pixels off about the tree (on the 24-view 1024-px
    capture, 2.5 px median; 0.8 px after)."""
    cells: int = 400
    """Finest carving cell (thin branches) = tree height / cells."""
    surface_cells: int = 200
    """Carving cell on the crown's surface (where the leaves go) = tree height / surface_cells."""
    tolerance: float = 0.25
    """Share of the views whose mask may miss a piece of the tree (occluders, segmentation errors)."""
    direction_weight: float = 1.0
    """The hidden branches' growth: weight of each node's own direction beside the direction to its
    attractors (:func:`~treeform.growth.space_colonization.space_colonization`; 0: Runions's rule)."""
    leaves: int = 15000
    """Leaf clusters (most on the crown's surface seen in the photos, the rest on the twigs inside)."""
    leaf_texture: str = "photo"
    """'photo': each leaf card shows the photo that sees it best, carved texel by texel against every
    view's matte (the crown's texture and gaps: novel-view IoU 0.658 -> 0.715 on the 24-view 1024-px
    capture, 0.642 -> 0.735 on its 480-px twin, side IoU better on 4 of the evaluation's 6 registered
    captures; BENCHMARKS.md); 'procedural': drawn leaf clusters tinted with the photos' colours (a GLB
    of about 5 MB instead of 13 MB at 15,000 clusters)."""
    hidden_growth: str = "replication"
    """How the branches the photos do not see are grown from the visible ones. 'colonization': the
    project's space colonization toward the carved leaf points. 'replication': seed 002 §5.2 -- first
    the visible skeleton's own subtrees (replication blocks), each turned about its primary branch and
    scaled onto an end branch it replaces, cut at the carved hull; then the constrained growth toward the
    leaf points with 90-degree influence cones (:mod:`treeform.methods.multiview.replication`). On the
    24-view oak capture: novel-view IoU 0.802 -> 0.804, skeleton 1.51 -> 0.81 % (BENCHMARKS.md)."""
    leaf_placement: str = "surface"
    """Where the leaf clusters go. 'surface': on the crown's surface the views' silhouettes carve, in
    proportion to its area, the rest on the grown twigs. 'segments': seed 002 §6 -- each view's foliage
    cut into leaf regions (mean shift in LUV, split or merge, the brightest colour clusters, ellipses),
    each placed on the leaf point along its centroid's line of sight and turned to the SVD plane of the
    points seen in it, de-duplicated across views, and the sparsest third of the branches given the
    leaves of the densest, round after round until ``leaves`` are placed
    (:mod:`treeform.methods.multiview.leaf_segments`)."""
    lod: str = "medium"
    """Triangle budget (see treeform.geometry.LOD_PRESETS)."""

    def validate(self) -> MultiviewConfig:
        from treeform._shared.defaults import SEGMENTERS
        from treeform._shared.rng import as_rng
        from treeform.geometry import LOD_PRESETS

        as_rng(self.seed)
        if self.height is not None:
            self.height = check_height(self.height, "height")
        check_positive(self.eye_height, "eye_height")
        check_int(self.max_size, "max_size", 128, 8192)
        check_int(self.mask_size, "mask_size", 64, 4096)
        if self.matte_side:
            check_int(self.matte_side, "matte_side", 64, 4096)
        check_choice(self.segmenter, "segmenter", SEGMENTERS)
        for name in ("thin_wood", "tile_wood", "sky_gaps", "refine_poses"):
            if not isinstance(getattr(self, name), bool):
                raise InputError(f"{name}: expected True or False, got {getattr(self, name)!r}")
        check_int(self.cells, "cells", 50, 2000)
        check_int(self.surface_cells, "surface_cells", 10, 2000)
        if not 0.0 <= float(self.tolerance) < 0.5:
            raise InputError(f"tolerance: expected a share in [0, 0.5), got {self.tolerance!r}")
        check_positive(self.direction_weight, "direction_weight", allow_zero=True)
        check_int(self.leaves, "leaves", 0, 1_000_000)
        check_choice(self.leaf_texture, "leaf_texture", LEAF_TEXTURES)
        check_choice(self.leaf_placement, "leaf_placement", LEAF_PLACEMENTS)
        check_choice(self.hidden_growth, "hidden_growth", HIDDEN_GROWTHS)
        check_choice(self.lod, "lod", tuple(LOD_PRESETS))
        return self

    def to_dict(self) -> dict:
        return asdict(self)
