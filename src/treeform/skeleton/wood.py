"""2D skeleton of a tree from its visible wood: a shortest-path tree to the trunk base.

Seed 004 §3 infers branches from the foliage outline alone, for crowns that hide them. Where
the photo shows wood (leafless and sparse crowns, branches seen through gaps), the branches
are in the image and the skeleton should follow them. :func:`wood_skeleton` does this the way
seed 002 §5 builds its visible branch graph, in 2D: a cost image that is cheap along wood,
dearer across foliage (a branch hidden behind leaves is bridged, not lost) and closed outside
the tree; every branch tip (the end points of the thinned wood, plus the tips of the thinned
crown where foliage hides the wood) is joined to the base by its least-cost path (Dijkstra,
:class:`skimage.graph.MCP_Geometric`). The paths form a tree; it is cut into branches by the
"longest reach continues" rule: at every fork the child whose subtree reaches farthest carries
the parent on, the others start branches of the next order. The trunk is the chain from the
base; first-order branches leave it; and so on for ``levels`` orders. The paths are then found
once more with the trunk made cheaper up to its first contested fork (where two children could
lead): a tip's path follows its branch to the trunk instead of cutting across the branches it
crosses in the image on a diagonal to the base.

The result is a :class:`~treeform.skeleton.foliage.Skeleton2D` like the foliage skeleton's
(``meta["mode"] == "wood"``, no cuts), so drawing, lifting to 3D and the analysis-by-synthesis
pipeline take either.
"""

from __future__ import annotations

import cv2
import numpy as np
from scipy import ndimage as ndi

from treeform._shared.checks import check_array, check_int, check_positive
from treeform._shared.errors import InputError, NoTreeFoundError
from treeform.skeleton.field import check_mask, work_scale
from treeform.skeleton.foliage import MIN_PIXELS, Skeleton2D

__all__ = ["trunk_foot", "wood_skeleton", "wood_fraction", "wood_visible", "WOOD_VISIBLE"]

WOOD_VISIBLE = 0.05
"""Share of the tree's pixels that must be wood for its branches to count as visible: the
analysis-by-synthesis search then also proposes the wood skeleton, and ``skeleton2d`` picks it.
With the classical segmentation, leafless photos have 0.3-0.6, sparse or open crowns 0.05-0.2,
dense crowns under 0.05; the synthetic renders of the growth engine 0.02-0.12 leaves on."""

_EIGHT = np.ones((3, 3), np.uint8)
# Constants chosen on growth seeds 1-2 of benchmarks/skeleton_recall.py (pooled F1 of first-order
# branches, leaves on and off), held out on seeds 4-6 (see BENCHMARKS.md):
_WOOD_GAIN = 0.5  # step cost along wood: 1 + gain / (0.5 + distance to the wood's edge)
_PROMOTE = 0.04  # sibling rule, fraction of the tree's height: any side chain this near the attachment
_PROMOTE_BIG = 0.10  # ... and side chains reaching _BIG times as far as the chain goes on, this near
_BIG = 0.5
_TRUNK_STEP = 0.5  # second pass: step cost along the trunk below its first contested fork, times this


def wood_fraction(mask, wood) -> float:
    """Share of the tree's pixels that are wood, the cue that the branches are visible.

    Examples
    --------
    >>> m = np.zeros((10, 10), bool); m[2:8, 2:8] = True
    >>> w = np.zeros_like(m); w[2:8, 4] = True
    >>> round(wood_fraction(m, w), 3)
    0.167
    """
    m = check_mask(mask)
    w = check_mask(wood, "wood")
    n = int(m.sum())
    return float((w & m).sum()) / n if n else 0.0


def wood_visible(mask, wood) -> bool:
    """Whether the tree shows its branches: at least :data:`WOOD_VISIBLE` of its pixels are wood."""
    return wood_fraction(mask, wood) >= WOOD_VISIBLE


