"""Crown shape priors: envelope inflation (bilaplacian), relief, radial distance maps (seed 001 §3.2–3.5)."""

from treeform.crown.envelope import Envelope, bilaplacian_solve, inflate_envelope, silhouette_sets
from treeform.crown.relief import relief_map
from treeform.crown.rdm import rdm_from_texels
from treeform.crown.sampling import sample_crown_columns

__all__ = ["Envelope", "bilaplacian_solve", "inflate_envelope", "silhouette_sets", "relief_map", "rdm_from_texels", "sample_crown_columns"]
