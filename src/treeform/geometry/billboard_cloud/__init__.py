"""Billboard clouds from one tree picture (seed 000 §6, Figs. 9–11).

The stages are functions over arrays in image pixels — ``x`` = column, ``y`` = row (down),
pixel ``(j, i)`` covering ``[j, j + 1) x [i, i + 1)`` — and depth ``z`` in pixels toward
the viewer:

1. :func:`superpixels` — SLIC superpixels of the crown (n = 256, compactness 0.35);
2. :func:`replace_straight_edges` — every straight superpixel edge is replaced by a curve
   taken from the crown silhouette, whose endpoints match the edge's within a tolerance and
   which never crosses the edge inward, so regions only grow (Fig. 10);
3. :func:`build_atlas` — the RGBA crops of all regions (and of the trunk) in one texture;
4. :func:`place_billboards` — a front layer at the regions' own image positions with
   depths from the envelope's biharmonic height field, darker-than-average regions pushed
   deeper; a rear layer with horizontally mirrored positions (textures not mirrored);
   extra billboards at blue-noise positions inside the crown volume, darkened with depth;
   the trunk as one billboard;
5. :func:`cloud_mesh` — one alpha-tested (MASK), double-sided quad per billboard.

Every vertex lies on the ray of the reference camera (:class:`CloudFrame`) through its
image point, so the front view reproduces the picture's pixel grid exactly whatever the
billboards' depths and yaw angles; rear and interior billboards are kept behind the front
layer at each of their pixels and inside the tree's alpha (up to ``max_leak``).
"""

from treeform.geometry.billboard_cloud._common import FRONT, INTERIOR, REAR, TRUNK
from treeform.geometry.billboard_cloud.atlas import build_atlas, luminance
from treeform.geometry.billboard_cloud.edges import Regions, replace_straight_edges
from treeform.geometry.billboard_cloud.mesh import CloudFrame, cloud_mesh
from treeform.geometry.billboard_cloud.placement import Placement, place_billboards
from treeform.geometry.billboard_cloud.superpixels import superpixels

__all__ = ["FRONT", "REAR", "INTERIOR", "TRUNK", "Regions", "Placement", "CloudFrame", "superpixels",
           "replace_straight_edges", "build_atlas", "place_billboards", "cloud_mesh", "luminance"]
