"""Batch reconstruction: a folder of photos, one task per photo on Dask (``treeform batch``)."""

from treeform.batch.run import PHOTO_SUFFIXES, list_photos, parse_memory, reconstruct_one, run_batch

__all__ = ["PHOTO_SUFFIXES", "list_photos", "parse_memory", "reconstruct_one", "run_batch"]
