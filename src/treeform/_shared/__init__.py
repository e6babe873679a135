"""Errors, input checks, RNG and timing helpers shared by every treeform folder."""
