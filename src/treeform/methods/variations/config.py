"""Configuration of the image-based tree variations method (seed 000)."""

from __future__ import annotations

from dataclasses import asdict, dataclass

from treeform._shared.checks import check_choice
from treeform._shared.checks import check_known_options
from treeform._shared.errors import InputError


@dataclass
class VariationsConfig:
    """Every knob of :mod:`treeform.methods.variations.pipeline`."""

    seed: int = 0
    """Random seed: same library + seed -> byte-identical PNGs."""
    size: int = 1024
    """Side of the normalised exemplars and of the synthesised trees, pixels (§4.1: 1024)."""
    margin: int | None = None
    """Transparent border around a normalised tree, pixels (None: size // 64)."""
    trunk_points: int = 200
    """Points of Cr on each trunk side, B -> R and L -> B (§4.5: 200)."""
    crown_points: int = 1600
    """Points of Cr on the crown, R -> L (§4.5: 1600; N = 2000 in all)."""
    simplified_points: int = 20
    """Points M of the simplified contour Cs (§4.6, §7: M = 20 looks like M = 100)."""
    dilate: int = 8
    """Dilation iterations of Cr's interior before Cs is extracted (§4.6: 8)."""
    mvc_step: int = 4
    """Grid step (pixels) at which mean value coordinates are evaluated exactly; bilinear
    in between (1 = every pixel)."""
    exemplars_per_variation: int = 2
    """Exemplars combined in one variation (§7: two)."""
    weight_range: tuple = (0.3, 0.7)
    """Range of the first contour weight w1 when two exemplars are combined (§7: [0.3, 0.7])."""
    from_weight_range: tuple = (0.55, 0.8)
    """Range of the weight of the given tree T in variations of T (§3: higher weight on T)."""
    colour_concentration: float = 1.0
    """Dirichlet concentration of the random colour weights (§5.2); small values favour
    one exemplar's colours, large ones an even mix."""
    pairing: str = "similar"
    """How partners are chosen: 'similar' (at random among the 5 exemplars whose contours
    are closest, which avoids combining radically different trees, §7 Limitations) or
    'random'."""
    tile: int = 256
    """Side of one tile of a contact sheet, pixels."""
    photo_max_size: int = 1024
    """Long side a photo is reduced to before a billboard is made of it."""
    matting_side: int = 800
    """Long side at which alpha matting runs (the alpha is upsampled to the photo's size)."""
    sky_gaps: bool = False
    """Billboards: make sky seen through gaps in the crown transparent (the automatic
    segmentation counts those gaps as tree, so this lowers the IoU with it a little)."""

    def validate(self) -> "VariationsConfig":
        check_choice(self.pairing, "pairing", ("similar", "random"))
        for name, lo, hi in (("size", 64, 8192), ("trunk_points", 1, 100_000), ("crown_points", 3, 1_000_000),
                             ("simplified_points", 5, 1000), ("dilate", 0, 256), ("mvc_step", 1, 64),
                             ("exemplars_per_variation", 1, 16), ("tile", 16, 4096), ("photo_max_size", 16, 8192),
                             ("matting_side", 16, 8192)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
                raise InputError(f"{name}: expected an integer in [{lo}, {hi}], got {v!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise InputError(f"seed: expected a non-negative integer, got {self.seed!r}")
        if self.margin is not None and (not isinstance(self.margin, int) or not 0 <= self.margin < self.size // 4):
            raise InputError(f"margin: expected None or an integer in [0, {self.size // 4}), got {self.margin!r}")
        for name in ("weight_range", "from_weight_range"):
            r = tuple(getattr(self, name))
            if len(r) != 2 or not 0 <= r[0] <= r[1] <= 1:
                raise InputError(f"{name}: expected (low, high) with 0 <= low <= high <= 1, got {r!r}")
            setattr(self, name, (float(r[0]), float(r[1])))
        if not self.colour_concentration > 0:
            raise InputError(f"colour_concentration: expected a positive number, got {self.colour_concentration!r}")
        return self

    @property
    def counts(self) -> tuple[int, int, int]:
        return (self.trunk_points, self.crown_points, self.trunk_points)

    def processing_key(self) -> dict:
        """The options a processed exemplar depends on (part of its cache key)."""
        return {"size": self.size, "margin": self.margin, "counts": list(self.counts),
                "m": self.simplified_points, "dilate": self.dilate}

    def to_dict(self) -> dict:
        d = asdict(self)
        d["weight_range"] = list(self.weight_range)
        d["from_weight_range"] = list(self.from_weight_range)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "VariationsConfig":
        d = check_known_options(cls, d)
        for name in ("weight_range", "from_weight_range"):
            if name in d:
                d[name] = tuple(d[name])
        return cls(**d).validate()
