"""Methods: one folder per paper, each a config over shared parts plus a pipeline.

``METHODS`` is the registry: name -> (one-line description, citation, pipeline entry point).
"""

METHODS = {
    "envelope": (
        "Single photo -> 3D tree: crown envelope + radial distance map + space colonization",
        "Argudo et al., Single-picture reconstruction and rendering of trees for plausible vegetation "
        "synthesis, Computers & Graphics 57 (2016)",
        "treeform.methods.envelope.pipeline:reconstruct",
    ),
}
