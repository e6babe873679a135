"""``treeform eval``: every tree-reconstruction method scored on the same cases against ground truth.

- :mod:`~treeform.evaluation.cases` — cases: synthetic trees with full 3D ground truth
  (``synthetic:N``), the same photographed all around for the multi-view method beside the
  single-photo ones (``captures:N``), or real photos with an optional mask beside each
  (``photos:DIR``);
- :mod:`~treeform.evaluation.scores` — front silhouette against the true and the method's own
  mask, novel-view silhouette IoU (90°, 180°, above), RBV error per level, tree-form metric
  distances (height, trunk diameter, branching angle, LAI, biomass, MRT), species; the
  multi-view tree aligned to the truth by its cameras first;
- :mod:`~treeform.evaluation.run` — :func:`evaluate`: one task per case on Dask, resumable,
  ``results.json`` with medians and 95 % intervals.

Sits above ``methods/`` (it runs them by their registry names) and below ``cli/``.
"""

from treeform.evaluation.cases import Case, case_names, load_case
from treeform.evaluation.run import evaluate
from treeform.evaluation.scores import novel_view_ious, rbv_errors, score_reconstruction

__all__ = ["Case", "case_names", "load_case", "evaluate", "novel_view_ious", "rbv_errors", "score_reconstruction"]