def wood_skeleton(mask, wood, *, trunk=None, levels: int = 2, max_side: int = 400, foliage_cost: float = 6.0,
                  min_length: float = 0.05, crown_tips: bool = True) -> Skeleton2D:
    """Skeleton of a tree image from its visible wood (shortest paths to the base).

    Parameters
    ----------
    mask : array_like, shape (H, W), bool
        Tree silhouette (wood and foliage).
    wood : array_like, shape (H, W), bool
        Wood pixels (trunk and branches); may be empty (then the crown's tips alone are used).
    trunk : array_like, shape (K, 2), optional
        Trunk polyline ``(x, y)`` from the base upward; its first point is the root of the
        paths. None: the trunk's foot found in the mask (the bottom of the thickest wood in
        the lowest 5 % of the tree, on its largest connected part).
    levels : int
        Branch orders to return (1..3) besides the trunk.
    max_side : int
        Long side of the working size (64..4096); thin branches survive the reduction (a
        working pixel is wood when a fifth of it is).
    foliage_cost : float
        Cost of a step through foliage relative to a step along wood (>= 1): how strongly
        the paths keep to visible wood.
    min_length : float
        Shortest branch kept, as a fraction of the tree's height in pixels (0..1).
    crown_tips : bool
        Also end paths at the tips of the thinned silhouette (branches hidden by foliage).

    Returns
    -------
    Skeleton2D
        Branch 0 the trunk, then the first-order branches by attachment height (base first),
        then the higher orders grouped by parent; ``partition`` labels each tree pixel with its
        nearest first-order branch; ``meta["mode"] == "wood"``.

    Raises
    ------
    InputError
        A mask is not 2-D, the shapes differ, or an option is out of range.
    NoTreeFoundError
        The mask has fewer than :data:`~treeform.skeleton.foliage.MIN_PIXELS` pixels.

    Examples
    --------
    >>> m = np.zeros((120, 80), bool)
    >>> m[20:118, 39:42] = True                      # trunk
    >>> for k in range(30):                          # one branch up to the right
    ...     m[70 - k, 41 + k:44 + k] = True
    >>> sk = wood_skeleton(m, m)
    >>> [int(o) for o in sk.order]
    [0, 1]
    >>> bool(sk.branches[1][-1, 0] > 65)             # its tip is at the right
    True
    """
    from skimage.graph import MCP_Geometric
    from skimage.morphology import skeletonize

    m = check_mask(mask)
    wd = check_mask(wood, "wood")
    if wd.shape != m.shape:
        raise InputError(f"wood: expected the mask's shape {m.shape}, got {wd.shape}")
    levels = check_int(levels, "levels", 1, 3)
    max_side = check_int(max_side, "max_side", 64, 4096)
    foliage_cost = check_positive(foliage_cost, "foliage_cost")
    if foliage_cost < 1.0:
        raise InputError(f"foliage_cost: expected a number >= 1, got {foliage_cost!r}")
    min_length = check_positive(min_length, "min_length", allow_zero=True)
    if min_length >= 1.0:
        raise InputError(f"min_length: expected a fraction in [0, 1), got {min_length!r}")
    if trunk is not None:
        trunk = check_array(trunk, "trunk", ndim=2, dtype_kind="biuf", shape=(None, 2), min_size=2).astype(float)
    count = int(m.sum())
    if count < MIN_PIXELS:
        raise NoTreeFoundError(f"mask: only {count} tree pixels, need at least {MIN_PIXELS}")
    H, W = m.shape
    h, w = work_scale((H, W), max_side)
    sx, sy = w / W, h / H
    scale = np.array([sx, sy])

    def small(a):
        if (h, w) == (H, W):
            return a.copy()
        return cv2.resize(a.astype(np.float32), (w, h), interpolation=cv2.INTER_AREA) >= 0.2

    mw = small(m)
    ww = small(wd & m) & mw
    # bridge the one-pixel gaps of thin, aliased branches
    passable = cv2.morphologyEx(mw.astype(np.uint8), cv2.MORPH_CLOSE, _EIGHT).astype(bool) | mw
    dt_wood = ndi.distance_transform_edt(ww)
    cost = np.full((h, w), np.inf)
    cost[passable] = foliage_cost
    cost[ww] = 1.0 + _WOOD_GAIN / (0.5 + dt_wood[ww])  # cheapest along thick wood, along its middle

    ys = np.nonzero(mw.any(axis=1))[0]
    tree_h = max(float(ys.max() - ys.min()), 1.0)
    if trunk is not None:
        root = (trunk[0] + 0.5) * scale - 0.5
    else:
        col, row = trunk_foot(passable, ww, connected=True)
        root = np.array([col, float(row)])
    root = _nearest_pixel(passable, root)

    mcp = MCP_Geometric(cost, fully_connected=True)
    reach_cost, trace = mcp.find_costs([tuple(root)])
    tips = _end_points(skeletonize(ww))
    if crown_tips:
        crown = cv2.morphologyEx(mw.astype(np.uint8), cv2.MORPH_OPEN, _EIGHT).astype(bool)
        tips = np.vstack([tips, _end_points(skeletonize(ndi.binary_fill_holes(crown)))])
    if len(tips):
        tips = tips[np.isfinite(reach_cost[tips[:, 0], tips[:, 1]])]
    pix, parent = _path_tree(trace, np.asarray(mcp.offsets), tuple(root), tips)
    opts = dict(levels=levels, min_len=min_length * tree_h, look=max(4.0, 0.04 * tree_h),
                promote=_PROMOTE * tree_h, promote_big=_PROMOTE_BIG * tree_h)
    trunk0 = _decompose(pix, parent, **{**opts, "levels": 0})[0]  # the trunk alone
    sure = trunk0["nodes"][:trunk0["contested"] + 1]
    if len(sure) >= 2:
        # Second pass: the trunk up to its first contested fork costs _TRUNK_STEP as much, so a tip's
        # path runs to the trunk and down it rather than cutting across the branches it overlaps in
        # the image on a diagonal to the foot (the branches then leave the trunk where they do).
        tp = pix[sure]
        cost[tp[:, 0], tp[:, 1]] *= _TRUNK_STEP
        mcp = MCP_Geometric(cost, fully_connected=True)
        _, trace = mcp.find_costs([tuple(root)])
        pix, parent = _path_tree(trace, np.asarray(mcp.offsets), tuple(root), tips)
    chains = _decompose(pix, parent, **opts)

    def to_full(p):
        return (np.asarray(p, float) + 0.5) / scale - 0.5

    dt_mask = ndi.distance_transform_edt(m)
    branches, widths, order, par = [], [], [], []
    for ch in chains:
        xy = _smooth(pix[ch["nodes"]][:, ::-1].astype(float))
        full = np.clip(to_full(xy), 0, [W - 1, H - 1])
        ij = np.round(full).astype(int)
        branches.append(full)
        widths.append(np.zeros(len(full)) if ch["order"] == 0 else dt_mask[ij[:, 1], ij[:, 0]].astype(float))
        order.append(ch["order"])
        par.append(ch["parent"])
    if trunk is not None and len(branches[0]) < 2:
        branches[0] = np.asarray(trunk, float)
        widths[0] = np.zeros(len(trunk))
    partition, area_branch = _partition(m, branches, order)
    meta = {"mode": "wood", "levels": levels, "max_side": max_side, "foliage_cost": foliage_cost,
            "min_length": min_length, "crown_tips": bool(crown_tips), "work_shape": [h, w],
            "scale": [float(sx), float(sy)], "trunk_auto": trunk is None, "tips": int(len(tips)),
            "wood_fraction": round(float((wd & m).sum()) / count, 4),
            "n_first_order": int(sum(1 for o in order if o == 1)), "area_branch": area_branch,
            "dce_polygon": [], "ending_points": [], "sub_cuts": []}
    return Skeleton2D(shape=(H, W), branches=branches, widths=widths, order=np.asarray(order, np.int32),
                      parent=np.asarray(par, np.int64), cuts=[], partition=partition, field=None, meta=meta)


