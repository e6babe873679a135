"""Image-based tree variations (seed 000): new RGBA trees from a library of RGBA trees.

Exemplar processing (:mod:`.exemplar`, §4), synthesis by contour combination, mean value
coordinate colour transfer and histogram transfer (:mod:`.synthesis`, §5), the
pipeline functions the CLI calls (:mod:`.pipeline`): :func:`process_library`,
:func:`vary`, :func:`morph`, :func:`billboard`, and billboard clouds (:mod:`.cloud`, §6):
:func:`cloud`.
"""

from treeform.methods.variations.cloud import cloud
from treeform.methods.variations.config import CloudConfig, VariationsConfig
from treeform.io import read_rgba
from treeform.methods.variations.exemplar import Exemplar, normalize_rgba, process_exemplar, split_crown_trunk
from treeform.methods.variations.pipeline import billboard, contact_sheet, load_exemplar, morph, process_library, vary
from treeform.methods.variations.synthesis import combine_contours, match_histograms, synthesize, transfer_rgba

__all__ = [
    "CloudConfig",
    "Exemplar",
    "VariationsConfig",
    "billboard",
    "cloud",
    "combine_contours",
    "contact_sheet",
    "load_exemplar",
    "match_histograms",
    "morph",
    "normalize_rgba",
    "process_exemplar",
    "process_library",
    "read_rgba",
    "split_crown_trunk",
    "synthesize",
    "transfer_rgba",
    "vary",
]
