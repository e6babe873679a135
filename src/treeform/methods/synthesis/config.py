"""Configuration of the analysis-by-synthesis method (seed 004 §3–§5)."""

from __future__ import annotations

import numbers
from dataclasses import asdict, dataclass

from treeform._shared.defaults import DEFAULT_SEGMENTER
from treeform._shared.checks import check_choice, check_height, check_int, check_known_options, check_range
from treeform._shared.errors import InputError

SPECIES_PRIORS = {
    #          first-order branches: mean, sd; cut-angle tolerance (deg); crown ("round" / "conical")
    "oak": (6.0, 1.5, 25.0),
    "maple": (5.0, 1.5, 25.0),
    "apple": (5.0, 1.5, 30.0),
    "acacia": (4.0, 1.5, 35.0),
    "birch": (5.0, 1.5, 20.0),
    "willow": (5.0, 1.5, 30.0),
    "pine": (8.0, 2.0, 15.0),
}
"""Species knowledge p(M) of seed 004 §5 eq. (4): the number n of first-order branches is a
Gaussian of this mean and standard deviation (the paper's vine prior is a Gaussian on the
number of shoots); the third value is the tolerance of the cut-angle condition of §3.5 (the
tree version of the τ balance: a species prior for trees)."""

LEAF_DENSITIES = (6.5, 9.0, 12.0)
"""Leaf densities the candidates try (multiplier of the preset's leaves per skeleton node)."""

LEAF_SPREADS = (1.25, 1.5, 1.8)
"""Leaf distributions the candidates try (multiplier of the foliage radius R the stems reach)."""


@dataclass
class SynthesisConfig:
    """Every knob of :func:`treeform.methods.synthesis.pipeline.reconstruct` (seed 004)."""

    seed: int = 0
    """Random seed: same photo + seed -> byte-identical skeleton.json."""
    candidates: int = 24
    """Models generated and scored by the reprojection error (§5, best of N); 1 = no search."""
    species: str | None = None
    """Species whose L-system preset and priors are used; None: the species network's guess."""
    n_branches: int | None = None
    """First-order branches of the skeleton; None: the candidates draw n from the species prior."""
    levels: int = 2
    """Branch orders the skeletonisation recurses to (§3.5)."""
    segmenter: str = DEFAULT_SEGMENTER
    """Tree segmentation: 'learned' (the network, default) or 'classical' (colour rules + graph cut)."""
    max_size: int = 640
    """Long side in pixels the photo is reduced to before any work."""
    tree_height: float = 10.0
    """Assumed height of the tree in metres (a single photo has no absolute scale)."""
    fov_y: float = 40.0
    """Vertical field of view of the photo's camera in degrees."""
    search_size: int = 224
    """Height in pixels of the candidates' silhouette renders (the photo's mask is reduced to it)."""
    prune: bool = True
    """Fit the leaves to the photo's silhouette: drop those projecting outside it, shrink the
    cards that would overhang it (the image constrains the generative model; without it only
    the search does)."""
    bole: float = 0.1
    """Share of the tree's height below which the generative model grows no twigs: the L-system's twigs
    on the lowest main branches hung down round the trunk's foot as a bush of stems; leaves may still
    hang lower from the wood above (as the envelope and learned routes' bole; 0: twigs anywhere)."""
    beyond_frame: bool = True
    """Continue a crown the photo's top or side edges cut past them, rounded
    (:func:`treeform.crown.frame.beyond_frame`): the 2D skeleton is drawn on the continued crown, the
    tree's height counts its continued top and the leaves may grow past the frame (the search still
    scores the photo's own view), instead of cutting the model flat at the frame."""
    leaves: int | None = None
    """Cap on the number of leaf cards of the final model; None: what the preset grows."""
    lod: str = "medium"
    """Level of detail: 'low' (20k triangles), 'medium' (60k), 'high' (200k), 'full' (no bound)."""
    texture_size: int | None = None
    """Bark texture edge N in texels (leaves get N/2); None: from the tree's size."""
    leaf_texture: str = "photo"
    """Leaf cards' texture: 'photo' (each card a tile of the photo's crown as the camera sees
    it, the cards the camera sees turned toward it; :func:`treeform.crown.photo_leaf_atlas`) or
    'procedural' (Bézier-outlined leaves, one photo colour per card)."""

    def validate(self) -> "SynthesisConfig":
        if isinstance(self.seed, bool) or not isinstance(self.seed, numbers.Integral):
            raise InputError(f"seed: expected an integer, got {self.seed!r}")
        check_int(self.candidates, "candidates", 1, 10_000)
        if self.species is not None:
            check_choice(self.species, "species", tuple(SPECIES_PRIORS))
        if self.n_branches is not None:
            check_int(self.n_branches, "n_branches", 1, 32)
        check_int(self.levels, "levels", 1, 3)
        check_choice(self.segmenter, "segmenter", ("learned", "classical"))
        check_int(self.max_size, "max_size", 32, 8192)
        check_height(self.tree_height)
        if not 5 <= self.fov_y <= 120:
            raise InputError(f"fov_y: expected 5..120 degrees, got {self.fov_y}")
        check_int(self.search_size, "search_size", 32, 2048)
        if self.leaves is not None:
            check_int(self.leaves, "leaves", 0, 2_000_000)
        from treeform.geometry import LOD_PRESETS

        check_choice(self.lod, "lod", tuple(LOD_PRESETS))
        check_choice(self.leaf_texture, "leaf_texture", ("photo", "procedural"))
        check_range(self.bole, "bole", 0.0, 0.5)
        if not isinstance(self.beyond_frame, bool):
            raise InputError(f"beyond_frame: expected true or false, got {self.beyond_frame!r}")
        if self.texture_size is not None:
            check_int(self.texture_size, "texture_size", 16, 8192)
        return self

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "SynthesisConfig":
        return cls(**check_known_options(cls, d)).validate()