# ----------------------------------------------------------------------------- helpers

def trunk_foot(tree: np.ndarray, wood: np.ndarray | None = None, *, connected: bool = False) -> tuple[float, int]:
    """Pixel ``(column, row)`` of the trunk's foot in a tree mask.

    In the lowest 5 % of the tree's rows the thickest wood (the thickest tree where no wood
    shows there) is the trunk: a drooping twig or a weeping curtain may hang lower than the
    trunk's foot, but it is thinner (one hanging lower than 5 % of the height is taken for the
    foot: a wider band would take a fork's thick junction for the trunk). The column is the
    middle of that thickest ridge, the row the lowest tree pixel within its half-width (plus two
    pixels) of it.

    Parameters
    ----------
    tree : ndarray, shape (H, W), bool
        Tree mask (not empty).
    wood : ndarray, shape (H, W), bool, optional
        Wood pixels.
    connected : bool
        Only the largest 8-connected part of the tree counts (for paths that must reach the
        whole crown from the foot). Otherwise every part does: a photo's mask may lose the
        trunk's middle (a bare tree against branches behind it) and keep its foot.

    Returns
    -------
    tuple
        ``(column, row)``: a column (float, pixel indices) and a row (int).

    Examples
    --------
    >>> t = np.zeros((100, 30), bool); t[5:90, 13:17] = True  # a trunk, its foot on row 89
    >>> t[50:92, 24] = True                                   # a hanging twig, lower
    >>> trunk_foot(t)
    (14.5, 89)
    """
    tree = np.asarray(tree, bool)
    comp = tree
    if connected:
        lab, n = ndi.label(tree, _EIGHT)
        if n > 1:
            comp = lab == 1 + int(np.argmax(np.bincount(lab.ravel())[1:]))
    ys, xs = np.nonzero(comp)
    if len(ys) == 0:
        raise NoTreeFoundError("no tree found: the tree mask is empty")
    size = int(ys.max() - ys.min()) + 1
    band = ys >= ys.max() - max(1.0, 0.05 * size)
    w = comp & np.asarray(wood, bool) if wood is not None else None
    base = w if w is not None and w[ys[band], xs[band]].any() else comp
    half = ndi.distance_transform_edt(base)[ys[band], xs[band]]
    k = int(np.argmax(half))
    x0 = xs[band][k]
    ridge = (half >= half[k] - 0.5) & (np.abs(xs[band] - x0) <= half[k])
    col = float(xs[band][ridge].mean())
    near = band & (np.abs(xs - col) <= half[k] + 2)
    return col, int(ys[near].max())


