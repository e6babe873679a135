"""Growth models: space colonization (Runions et al. 2007), pipe-model radii, attractor sampling."""

from treeform.growth.radii import branch_orders, pipe_model_radii
from treeform.growth.sampling import blue_noise_points
from treeform.growth.space_colonization import SpaceColonizationResult, space_colonization

__all__ = ["space_colonization", "SpaceColonizationResult", "pipe_model_radii", "branch_orders", "blue_noise_points"]
