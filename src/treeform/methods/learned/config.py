"""Configuration of the grow pipeline of the learned method (seed 003 §4.3, Appendix Tables 2–3)."""

from __future__ import annotations

import numbers
from dataclasses import asdict, dataclass, field

from treeform._shared.checks import check_choice, check_height, check_int, check_positive, check_range
from treeform._shared.checks import check_known_options
from treeform._shared.errors import InputError


def _lod_names() -> tuple:
    from treeform.geometry import LOD_PRESETS

    return tuple(LOD_PRESETS)


def _check_common(cfg) -> None:
    """Checks shared by the learned method's configs: seed, lod, fov_y, foliage, texture size, leaves."""
    if isinstance(cfg.seed, bool) or not isinstance(cfg.seed, numbers.Integral):
        raise InputError(f"seed: expected an integer, got {cfg.seed!r}")
    check_choice(cfg.lod, "lod", _lod_names())
    if not 5 <= cfg.fov_y <= 120:
        raise InputError(f"fov_y: expected 5..120 degrees, got {cfg.fov_y}")
    check_choice(cfg.foliage, "foliage", ("auto", "broadleaf", "needles", "scales"))
    if cfg.texture_size is not None:
        check_int(cfg.texture_size, "texture_size", 16, 8192)
    if cfg.leaves is not None and (isinstance(cfg.leaves, bool) or not isinstance(cfg.leaves, numbers.Integral)
                                   or not 0 <= cfg.leaves <= 2_000_000):
        raise InputError(f"leaves: expected an integer in [0, 2000000] or None, got {cfg.leaves!r}")


def _check_ints(cfg, ranges) -> None:
    for name, lo, hi in ranges:
        v = getattr(cfg, name)
        if isinstance(v, bool) or not isinstance(v, numbers.Integral) or not lo <= v <= hi:
            raise InputError(f"{name}: expected an integer in [{lo}, {hi}], got {v!r}")


@dataclass
class GrowConfig:
    """Every knob of :func:`treeform.methods.learned.grow.grow_tree`."""

    species: str = "oak"
    """Species preset (acacia, apple, willow, maple, birch, oak, pine) or the path of a species
    JSON file (see :mod:`treeform.growth.species`)."""
    seed: int = 0
    """Random seed: same species + parameters + seed -> byte-identical skeleton.json."""
    params: dict = field(default_factory=dict)
    """Overrides of :class:`~treeform.growth.phenomenological.GrowthParameters` fields, e.g.
    ``{"age": 12}``."""
    leaves_per_twig: float = 3.0
    """Leaf clusters per twig node (a node carrying at most ``twig_tips`` tips), when
    ``leaves`` is None."""
    leaves: int | None = None
    """Total number of leaf clusters (alpha-textured cards); None: ``leaves_per_twig`` per twig.
    Under a triangle budget (``lod`` other than "full") this is the full-detail count: only the
    clusters the budget keeps are made, enlarged (:func:`treeform.geometry.foliage_budget`)."""
    twig_tips: int = 4
    """A node whose subtree holds at most this many tips is a twig: leaves hang on twigs."""
    leaf_size: float | None = None
    """Edge length of a leaf-cluster card in metres; None: the species' size."""
    lod: str = "medium"
    """Level of detail: 'low' (20k triangles), 'medium' (60k), 'high' (200k), 'full' (no bound)."""
    radial_segments: int = 8
    """Sides of the branch tubes before any LOD reduction."""
    foliage: str = "auto"
    """What the leaf cards show: 'broadleaf', 'needles' or 'scales'; 'auto': the species'
    ``leaf_type`` (pine: needles)."""
    texture_size: int | None = None
    """Bark texture edge N in texels (leaves get N/2); None: from the tree's size (at least 512,
    leaves 256; see :func:`treeform.geometry.texture_sizes`)."""
    render_size: int = 512
    """Edge in pixels of the square front, side and top preview renders."""
    fov_y: float = 35.0
    """Vertical field of view of the preview cameras in degrees."""
    out: str | None = None
    """Output directory (None: nothing is written)."""
    rbv: str | None = None
    """A RadialBoundingVolume file (.npz): grow by the bi-modal model inside it (seed 003 §4.3–4.4)."""
    mask: str | None = None
    """A branch mask image (white = branch) seen from the front, with ``rbv``: the scaffold follows it."""
    bole: float = 0.0
    """With ``rbv``: share of the tree's height (0..0.5) below which no branch leaves the stem
    (:func:`treeform.growth.bimodal.bimodal_grow`); 0: wherever the mask and the volume lead."""

    def validate(self) -> "GrowConfig":
        if not isinstance(self.species, str) or not self.species:
            raise InputError(f"species: expected a species name or a path, got {self.species!r}")
        _check_common(self)
        self.seed = int(self.seed)
        if self.mask is not None and self.rbv is None:
            raise InputError("mask: a branch mask needs --rbv (the volume the crown grows in)")
        if not isinstance(self.params, dict):
            raise InputError(f"params: expected a mapping of growth parameters, got {type(self.params).__name__}")
        check_positive(self.leaves_per_twig, "leaves_per_twig", allow_zero=True)
        if self.leaf_size is not None:
            check_positive(self.leaf_size, "leaf_size")
        _check_ints(self, (("twig_tips", 1, 10_000), ("radial_segments", 3, 64), ("render_size", 32, 4096)))
        check_range(self.bole, "bole", 0.0, 0.5)
        return self

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "GrowConfig":
        d = check_known_options(cls, d)
        if d.get("out") is not None:
            d["out"] = str(d["out"])
        if "params" in d and d["params"] is not None:
            d["params"] = dict(d["params"])
        return cls(**d).validate()


