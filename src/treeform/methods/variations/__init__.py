"""Image-based tree variations (seed 000): new RGBA trees from a library of RGBA trees.

Exemplar processing (:mod:`.exemplar`, §4), growth forms from silhouettes
(:mod:`.form`), synthesis by contour combination, mean value coordinate colour transfer
and histogram transfer (:mod:`.synthesis`, §5), season transfer from a photographed tree
(:mod:`.season`, §5.3), the pipeline functions the CLI calls (:mod:`.pipeline`):
:func:`process_library`, :func:`vary`, :func:`morph`, :func:`billboard`, and billboard
clouds (:mod:`.cloud`, §6): :func:`cloud`.
"""

from treeform.methods.variations.cloud import cloud
from treeform.methods.variations.config import CloudConfig, VariationsConfig
from treeform.io import read_rgba
from treeform.methods.variations.exemplar import Exemplar, normalize_rgba, process_exemplar, split_crown_trunk
from treeform.contour.form import FORMS, classify_form, form_descriptor
from treeform.methods.variations.pipeline import billboard, contact_sheet, load_exemplar, morph, process_library, vary
from treeform.methods.variations.season import SeasonReference, season_reference, season_transfer
from treeform.methods.variations.synthesis import combine_contours, match_histograms, synthesize, transfer_rgba

__all__ = [
    "CloudConfig",
    "Exemplar",
    "FORMS",
    "SeasonReference",
    "VariationsConfig",
    "billboard",
    "classify_form",
    "cloud",
    "combine_contours",
    "contact_sheet",
    "form_descriptor",
    "load_exemplar",
    "match_histograms",
    "morph",
    "normalize_rgba",
    "process_exemplar",
    "process_library",
    "read_rgba",
    "season_reference",
    "season_transfer",
    "split_crown_trunk",
    "synthesize",
    "transfer_rgba",
    "vary",
]
