"""Readers and writers: GLB (glTF 2.0), OBJ + MTL, skeleton PLY/JSON, photos, masks and PNGs.

``save(obj, path)`` picks the writer by extension; every writer is atomic (temporary file,
then ``os.replace``) so a failure never leaves a partial output file. Pillow is imported
only when an image is read or written.
"""

from treeform.io.gltf import read_glb, read_glb_counts, write_glb
from treeform.io.images import MAX_PIXELS, read_mask, read_photo, read_rgba, write_png
from treeform.io.obj import write_obj
from treeform.io.ply import read_skeleton_ply, write_skeleton_ply
from treeform.io.outputs import (StagedOutputs, check_out_dir, check_out_file, start_tree_outputs, write_json,
                                  write_staged, write_tree_outputs)
from treeform.io.registry import known_extensions, register_writer, save
from treeform.io.trees import read_tree

__all__ = [
    "MAX_PIXELS",
    "StagedOutputs",
    "check_out_dir",
    "check_out_file",
    "known_extensions",
    "read_glb",
    "read_glb_counts",
    "read_mask",
    "read_photo",
    "read_rgba",
    "read_skeleton_ply",
    "read_tree",
    "register_writer",
    "save",
    "start_tree_outputs",
    "write_glb",
    "write_json",
    "write_obj",
    "write_png",
    "write_skeleton_ply",
    "write_staged",
    "write_tree_outputs",
]
