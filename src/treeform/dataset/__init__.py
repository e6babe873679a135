"""Synthetic training data at scale (seed 003 §4.2.1–4.2.2).

- :func:`make_sample` — one photo-like render of a grown tree with its exact mask, RBV
  levels 1–5, species id, growth parameters and skeleton, reproducible from (seed, index);
- :func:`procedural_background`, :class:`BackgroundPool` — the backgrounds;
- :func:`generate_dataset` — many samples on Dask distributed into resumable tar shards;
- :class:`SyntheticDataset`, :class:`Augment`, :func:`torch_dataset` — reading, augmenting
  and batching for training code;
- :func:`show_dataset` — a contact sheet of images and masks.
"""

from treeform.dataset.augment import Augment, mirror_rbv
from treeform.dataset.backgrounds import BACKGROUND_KINDS, BackgroundPool, procedural_background
from treeform.dataset.generate import GenerateResult, generate_dataset, parse_species, sample_members
from treeform.dataset.loader import SyntheticDataset, torch_dataset
from treeform.dataset.sheet import contact_sheet, mask_to_rgb, show_dataset
from treeform.dataset.synthetic import LABELS, Sample, SampleOptions, make_sample, sample_rng

__all__ = [
    "Augment",
    "BACKGROUND_KINDS",
    "BackgroundPool",
    "GenerateResult",
    "LABELS",
    "Sample",
    "SampleOptions",
    "SyntheticDataset",
    "contact_sheet",
    "generate_dataset",
    "make_sample",
    "mask_to_rgb",
    "mirror_rbv",
    "parse_species",
    "procedural_background",
    "sample_members",
    "sample_rng",
    "show_dataset",
    "torch_dataset",
]
