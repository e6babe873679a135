"""Species presets of the phenomenological growth model (seed 003 Appendix Table 2).

Each species is a JSON file beside this module that users can copy and edit::

    {
      "species": "oak",
      "source": "...",                      # free text (optional)
      "base": "oak",                        # optional: start from this preset, override below
      "parameters": {"growth_rate": 3.0, ...},   # GrowthParameters fields
      "reference_height": 17.0,             # optional: metres of a typical grown tree (RBV scale, 003 §4.4)
      "perception_angle": 60.0,             # optional: degrees, cone of bi-modal growth's volume limbs
      "marker_density": 0.5,                # optional: markers per m³ of RBV for those limbs
      "appearance": {"leaf_color": [r, g, b], "leaf_size": 0.5,   # optional
                     "leaf_type": "broadleaf"}   # or "needles", "scales" (the leaf texture)
    }

Without ``base`` every parameter must be given. :func:`load_species` accepts a preset name
(``"oak"``) or the path of such a file.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from treeform._shared.errors import InputError
from treeform.growth.phenomenological import GrowthParameters

__all__ = ["SPECIES", "SpeciesAppearance", "load_species", "load_species_appearance", "load_reference_height",
           "load_perception_angle", "load_marker_density", "species_path"]

_DIR = Path(__file__).resolve().parent
SPECIES = ("acacia", "apple", "willow", "maple", "birch", "oak", "pine")
"""The seven presets of seed 003 Table 2, in the table's order."""

_TOP_KEYS = {"species", "source", "notes", "base", "parameters", "appearance", "reference_height",
             "perception_angle", "marker_density"}


@dataclass(frozen=True)
class SpeciesAppearance:
    """How a species' leaves look (chosen by hand, as in seed 003's Appendix).

    Attributes
    ----------
    leaf_color : tuple of 3 floats in [0, 1]
        Mean RGB of the leaves.
    leaf_size : float
        Edge length in metres of one leaf-cluster card.
    leaf_type : {"broadleaf", "needles", "scales"}
        What a card shows: a broadleaf cluster, a needle cluster (pines), a scale spray
        (thuja, juniper); see :func:`treeform.geometry.tree_textures`.
    """

    leaf_color: tuple = (0.22, 0.4, 0.13)
    leaf_size: float = 0.45
    leaf_type: str = "broadleaf"


def species_path(name: str) -> Path:
    """Path of a preset's JSON file; unknown names raise :class:`InputError` listing the known ones."""
    if name not in SPECIES:
        raise InputError(f"species: unknown {name!r}; known: {', '.join(SPECIES)} (or a path to a .json file)")
    return _DIR / f"{name}.json"


