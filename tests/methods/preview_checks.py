"""Checks of preview.png shared by the pipeline tests (tests/methods is on sys.path under pytest)."""

import numpy as np

from treeform.report import preview_windows


def assert_panels_show_the_whole_tree(renders, preview, *, keep=None, first_panels=()):
    """Each 3D panel of preview.png: a background margin all round the tree, which fills >= half of it;
    a dark label above every panel. ``first_panels``: (H, W) of the panels before the 3D ones."""
    assert set(renders) == {"front", "side", "top"}
    windows = preview_windows({k: r.mask for k, r in renders.items()}, keep=keep)
    sizes = list(first_panels)
    for view in ("front", "side", "top"):
        full = renders[view].mask
        # the camera saw all of the tree: nothing touches its image's border
        assert not (full[0].any() or full[-1].any() or full[:, 0].any() or full[:, -1].any()), view
        m = full[windows[view]]
        assert not (m[0].any() or m[-1].any() or m[:, 0].any() or m[:, -1].any()), view
        ys, xs = np.nonzero(m)
        fill = max((np.ptp(ys) + 1) / m.shape[0], (np.ptp(xs) + 1) / m.shape[1])
        assert fill >= 0.5, (view, fill)
        sizes.append(m.shape)
    # panels are scaled to one height and laid out left to right with 6 px gaps under a label band
    widths = [round(w * 360 / h) for h, w in sizes]
    assert preview.shape[1] == sum(widths) + 6 * (len(widths) + 1)
    band = preview.shape[0] - 360 - 12
    assert band >= 12
    x = 6
    for w in widths:
        label = preview[6:6 + band - 2, x:x + w]
        assert (label.min(axis=2) < 100).sum() > 30  # dark text on the light band
        x += w + 6
