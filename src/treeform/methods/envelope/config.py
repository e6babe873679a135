"""Configuration of the single-photo envelope method (seed 001 §3)."""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

from treeform._shared.defaults import DEFAULT_SEGMENTER
from treeform._shared.checks import check_choice, check_height, check_int, check_positive
from treeform._shared.checks import check_known_options
from treeform._shared.errors import InputError



COLONIZATION_PRESETS = {
    "coarse": {"segment_length": 0.04, "kill_factor": 2.5, "direction_weight": 1.0},
    "paper": {"segment_length": 0.005, "kill_factor": 2.0, "direction_weight": 0.0},
}
"""Space-colonization regimes: 'coarse' (treeform's default: D = 0.04 r, d_k = 0.1 r, laterals
leaving at about 45 degrees) and 'paper' (seed 001 §3.6 at full detail: d_k = 0.01 r, D = 0.5 d_k,
Runions's rule as the paper uses it), r the mean crown radius."""

FORM_SPECIES = {"broadleaf": None, "conifer": "pine"}
"""The growth preset (``treeform/growth/species``) whose ``branching_angle_mean`` sets the angle
at which a growth form's laterals leave its trunk or leader (:func:`leader_direction_weight`);
``None``: as every other branch (``direction_weight``)."""


@dataclass
class EnvelopeConfig:
    """Every knob of :func:`treeform.methods.envelope.pipeline.reconstruct`."""

    seed: int = 0
    """Random seed: same photo + seed -> byte-identical skeleton.json."""
    max_size: int = 640
    """Long side in pixels the photo is reduced to before any work."""
    tree_height: float = 10.0
    """Assumed height of the tree in metres (a single photo has no absolute scale)."""
    segmenter: str = DEFAULT_SEGMENTER
    """Tree segmentation: 'learned' (the network, default) or 'classical' (colour rules + graph cut)."""
    fov_y: float = 40.0
    """Vertical field of view of the photo's camera in degrees."""
    crown: str = "auto"
    """Envelope tangent function (§3.2): 'round' (f = k) or 'conical' (f = a·y² + 1, and a side
    as wide as the front at each height); 'auto': conical for a conifer (``form``), else round."""
    tangent_k: float | None = None
    """Silhouette tangent length k (about 6 inflates a disc into a sphere); None = automatic:
    the k that makes the envelope ``depth_ratio`` times as deep as it is wide."""
    depth_ratio: float = 1.0
    """Envelope depth / width when ``tangent_k`` is None (1 = a round crown from the side)."""
    profile: str = "rounded"
    """Side profile of the envelope: 'rounded' (each row as deep as a rounded crown of the
    front's size: :func:`treeform.crown.envelope.side_profile`) or 'thin-plate' (the depth of
    seed 001 §3.2 as solved, deepest where the front is widest)."""
    conical_a: float = 3.0
    """Quadratic coefficient a of the conical tangent function."""
    envelope_grid: int = 128
    """Grid size (crown's longer side, pixels) of the bilaplacian solve."""
    relief_levels: int = 4
    """Gaussian pyramid levels of the relief (§3.4: 4 or 5)."""
    relief_weight: float = 0.15
    """rho of §3.5: r = |p - c| (1 + rho (h - 0.5))."""
    rdm_resolution: int = 256
    """Cubemap side R of the radial distance map (6 x R x R texels)."""
    rdm_rotations: tuple = ()
    """Extra copies of the envelope rotated about the vertical axis (degrees), max radius kept."""
    attractors: int = 10_000
    """Blue-noise attraction points of the space colonization (§3.6)."""
    segment_length: float = 0.04
    """Space-colonization internode D, as a fraction of the mean crown radius."""
    kill_factor: float = 2.5
    """Kill distance d_k = kill_factor x D."""
    influence: float = 0.5
    """Influence radius d_i as a fraction of the mean crown radius."""
    direction_weight: float = 1.0
    """Weight of each node's own direction beside the unit direction to its attractors
    (:func:`~treeform.growth.space_colonization.space_colonization`): at 1 a lateral leaves its
    parent at about 45 degrees and bends toward its attractors, at w at about atan(1 / w); 0 is
    Runions's rule (laterals square to their parents, twigs bristling off every branch). A
    conifer's laterals leave its leader at its own angle (:func:`leader_direction_weight`)."""
    form: str = "auto"
    """Growth form: 'broadleaf' (the trunk splits into scaffold limbs where the crown begins),
    'conifer' (one leader up to the crown's top, laterals leaving it all along the crown at a
    conifer's angle; needle cards with ``foliage='auto'``) or 'auto': read from the tree's
    silhouette (:func:`treeform.contour.form.classify_form`: a narrow cone or column
    down to near the ground is a conifer)."""
    pipe_exponent: float = 2.3
    """Pipe-model exponent e: r_parent^e = sum r_child^e."""
    leaves: int = 8000
    """Number of leaf clusters (alpha-textured cards)."""
    shell_leaves: float = 0.35
    """Share of the leaves sampled on the RDM's 3D shell (covers side and top views); the rest
    are spread evenly over the photo's crown pixels (covers the front view)."""
    clumps: float = 0.4
    """Spacing of the crown's foliage clumps, as a fraction of the mean crown radius: leaves and
    branch attractors gather around blue-noise centres this far apart, so the side, back and top
    show lobes, gaps and limbs as real crowns do (:func:`treeform.crown.sampling.foliage_clumps`);
    the photo's view keeps every leaf pixel. 0: foliage spread evenly through the envelope."""
    beyond_frame: bool = True
    """Continue a crown the photo's top or side edges cut past them, rounded
    (:func:`treeform.crown.frame.beyond_frame`), instead of cutting the model flat at the frame."""
    leaf_coverage: float = 3.0
    """Mean number of leaf cards over a crown pixel seen from the front; sets the card size."""
    lod: str = "medium"
    """Level of detail: 'low' (20k triangles), 'medium' (60k), 'high' (200k), 'full' (no bound)."""
    radial_segments: int = 8
    """Sides of the branch tubes before any LOD reduction."""
    foliage: str = "auto"
    """What the leaf cards show: 'broadleaf' clusters, pine-like 'needles', thuja-like 'scales';
    'auto': needles for a conical crown, else broadleaf."""
    leaf_texture: str = "photo"
    """Leaf-card texture: 'photo' (each card a tile cut from the photo's crown where the card
    projects, in a leaf-cluster outline; see :func:`treeform.crown.photo_leaf_atlas`) or
    'procedural' (one drawn cluster tinted by the photo's colour at the card)."""
    texture_size: int | None = None
    """Bark texture edge N in texels (leaves get N/2); None: from the tree's size (at least 512,
    leaves 256; see :func:`treeform.geometry.texture_sizes`)."""
    render_size: int = 512
    """Height in pixels of the side and top preview renders."""

    def validate(self) -> "EnvelopeConfig":
        check_choice(self.crown, "crown", ("auto", "round", "conical"))
        check_choice(self.lod, "lod", ("low", "medium", "high", "full"))
        check_choice(self.segmenter, "segmenter", ("learned", "classical"))
        check_choice(self.foliage, "foliage", ("auto", "broadleaf", "needles", "scales"))
        check_choice(self.leaf_texture, "leaf_texture", ("photo", "procedural"))
        check_choice(self.profile, "profile", ("rounded", "thin-plate"))
        check_choice(self.form, "form", ("auto", "broadleaf", "conifer"))
        if self.texture_size is not None:
            check_int(self.texture_size, "texture_size", 16, 8192)
        if self.tangent_k is not None:
            check_positive(self.tangent_k, "tangent_k")
        check_height(self.tree_height)
        for name in ("depth_ratio", "segment_length", "kill_factor", "influence", "pipe_exponent", "leaf_coverage"):
            check_positive(getattr(self, name), name)
        check_positive(self.relief_weight, "relief_weight", allow_zero=True)
        check_positive(self.clumps, "clumps", allow_zero=True)
        check_positive(self.direction_weight, "direction_weight", allow_zero=True)
        if not isinstance(self.beyond_frame, bool):
            raise InputError(f"beyond_frame: expected true or false, got {self.beyond_frame!r}")
        if not 0 <= self.shell_leaves <= 1:
            raise InputError(f"shell_leaves: expected a fraction in [0, 1], got {self.shell_leaves}")
        for name, lo, hi in (("max_size", 32, 8192), ("envelope_grid", 16, 1024), ("relief_levels", 1, 8),
                             ("rdm_resolution", 8, 2048), ("attractors", 10, 2_000_000), ("leaves", 0, 2_000_000),
                             ("radial_segments", 3, 64), ("render_size", 32, 4096)):
            v = getattr(self, name)
            if not isinstance(v, int) or not lo <= v <= hi:
                raise InputError(f"{name}: expected an integer in [{lo}, {hi}], got {v!r}")
        if not 5 <= self.fov_y <= 120:
            raise InputError(f"fov_y: expected 5..120 degrees, got {self.fov_y}")
        return self

    def foliage_kind(self, form: str | None = None) -> str:
        """The foliage kind the leaf cards show ('auto': needles for a conical crown or a conifer
        ``form``, the growth form :func:`~treeform.methods.envelope.pipeline.reconstruct` found)."""
        if self.foliage != "auto":
            return self.foliage
        return "needles" if self.crown == "conical" or (form or self.form) == "conifer" else "broadleaf"

    def crown_for(self, form: str) -> str:
        """The envelope's tangent function for a growth form (``crown`` if set)."""
        return self.crown if self.crown != "auto" else ("conical" if form == "conifer" else "round")

    def to_dict(self) -> dict:
        d = asdict(self)
        d["rdm_rotations"] = list(self.rdm_rotations)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "EnvelopeConfig":
        d = check_known_options(cls, d)
        if "rdm_rotations" in d:
            d["rdm_rotations"] = tuple(d["rdm_rotations"])
        return cls(**d).validate()


def leader_direction_weight(form: str) -> float | None:
    """Direction weight w of the laterals leaving a growth form's trunk or leader: 1 / tan(a).

    A lateral's first step is the unit direction toward its attractors (square to its parent
    inside a crown) plus w times its parent's direction, so it leaves at atan(1 / w); a is the
    ``branching_angle_mean`` of the form's growth preset (:data:`FORM_SPECIES`). ``None`` for a
    broadleaf (its limbs leave the trunk as every other branch does).

    Examples
    --------
    >>> leader_direction_weight("broadleaf") is None
    True
    >>> round(leader_direction_weight("conifer"), 3)  # the pine preset's 80 degrees
    0.176
    """
    check_choice(form, "form", tuple(FORM_SPECIES))
    name = FORM_SPECIES[form]
    if name is None:
        return None
    from treeform.growth.species import load_species

    return 1.0 / math.tan(math.radians(float(load_species(name).branching_angle_mean)))
