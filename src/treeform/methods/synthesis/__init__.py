"""Single photo -> 3D tree by analysis by synthesis (seed 004, Guénard et al. 2013): foliage
skeletonisation, an L-system generative model and best-of-N candidates by reprojection."""

from treeform.methods.synthesis.config import SynthesisConfig

__all__ = ["SynthesisConfig"]