def _nearest_pixel(mask: np.ndarray, p: np.ndarray) -> np.ndarray:
    """(row, col) of the ``mask`` pixel nearest to the point ``p = (x, y)``."""
    ys, xs = np.nonzero(mask)
    k = int(np.argmin((xs - p[0]) ** 2 + (ys - p[1]) ** 2))
    return np.array([ys[k], xs[k]], np.int64)


def _end_points(sk: np.ndarray) -> np.ndarray:
    """(row, col) of the pixels of a thinned image with exactly one 8-neighbour."""
    n = cv2.filter2D(sk.astype(np.uint8), -1, _EIGHT, borderType=cv2.BORDER_CONSTANT)
    return np.argwhere(sk & (n == 2)).astype(np.int64)


def _path_tree(trace: np.ndarray, offsets: np.ndarray, root: tuple,
               tips: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The least-cost paths from ``tips`` back to ``root`` as one tree of pixels.

    ``trace`` and ``offsets`` are an :class:`~skimage.graph.MCP` search's from ``root`` alone
    (``find_costs``' traceback array, ``mcp.offsets``): a pixel was reached from itself minus
    ``offsets[trace[pixel]]``. Each tip's path is followed back only until it meets a pixel
    already in the tree, so every pixel is visited once, not once per tip whose path crosses it.

    Returns ``(pix, parent)``: ``(N, 2)`` (row, col) and ``(N,)``; node 0 is the root
    (``parent[0] == -1``) and every parent is created before its children.
    """
    node_of = {root: 0}
    parent, pix = [-1], [root]
    for r, c in tips:
        p = (int(r), int(c))
        new = []
        while p not in node_of:
            new.append(p)
            d = offsets[trace[p]]
            p = (p[0] - int(d[0]), p[1] - int(d[1]))
        prev = node_of[p]
        for q in reversed(new):
            node_of[q] = len(pix)
            pix.append(q)
            parent.append(prev)
            prev = node_of[q]
    return np.asarray(pix, np.int64), np.asarray(parent, np.int64)


def _decompose(pix: np.ndarray, parent: np.ndarray, *, levels: int, min_len: float, look: float,
               promote: float = 0.0, promote_big: float = 0.0) -> list[dict]:
    """Cut a pixel tree into chains: at each fork the straightest far-reaching child continues.

    At a fork of a branch, the children whose subtree reaches at least half as far (arc
    length) as the farthest one compete; at a fork of the trunk, those whose subtree climbs
    within ``2 look`` rows of the highest one (the leader reaches the top of the tree). The
    one turning least from the parent's direction (both measured over ``look`` pixels, the
    child's along its farthest-reaching path) carries the chain on, the others
    start chains of the next order — except on a branch (not the trunk) near its attachment:
    a side chain forking within ``promote`` pixels of it, or within ``promote_big`` pixels and
    reaching at least :data:`_BIG` times as far as the chain goes on from there, is the chain's
    sibling (same order, same parent): two limbs whose stems share pixels in the image. Returns
    the chains breadth first (trunk first), each ``{"nodes", "order", "parent"}`` with
    ``nodes`` from the attachment (the fork pixel) to the tip (the trunk's also has
    ``"contested"``: the index in ``nodes`` of its first fork where more than one child could
    lead, its last node if none; ``levels=0`` gives the trunk alone); a side chain whose reach from
    its fork is under ``min_len`` pixels is dropped with its subtree.
    """
    n = len(parent)
    step = np.zeros(n)
    step[1:] = np.linalg.norm(pix[1:] - pix[parent[1:]], axis=1)
    depth = np.zeros(n)
    for k in range(1, n):  # parents are created before their children
        depth[k] = depth[parent[k]] + step[k]
    reach = depth.copy()  # farthest arc length below each node
    heavy = np.full(n, -1, np.int64)  # the child on the path to that farthest point
    for k in range(n - 1, 0, -1):
        p = parent[k]
        if reach[k] > reach[p] or (reach[k] == reach[p] and heavy[p] > k):
            reach[p] = reach[k]
            heavy[p] = k
    top = pix[:, 0].astype(float)  # highest row (smallest) below each node
    for k in range(n - 1, 0, -1):
        top[parent[k]] = min(top[parent[k]], top[k])
    children: list[list[int]] = [[] for _ in range(n)]
    for k in range(1, n):
        children[parent[k]].append(k)

    def ahead(k: int) -> np.ndarray:
        start = depth[parent[k]]
        while heavy[k] >= 0 and depth[k] - start < look:
            k = int(heavy[k])
        return pix[k].astype(float)

    def behind(k: int) -> np.ndarray:
        end = depth[k]
        while parent[k] >= 0 and end - depth[k] < look:
            k = int(parent[k])
        return pix[k].astype(float)

    def unit(v):
        return v / max(float(np.linalg.norm(v)), 1e-9)

    up = np.array([-1.0, 0.0])  # (row, col): the trunk starts upward
    chains: list[dict] = []
    queue = [(0, 0, -1)]  # (start node, order, parent chain)
    while queue:
        start, o, pc = queue.pop(0)
        nodes = [start] if start == 0 else [int(parent[start]), start]
        k = start
        sides = []
        contested = None
        while children[k]:
            kids = children[k]
            if len(kids) > 1:
                if o == 0:
                    high = min(top[c] for c in kids)
                    pool = [c for c in kids if top[c] <= high + 2 * look]
                    if len(pool) > 1 and contested is None:
                        contested = len(nodes) - 1
                else:
                    far = max(reach[c] - depth[k] for c in kids)
                    pool = [c for c in kids if reach[c] - depth[k] >= 0.5 * far]
                d_in = unit(pix[k] - behind(k)) if k else up
                best = max(pool, key=lambda c: (float(unit(ahead(c) - pix[k]) @ d_in), -c))
            else:
                best = kids[0]
            sides += [c for c in kids if c != best]
            k = best
            nodes.append(k)
        idx = len(chains)
        chains.append({"nodes": np.asarray(nodes, np.int64), "order": o, "parent": pc})
        if o == 0:  # the trunk's first fork where more than one child could lead (its last node if none)
            chains[-1]["contested"] = len(nodes) - 1 if contested is None else contested
        base = depth[nodes[0]]
        after = dict(zip(nodes[:-1], nodes[1:]))
        for s_ in sorted(sides, key=lambda c: depth[c]):
            f = int(parent[s_])
            own = reach[s_] - depth[f]
            if own >= max(min_len, 2.0):
                near = depth[f] - base < promote
                big = depth[f] - base < promote_big and own >= _BIG * (reach[after[f]] - depth[f])
                if o >= 1 and (near or big):  # a sibling sharing the stem's pixels
                    queue.append((s_, o, pc))
                elif o < levels:
                    queue.append((s_, o + 1, idx))
    return chains


def _smooth(xy: np.ndarray, window: int = 5) -> np.ndarray:
    """Moving average of a pixel chain (ends kept), then one point every ~2 pixels."""
    if len(xy) > window:
        k = np.ones(window) / window
        pad = window // 2
        ext = np.vstack([np.repeat(xy[:1], pad, 0), xy, np.repeat(xy[-1:], pad, 0)])
        sm = np.stack([np.convolve(ext[:, j], k, mode="valid") for j in range(2)], axis=1)
        sm[0], sm[-1] = xy[0], xy[-1]
        xy = sm
    keep = np.unique(np.r_[np.arange(0, len(xy), 2), len(xy) - 1])
    out = xy[keep]
    return out if len(out) >= 2 else np.vstack([xy[:1], xy[-1:]])


def _partition(mask: np.ndarray, branches: list, order: list) -> tuple[np.ndarray, list]:
    """Each mask pixel's nearest first-order branch (area index), and the area -> branch table."""
    H, W = mask.shape
    first = [i for i, o in enumerate(order) if o == 1]
    part = np.full((H, W), -1, np.int32)
    if not first:
        part[mask] = 0
        return part, [-1]
    lines = np.zeros((H, W), np.int32)
    for a, i in enumerate(first):
        p = np.round(np.asarray(branches[i]) * 16).astype(np.int32).reshape(-1, 1, 2)
        cv2.polylines(lines, [p], False, a + 1, 1, cv2.LINE_8, shift=4)
    _, (iy, ix) = ndi.distance_transform_edt(lines == 0, return_indices=True)
    part = lines[iy, ix] - 1
    part[~mask] = -1
    return part.astype(np.int32), first
