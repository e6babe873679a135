"""Defaults shared by the library and the CLI, in a module that imports nothing heavy."""

SEGMENTERS = ("learned", "classical")
"""Names accepted by :func:`segment` (``--segmenter``)."""

DEFAULT_SEGMENTER = "classical"
"""The segmenter of every command that segments a photo (reconstruct's envelope and abs methods,
billboard, cloud, segment, skeleton2d, variations) unless told otherwise; the learned method and
``treeform species`` use the network, which their species and RBV networks were trained with.
The network finds the main tree on the real photos of ../shared/data/photos, keeps autumn crowns
foliage and scores a median tree IoU of 0.83 on real cut-outs over real photos against the colour
rules' 0.08 (docs/MODELS.md), but it takes the hedges and bushes behind a tree's foot into the tree
(the bundled sample among them: its reconstruction grows a bush skirt; Acer rubrum 2, Morus rubra 1),
so the colour rules stay the default and the network is one ``--segmenter learned`` away. Made the
default on 2026-11-26 as a trial, it also slowed the test suite from about 7.5 to 11.5 minutes."""
