"""Structure from motion: photo collection -> registered cameras and 3D points (seed 002 §3).

:func:`load_photos` reads a folder (upright, resized, EXIF focal prior), :func:`run_sfm`
registers it with COLMAP into an :class:`SfmResult`, :func:`to_tree_frame` (module
:mod:`treeform.sfm.align`) puts it into treeform's frame, and :mod:`treeform.sfm.evaluate`
scores it against known cameras.

pycolmap is imported inside the functions that need it (``treeform --help`` stays fast).
"""

from treeform.sfm.align import to_tree_frame
from treeform.sfm.colmap import run_sfm
from treeform.sfm.photos import PhotoView, load_photos
from treeform.sfm.result import SfmResult

__all__ = ["SfmResult", "PhotoView", "load_photos", "run_sfm", "to_tree_frame"]
