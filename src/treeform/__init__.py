"""treeform: photographs of real trees to 3D tree assets.

The top-level namespace stays light (no OpenGL, no OpenCV at import) so that
``treeform --help`` is fast; :func:`reconstruct` imports its pipeline lazily.
"""

__version__ = "0.1.0"

__all__ = ["__version__", "reconstruct"]


def reconstruct(*args, **kwargs):
    """Single photo -> 3D tree (paper 001). See :func:`treeform.methods.envelope.pipeline.reconstruct`."""
    from treeform.methods.envelope.pipeline import reconstruct as _reconstruct

    return _reconstruct(*args, **kwargs)
