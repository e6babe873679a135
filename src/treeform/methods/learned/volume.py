"""The radial bounding volume of an existing tree (paper 003 §4.1): what ``grow --rbv`` reads."""

from __future__ import annotations

from treeform._shared.errors import InputError


def fit_rbv(tree, *, level: int = 4, out=None, plot=None):
    """Fit the radial bounding volume of a tree and write it (``.npz``) and optionally a picture.

    ``tree`` is a treeform output folder, a skeleton JSON or a GLB (see
    :func:`treeform.io.read_tree`): a skeleton gives the volume of its branch surfaces, any
    other GLB that of its vertices around the vertical axis through its lowest point.
    """
    import numpy as np

    from treeform.io import check_out_file, read_tree, write_png
    from treeform.structures import RadialBoundingVolume, TreeSkeleton

    if isinstance(level, bool) or level not in (1, 2, 3, 4, 5):
        raise InputError(f"--level: expected 1..5, got {level!r}")
    out_p = check_out_file(out, suffix=".npz") if out is not None else None
    plot_p = check_out_file(plot, "--plot") if plot is not None else None
    tree = read_tree(tree)
    if isinstance(tree, TreeSkeleton):
        rbv = RadialBoundingVolume.from_skeleton(tree, level=level)
    else:
        low = tree[:, 1] <= tree[:, 1].min() + 0.02 * max(float(np.ptp(tree[:, 1])), 1e-9)
        x, z = tree[low][:, [0, 2]].mean(axis=0)
        rbv = RadialBoundingVolume.from_points(tree, level=level, axis_origin=(x, float(tree[:, 1].min()), z))
    if out_p is not None:
        rbv.save(out_p)
    if plot_p is not None:
        from treeform.report.rbv_plot import plot_rbv

        write_png(plot_rbv(rbv), plot_p)
    return rbv
