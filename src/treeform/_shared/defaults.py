"""Defaults shared by the library and the CLI, in a module that imports nothing heavy."""

SEGMENTERS = ("learned", "classical")
"""Names accepted by :func:`segment` (``--segmenter``)."""

DEFAULT_SEGMENTER = "learned"
"""The segmenter of every command that segments a photo (reconstruct's three methods, billboard,
cloud, segment, skeleton2d, variations, multiview's mattes) unless told otherwise
(``--segmenter classical``). Measured on 2026-11-26 (BENCHMARKS.md, "Learned perception"): real
cut-outs over real photos, median tree IoU 0.84 against the colour rules' 0.08; the evaluation's
70 synthetic cases, segmentation IoU 0.92 against 0.74 and the envelope route's front IoU against
the true mask 0.86 against 0.78; the network keeps red, orange and yellow crowns foliage where the
rules paint wood. Its known errors: hedges and planters right behind a tree's foot can join the
tree (Acer rubrum 2, Morus rubra 1), a house front joins Ulmus americana 1, and bare trees are
found in part (Gleditsia triacanthos 2, Platanus occidentalis 2)."""
