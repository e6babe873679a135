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
    "learned": (
        "Single photo -> 3D tree: segmentation, species and radial-bounding-volume networks + bi-modal "
        "growth of the species' developmental model (also: grow a named species)",
        "Li et al., Learning to reconstruct botanical trees from single images, ACM TOG 40(6) (2021)",
        "treeform.methods.learned.pipeline:reconstruct",
    ),
    "abs": (
        "Single photo -> 3D tree by analysis by synthesis: foliage skeletonisation (force field, DCE "
        "cuts), an L-system generative model, the best of N candidates by reprojection error",
        "Guénard et al., Reconstructing plants in 3D from a single image using analysis-by-synthesis, ISVC (2013)",
        "treeform.methods.synthesis.pipeline:reconstruct",
    ),
    "multiview": (
        "Several photos around one tree -> 3D tree: structure from motion (pycolmap), per-view tree mattes, "
        "their visual hull partitioned into branch and leaf points, the visible branch graph, hidden "
        "branches grown into the leaf volume",
        "Tan et al., Image-based tree modeling, ACM TOG 26(3), SIGGRAPH (2007)",
        "treeform.methods.multiview.pipeline:reconstruct_multiview",
    ),
    "variations": (
        "New RGBA tree images from a library of RGBA trees (contour synthesis + mean value coordinates); "
        "photo -> RGBA billboard by alpha matting; picture -> billboard cloud (alpha-tested GLB)",
        "Argudo et al., Image-based tree variations, Computer Graphics Forum 39(1) (2020)",
        "treeform.methods.variations.pipeline:vary",
    ),
}