@dataclass
class LearnedConfig:
    """Every knob of :func:`treeform.methods.learned.pipeline.reconstruct` (seed 003 §5)."""

    seed: int = 0
    """Random seed: same photo + seed -> byte-identical skeleton.json."""
    species: str | None = None
    """Species preset to grow; None: the species network's prediction."""
    segmenter: str = "learned"
    """Tree segmentation: 'learned' (network) or 'classical' (colour rules + graph cut)."""
    tree_height: float | None = None
    """Tree height in metres; None: the predicted species' reference height (its RBV scale, §4.4)."""
    rbv_level: int = 4
    """Level of the predicted RBV the crown grows in (4 = 8 layers x 8 sectors)."""
    carve: bool = True
    """Drop the branches that project outside the tree mask and the leaf cards whose square lies
    mostly off it (:func:`treeform.crown.sampling.carve_to_silhouette`): the tree lies inside the
    cone of its silhouette."""
    beyond_frame: bool = True
    """Continue a crown the photo's top or side edges cut past them, rounded
    (:func:`treeform.crown.frame.beyond_frame`): the tree's height counts its continued top, the
    predicted RBV (a whole tree's) is fitted to the part of the silhouette the photo shows (as
    ``fit_silhouette``) and the carving keeps what grows past the frame, instead of cutting the model
    flat at it."""
    fill: bool = True
    """Add leaf cards where the tree mask shows foliage and no grown card projects, inside the RBV
    along each pixel's ray (:func:`treeform.methods.learned.pipeline.fill_silhouette`)."""
    leaf_texture: str = "photo"
    """'photo': leaf cards textured with the photo's crown, those the camera sees facing it
    (:func:`treeform.crown.photo_leaf_atlas`); 'procedural': the species' drawn leaves."""
    bole: float = 0.1
    """Share of the tree's height below which no branch leaves the stem: a crown that hangs to the
    ground (or a mask that takes in the shrubs under it) still stands on one trunk, which goes on
    up, hidden, where the photo's trunk disappears lower (as the envelope route's tenth; 0: branches
    may leave the stem anywhere)."""
    fit_silhouette: bool = False
    """Rescale each layer of the predicted RBV so the photo's camera sees it span the tree mask's
    left and right extent (:func:`treeform.crown.rbv_fit.fit_rbv_to_silhouette`); False: the
    network's RBV as predicted (seed 003 as published)."""
    max_size: int = 640
    """Long side the photo is reduced to before segmentation."""
    fov_y: float = 40.0
    """Vertical field of view of the photo's camera in degrees."""
    leaves: int | None = None
    """Total number of leaf clusters; None: the species' leaves per twig."""
    lod: str = "medium"
    """Level of detail: 'low' (20k triangles), 'medium' (60k), 'high' (200k), 'full' (no bound)."""
    foliage: str = "auto"
    """What the leaf cards show: 'broadleaf', 'needles' or 'scales'; 'auto': the grown species'
    ``leaf_type`` (pine: needles)."""
    texture_size: int | None = None
    """Bark texture edge N in texels (leaves get N/2); None: from the tree's size."""
    render_size: int = 512
    """Height in pixels of the side and top preview renders."""

    def validate(self) -> "LearnedConfig":
        _check_common(self)
        if self.species is not None:
            from treeform.growth.species import SPECIES

            check_choice(self.species, "species", SPECIES)
        check_choice(self.segmenter, "segmenter", ("learned", "classical"))
        if self.tree_height is not None:
            check_height(self.tree_height)
        for name in ("fit_silhouette", "carve", "fill", "beyond_frame"):
            if not isinstance(getattr(self, name), bool):
                raise InputError(f"{name}: expected true or false, got {getattr(self, name)!r}")
        check_choice(self.leaf_texture, "leaf_texture", ("photo", "procedural"))
        check_range(self.bole, "bole", 0.0, 0.5)
        if self.rbv_level not in (1, 2, 3, 4, 5):
            raise InputError(f"rbv_level: expected 1..5, got {self.rbv_level!r}")
        _check_ints(self, (("max_size", 32, 8192), ("render_size", 32, 4096)))
        return self

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "LearnedConfig":
        return cls(**check_known_options(cls, d)).validate()
