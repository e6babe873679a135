"""Configuration of the image-based tree variations method (seed 000)."""

from __future__ import annotations

from dataclasses import asdict, dataclass

from treeform._shared.defaults import DEFAULT_SEGMENTER
from treeform._shared.checks import check_choice, check_height
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
    any_form: bool = False
    """Combine exemplars of any growth form. By default a variation combines exemplars of
    one form only, broadleaf, conifer or palm, read from their silhouettes
    (:mod:`treeform.contour.form`); another form is used only for an exemplar
    that is the library's only one of its form."""
    season_space: str = "lab"
    """Season transfer (``season=``): the colour space whose channels are matched one by
    one, 'lab' (CIE L*a*b*, default: lightness apart from the two colour axes) or 'rgb'
    (the paper's; turns greyish stems and shaded leaves pink)."""
    season_min_trunk: float = 0.005
    """Season transfer: the photo's trunk colours go onto the trunks only when its visible
    trunk is at least this fraction of the photographed tree; else the trunks keep theirs."""
    tile: int = 256
    """Side of one tile of a contact sheet, pixels."""
    photo_max_size: int = 1024
    """Long side a photo is reduced to before a billboard is made of it."""
    matting_side: int = 800
    """Long side at which alpha matting runs (the alpha is upsampled to the photo's size)."""
    segmenter: str = DEFAULT_SEGMENTER
    """Billboards from photos and the season photo: tree segmentation, 'classical' (colour rules,
    default) or 'learned' (network)."""
    sky_gaps: bool = False
    """Billboards: make sky seen through gaps in the crown transparent (the automatic
    segmentation counts those gaps as tree, so this lowers the IoU with it a little)."""

    def validate(self) -> "VariationsConfig":
        check_choice(self.pairing, "pairing", ("similar", "random"))
        check_choice(self.segmenter, "segmenter", ("learned", "classical"))
        check_choice(self.season_space, "season_space", ("lab", "rgb"))
        if not isinstance(self.any_form, bool):
            raise InputError(f"any_form: expected true or false, got {self.any_form!r}")
        v = self.season_min_trunk
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 <= v <= 1:
            raise InputError(f"season_min_trunk: expected a fraction in [0, 1], got {v!r}")
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


@dataclass
class CloudConfig:
    """Every knob of :func:`treeform.methods.variations.cloud.cloud` (seed 000 §6)."""

    seed: int = 0
    """Random seed: same picture + seed -> byte-identical GLB and JSON."""
    segmenter: str = DEFAULT_SEGMENTER
    """A photo (no transparency) is made into a billboard first: 'learned' (default) or 'classical' segmentation."""
    size: int = 1024
    """Side of the normalised picture the cloud is made of, pixels (§4.1: 1024)."""
    segments: int = 256
    """Approximate number of SLIC superpixels of the crown (§6: 256)."""
    compactness: float = 0.35
    """SLIC compactness on colours in [0, 1] (§6: 0.35; lower is more fractal)."""
    slic_side: int = 512
    """Longest side SLIC runs at (labels are scaled back to ``size``)."""
    straightness: float = 0.05
    """Douglas-Peucker tolerance that defines a straight superpixel edge, in superpixel sides."""
    min_edge: float = 0.3
    """Shortest straight edge that is replaced, in superpixel sides."""
    endpoint_tolerance: float = 0.1
    """Mismatch allowed between the endpoints of an edge and of its silhouette curve, as a
    fraction of the edge length (§6's first constraint)."""
    max_bulge: float = 0.5
    """Largest distance of a silhouette curve from its edge, in superpixel sides."""
    overlap: int = 2
    """Pixels by which every billboard's footprint grows into its neighbours' (beyond the
    paper: no cracks between billboards in minified views)."""
    depth_ratio: float = 1.0
    """Depth / width of the crown envelope that gives the billboards' depths (1: round)."""
    push: float = 0.5
    """How deep the darkest front billboard is pushed, as a fraction of the envelope's depth."""
    interior: float = 0.5
    """Extra billboards inside the crown volume, per superpixel."""
    darken: float = 0.5
    """Colour factor lost by an interior billboard on the crown's centre plane (0: none)."""
    yaw: tuple = (20.0, 50.0)
    """Range of the billboards' random turn about the vertical axis, degrees (either way)."""
    max_leak: float = 0.02
    """Largest fraction of a rear or interior billboard's pixels allowed outside the tree."""
    tree_height: float = 10.0
    """Height of the tree in metres (a picture has no absolute scale)."""
    fov_y: float = 10.0
    """Vertical field of view of the reference (front) camera, degrees."""
    view_size: int = 384
    """Side of each view of the turntable strip, pixels."""
    views: tuple = (0.0, 30.0, 60.0, 90.0)
    """Orbit angles of the strip's views, degrees (0 = the front view)."""

    def validate(self) -> "CloudConfig":
        check_choice(self.segmenter, "segmenter", ("learned", "classical"))
        for name, lo, hi in (("size", 64, 8192), ("segments", 1, 100_000), ("slic_side", 16, 8192),
                             ("view_size", 16, 4096), ("overlap", 0, 64)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int) or not lo <= v <= hi:
                raise InputError(f"{name}: expected an integer in [{lo}, {hi}], got {v!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise InputError(f"seed: expected a non-negative integer, got {self.seed!r}")
        check_height(self.tree_height)
        for name in ("compactness", "straightness", "min_edge", "endpoint_tolerance", "max_bulge", "depth_ratio"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 < v < float("inf"):
                raise InputError(f"{name}: expected a positive number, got {v!r}")
        for name, hi in (("push", 1.0), ("interior", 10.0), ("darken", 1.0), ("max_leak", 1.0)):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 <= v <= hi:
                raise InputError(f"{name}: expected a number in [0, {hi}], got {v!r}")
        if not isinstance(self.fov_y, (int, float)) or not 0 < self.fov_y < 120:
            raise InputError(f"fov_y: expected degrees in (0, 120), got {self.fov_y!r}")
        y = tuple(self.yaw)
        if len(y) != 2 or not 0 <= y[0] <= y[1] < 80:
            raise InputError(f"yaw: expected (low, high) degrees with 0 <= low <= high < 80, got {y!r}")
        self.yaw = (float(y[0]), float(y[1]))
        try:
            self.views = tuple(float(a) for a in self.views)
        except (TypeError, ValueError):
            raise InputError(f"views: expected a sequence of angles in degrees, got {self.views!r}") from None
        if not self.views:
            raise InputError("views: expected at least one angle")
        return self

    def to_dict(self) -> dict:
        d = asdict(self)
        d["yaw"], d["views"] = list(self.yaw), list(self.views)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "CloudConfig":
        return cls(**check_known_options(cls, d)).validate()
