"""Contours of tree masks (seed 000 §4.1–4.6, §5.1–5.2).

Normalisation of an RGBA tree image (:func:`normalize_rgba`), its growth form read from the
silhouette (:func:`classify_form`, :func:`form_descriptor`), border following
(:func:`find_contours`, :func:`longest_exterior_contour`), pin points B / L / R
(:func:`pin_points`), chord-length resampling to a fixed length
(:func:`resample_contour`), region fill robust to self-intersections
(:func:`fill_contour`), the simplified contour Cs (:func:`simplify_contour`) and mean
value coordinates (:func:`mean_value_coordinates`, :func:`mvc_map`).

Coordinates are pixels ``(x, y)`` = (column, row), ``y`` down.
"""

from treeform.contour.borders import contour_length, find_contours, longest_exterior_contour, orient_contour, signed_area
from treeform.contour.fill import fill_contour, simplify_contour
from treeform.contour.form import FORMS, FormDescriptor, classify_form, form_descriptor
from treeform.contour.mvc import mean_value_coordinates, mvc_map
from treeform.contour.normalize import normalize_rgba
from treeform.contour.pins import PinPoints, crown_baseline, pin_points
from treeform.contour.resample import DEFAULT_COUNTS, resample_contour, resample_polyline, segment_counts

__all__ = [
    "DEFAULT_COUNTS",
    "FORMS",
    "FormDescriptor",
    "PinPoints",
    "classify_form",
    "contour_length",
    "crown_baseline",
    "fill_contour",
    "find_contours",
    "form_descriptor",
    "longest_exterior_contour",
    "mean_value_coordinates",
    "mvc_map",
    "normalize_rgba",
    "orient_contour",
    "pin_points",
    "resample_contour",
    "resample_polyline",
    "segment_counts",
    "signed_area",
    "simplify_contour",
]
