"""Paper 003 (Li et al. 2021, learning to reconstruct botanical trees from single images).

So far its developmental part: species presets grown by the phenomenological bud-based
model (§4.3, Appendix Tables 2–3) into leafy, textured trees — :func:`grow.grow_tree`.
"""

from treeform.methods.learned.config import GrowConfig

__all__ = ["GrowConfig"]