def _read(name_or_path, _seen=()) -> dict:
    s = str(name_or_path)
    if isinstance(name_or_path, str) and s in SPECIES:
        path = species_path(s)
    elif isinstance(name_or_path, Path) or s.endswith(".json") or "/" in s or "\\" in s:
        path = Path(s)
        if not path.is_file():
            raise InputError(f"species: no such file {path}")
    else:
        species_path(s)  # raises, listing the known names
    if path in _seen:
        raise InputError(f"species: {path} refers to itself through 'base'")
    try:
        data = json.loads(path.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputError(f"species: {path} is not valid JSON ({exc})") from None
    except OSError as exc:
        raise InputError(f"species: cannot read {path} ({exc.strerror})") from None
    if not isinstance(data, dict):
        raise InputError(f"species: {path} must hold a JSON object")
    unknown = sorted(set(data) - _TOP_KEYS)
    if unknown:
        raise InputError(f"species: {path}: unknown key(s) {', '.join(unknown)}; known: {', '.join(sorted(_TOP_KEYS))}")
    if "parameters" not in data:
        raise InputError(f"species: {path} lacks 'parameters'")
    data = dict(data)
    data["_path"] = path
    data["_seen"] = tuple(_seen) + (path,)
    return data


def _params(data: dict) -> GrowthParameters:
    base = None
    if data.get("base") is not None:
        base = _params(_read(data["base"], data["_seen"]))
    try:
        return GrowthParameters.from_dict(data["parameters"], base=base)
    except InputError as exc:
        raise InputError(f"species {data['_path'].name}: {exc}") from None


def load_species(name_or_path) -> GrowthParameters:
    """The growth parameters of a preset (``"oak"``) or a species JSON file (seed 003 Table 2).

    Parameters
    ----------
    name_or_path : str or path-like
        One of :data:`SPECIES`, or a path to a JSON file in the format of the presets.

    Returns
    -------
    GrowthParameters

    Raises
    ------
    InputError
        Unknown name (the message lists the known ones), unreadable file, unknown keys or
        parameter names, missing parameters (without ``base``), or invalid values.

    Examples
    --------
    >>> load_species("pine").branching_angle_mean
    80.0
    """
    return _params(_read(name_or_path))


def load_species_appearance(name_or_path) -> SpeciesAppearance:
    """The leaf colour, size and type of a preset or species file (defaults where it gives none)."""
    data = _read(name_or_path)
    look = data.get("appearance")
    if look is None and data.get("base") is not None:
        return load_species_appearance(data["base"])
    look = look or {}
    if not isinstance(look, dict) or set(look) - {"leaf_color", "leaf_size", "leaf_type"}:
        raise InputError(f"species {data['_path'].name}: 'appearance' takes only leaf_color, leaf_size and leaf_type")
    # keys it leaves out come from its base preset, if any (a pine variant keeps its needles)
    default = load_species_appearance(data["base"]) if data.get("base") is not None else SpeciesAppearance()
    color = look.get("leaf_color", default.leaf_color)
    size = look.get("leaf_size", default.leaf_size)
    try:
        color = tuple(float(c) for c in color)
        size = float(size)
    except (TypeError, ValueError):
        raise InputError(f"species {data['_path'].name}: leaf_color must be 3 numbers, leaf_size a number") from None
    if len(color) != 3 or not all(0 <= c <= 1 for c in color):
        raise InputError(f"species {data['_path'].name}: leaf_color must be 3 numbers in [0, 1], got {color}")
    if not size > 0:
        raise InputError(f"species {data['_path'].name}: leaf_size must be positive, got {size}")
    leaf_type = look.get("leaf_type", default.leaf_type)
    if leaf_type not in ("broadleaf", "needles", "scales"):
        raise InputError(f"species {data['_path'].name}: leaf_type must be broadleaf, needles or scales, "
                         f"got {leaf_type!r}")
    return SpeciesAppearance(color, size, leaf_type)


def load_reference_height(name_or_path) -> float:
    """The species' RBV scale factor (seed 003 §4.4): the height in metres of a typical tree of it.

    The presets store the median height of the preset grown at its age over 2,400 seeds (the
    training data of the networks), so a height-normalised RBV predicted from a photo becomes
    metres. A file without it inherits its ``base``'s, else 10 m.

    >>> load_reference_height("oak")
    17.0
    """
    return _positive(name_or_path, "reference_height", 10.0)


def load_perception_angle(name_or_path) -> float:
    """Half-angle (degrees) of the perception cone with which bi-modal growth fills the RBV.

    After the photo's branches are traced and turned (seed 003 §4.4), the scaffold goes on
    growing by space colonization toward markers in the RBV; the cone bounds the angle at
    which these hidden limbs leave it, which makes it a species trait. The presets store the
    angle that best reproduces each species' own branching angle and biomass when it is
    regrown from its own RBV and branch mask (``python benchmarks/bench_bimodal.py --calibrate``,
    growth seeds 4-6; the benchmark uses seeds 1-3). A file without it inherits its
    ``base``'s, else 50°.

    >>> 10 < load_perception_angle("oak") <= 90
    True
    """
    a = _positive(name_or_path, "perception_angle", 50.0)
    if a > 90:
        raise InputError(f"species {_read(name_or_path)['_path'].name}: perception_angle must be at most 90, got {a}")
    return a


def load_marker_density(name_or_path) -> float:
    """Markers per m³ of the RBV with which bi-modal growth grows the limbs the photo hides.

    How densely the species branches through its crown: the presets store 1,500 markers in
    the median level-4 RBV of the preset grown with seeds 4-6
    (``python benchmarks/bench_bimodal.py --calibrate``), so a small or open crown gets fewer
    limbs than a large one of the same species. A file without it inherits its ``base``'s,
    else 0.5.

    >>> load_marker_density("pine") > load_marker_density("maple")  # a dense small crown
    True
    """
    return _positive(name_or_path, "marker_density", 0.5)


def _positive(name_or_path, key: str, default: float) -> float:
    """A positive number stored at the top of a species file, else its ``base``'s, else ``default``."""
    data = _read(name_or_path)
    v = data.get(key)
    if v is None:
        return _positive(data["base"], key, default) if data.get("base") is not None else default
    try:
        v = float(v)
    except (TypeError, ValueError):
        raise InputError(f"species {data['_path'].name}: {key} must be a number, got {v!r}") from None
    if not v > 0:
        raise InputError(f"species {data['_path'].name}: {key} must be positive, got {v}")
    return v
