"""Paper 001: crown envelope + radial distance map + space colonization."""

from treeform.methods.envelope.config import EnvelopeConfig

__all__ = ["EnvelopeConfig"]
