"""The one error hierarchy of treeform.

Every error a user can cause derives from :class:`TreeformError`; the CLI turns
it into one line on stderr and a non-zero exit status, without a traceback.
"""


class TreeformError(Exception):
    """Base class of all errors treeform raises on purpose."""

    exit_code = 1


class InputError(TreeformError, ValueError):
    """A bad argument or an unreadable / invalid input file."""

    exit_code = 2


class NoTreeFoundError(TreeformError):
    """The photo contains no tree the segmentation can find."""

    exit_code = 3


class OutputError(TreeformError):
    """The output location cannot be written."""

    exit_code = 4


class RenderError(TreeformError):
    """No OpenGL context could be created (e.g. Mesa EGL is missing)."""

    exit_code = 5


class ModelError(TreeformError):
    """A shipped network's weights file is missing or unreadable (rebuild with ``make weights``)."""

    exit_code = 6


class SfmError(TreeformError):
    """Structure from motion could not register the photos (too few, too little overlap, degenerate)."""

    exit_code = 7
