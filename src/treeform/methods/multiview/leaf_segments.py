"""Leaves from the photos' leaf regions (seed 002 §6.2): placed on the 3D points, de-duplicated, synthesized.

Each registered view's foliage is cut into candidate leaves
(:func:`treeform.segment.leaf_regions.leaf_regions`: mean shift in LUV, split or merge,
the brightest colour clusters, an ellipse per region). A kept region becomes a leaf at the
carved leaf point nearest the camera along the line of sight of its centroid (the tree's
skeleton nodes where no leaf point lies on it), facing the plane the SVD fits to the leaf
points seen inside the region when more than three are, else parallel to the image plane
with its major axis along the ellipse's; its card as large as the ellipse at that depth.
Views do not share regions, so one leaf comes back from several views: leaves within half a
leaf's width of a larger one go. Last, the branches with the fewest leaves per metre (the
bottom third) get the leaves of a branch among the densest third, turned and scaled onto
them (the paper's synthesis of the leaves the photos do not cover), where they land in the
leaf volume; round after round (:func:`fill_sparse`), counting the copies, until the leaf
budget is spent.
"""

from __future__ import annotations

import numpy as np

__all__ = ["segmented_leaves", "fork_chains", "synthesize_sparse", "fill_sparse"]


def fork_chains(parent: np.ndarray) -> np.ndarray:
    """(N,) index of the run of nodes between forks each node is on (the root's run is 0).

    Unlike :meth:`~treeform.structures.TreeSkeleton.chains` (a branch goes on through its main
    child), every fork ends a run here: the internodes between branchings.

    >>> fork_chains(np.array([-1, 0, 1, 1, 3])).tolist()
    [0, 0, 1, 2, 2]
    """
    parent = np.asarray(parent)
    n = len(parent)
    children = np.bincount(parent[parent >= 0], minlength=n)
    chain = np.zeros(n, np.int64)
    nxt = 1
    for i in range(1, n):  # parents come before their children
        p = parent[i]
        if p < 0 or children[p] != 1:
            chain[i] = nxt
            nxt += 1
        else:
            chain[i] = chain[p]
    return chain


def synthesize_sparse(positions: np.ndarray, node: np.ndarray, skeleton, rng, *, inside=None,
                      skip_chain0: bool = True):
    """Leaves for the sparsest third of the branches, copied from the densest third (seed 002 §6.2).

    Branches are the runs of nodes between forks (:func:`fork_chains`; the root's, the trunk's,
    is skipped with ``skip_chain0``): on the oak capture they score 0.70 novel-view IoU against
    0.62 for the skeleton's main-child chains (:meth:`~treeform.structures.TreeSkeleton.chains`),
    whose long branches take copies spread along their whole length. ``inside`` (N,) bool, optional: the skeleton's nodes in the crown's leaf
    volume; only branches with a node there are synthesized or copied (a bare limb below the crown stays bare: the
    photos would show its leaves). Returns ``(idx, new_positions, new_node)``: each synthesized
    leaf copies leaf ``idx`` (its orientation, size and colour) at ``new_positions`` on twig
    ``new_node``.
    """
    from treeform.methods.multiview.replication import rotation_onto

    pos = np.asarray(skeleton.positions, np.float64)
    par = np.asarray(skeleton.parent)
    chain = fork_chains(par)
    nc = int(chain.max()) + 1
    seg = np.where(par >= 0, np.linalg.norm(pos - pos[np.maximum(par, 0)], axis=1), 0.0)
    length = np.bincount(chain, seg, nc)
    # each branch's start (the parent of its first node: the fork) and end (its last node)
    first = np.full(nc, len(par))
    np.minimum.at(first, chain, np.arange(len(par)))
    last = np.full(nc, -1)
    np.maximum.at(last, chain, np.arange(len(par)))
    start = np.where(par[first] >= 0, par[first], first)
    count = np.bincount(chain[node], minlength=nc)
    cand = np.flatnonzero(length > 0)
    if skip_chain0:
        cand = cand[cand != chain[0]]
    if inside is not None:
        cand = cand[np.bincount(chain, np.asarray(inside, np.float64), nc)[cand] > 0]
    if len(cand) < 3 or not count[cand].any():
        return np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0, np.int64)
    density = count[cand] / length[cand]
    order = cand[np.argsort(density, kind="stable")]
    third = len(order) // 3
    sparse, dense = order[:third], order[-third:]
    dense = dense[count[dense] > 0]
    if not len(dense) or not len(sparse):
        return np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0, np.int64)
    leaf_chain = chain[node]
    idx, new_pos, new_node = [], [], []
    for c in sparse:
        # an exemplar of about the branch's length (its leaves are scaled by the ratio of the lengths)
        ratio = length[dense] / length[c]
        like = dense[(ratio > 0.5) & (ratio < 2.0)]
        e = like[rng.integers(len(like))] if len(like) else dense[np.argmin(np.abs(np.log(ratio)))]
        a0, a1 = pos[start[e]], pos[last[e]]
        b0, b1 = pos[start[c]], pos[last[c]]
        va, vb = a1 - a0, b1 - b0
        la, lb = np.linalg.norm(va), np.linalg.norm(vb)
        if la < 1e-9 or lb < 1e-9:
            continue
        R = rotation_onto(va / la, vb / lb)
        mine = np.flatnonzero(leaf_chain == e)
        p = (positions[mine] - a0) @ R.T * (lb / la) + b0
        nodes_c = np.flatnonzero(chain == c)
        near = nodes_c[np.argmin(np.linalg.norm(pos[nodes_c][None] - p[:, None], axis=2), axis=1)]
        idx.append(mine)
        new_pos.append(p)
        new_node.append(near)
    if not idx:
        return np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0, np.int64)
    return np.concatenate(idx), np.concatenate(new_pos), np.concatenate(new_node)


def fill_sparse(positions: np.ndarray, node: np.ndarray, skeleton, rng, *, budget: int, rounds: int = 4,
                inside=None, volume=None, reach: float = 0.0):
    """``rounds`` rounds of :func:`synthesize_sparse`, or fewer where ``budget`` leaves are made.

    Each round counts the leaves synthesized so far, so the branches that were the sparsest
    third have leaves now and the next sparsest third is filled (one round of seed 002 §6.2
    leaves its "more evenly distributed leaf density" half done: on the 24-view oak capture it
    spends 3,378 of the 8,626 leaves the budget has room for and scores novel-view IoU 0.534;
    rounds until the budget is spent, 0.777). ``volume`` (a ``scipy.spatial.cKDTree`` of the
    leaf points), optional: a copy farther than ``reach`` from every leaf point goes. Where a
    round makes more than the budget has room for, a random share of all the rounds' copies is
    kept (the earlier rounds' first scores 0.766 there). Returns ``(idx, new_positions,
    new_node)`` as :func:`synthesize_sparse`: ``idx`` always indexes ``positions`` (a copy of a
    copy names the original).

    >>> from treeform.structures import TreeSkeleton
    >>> pos = np.array([[0, 0, 0], [0, 1, 0], [0, 2, 0], [1, 3, 0], [-1, 3, 0], [0, 3, 1], [0, 3, -1]], float)
    >>> sk = TreeSkeleton(pos, np.array([-1, 0, 1, 2, 2, 2, 2]))
    >>> leaves = np.array([[1.0, 2.9, 0], [0.5, 2.5, 0]])
    >>> idx, new, twig = fill_sparse(leaves, np.array([3, 3]), sk, np.random.default_rng(0), budget=10,
    ...                              rounds=3)
    >>> len(idx), sorted(set(twig.tolist()))  # a round each: the three bare limbs get the first limb's leaves
    (6, [4, 5, 6])
    """
    positions = np.asarray(positions, np.float64)
    node = np.asarray(node)
    src, all_pos, all_node = np.arange(len(positions)), positions, node
    idx, spos, snode = np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros(0, np.int64)
    for _ in range(max(0, int(rounds))):
        if len(idx) >= budget:
            break
        i, p, q = synthesize_sparse(all_pos, all_node, skeleton, rng, inside=inside)
        if volume is not None and len(p):
            near = volume.query(p, distance_upper_bound=reach)[0] <= reach
            i, p, q = i[near], p[near], q[near]
        if not len(i):
            break
        i = src[i]
        idx, spos, snode = np.concatenate([idx, i]), np.concatenate([spos, p]), np.concatenate([snode, q])
        src, all_pos, all_node = np.concatenate([src, i]), np.concatenate([all_pos, p]), np.concatenate([all_node, q])
    if len(idx) > budget:
        pick = np.sort(rng.choice(len(idx), max(0, budget), replace=False))
        idx, spos, snode = idx[pick], spos[pick], snode[pick]
    return idx, spos, snode


def _view_leaves(pts, skel_pts, K, w2c, c2w, lab, img, size, seed):
    """The leaves one view's regions give: (positions, normals, up, size, colour, area)."""
    from scipy.spatial import cKDTree

    from treeform.methods.multiview.carve import _pixels, _project
    from treeform.segment.leaf_regions import leaf_regions

    h, w = lab.shape
    foliage = lab == 1
    ok, row, col, z = _pixels(pts, w2c, K, (h, w))
    ok &= foliage[row, col]
    if ok.sum() < 4:
        return None
    f = float(K[0, 0])
    depth = float(np.median(z[ok]))
    side_px = size * f / depth
    regions = leaf_regions(img, foliage, leaf_area=max(4.0, side_px * side_px), seed=seed)
    keep = np.flatnonzero(regions.kept)
    if not len(keep):
        return None
    # the point nearest the camera on each pixel (a z-buffer of the points), then the nearest within
    # ``reach`` pixels of each region's centroid: the leaf point on its line of sight
    ids = np.flatnonzero(ok)
    pix = row[ids] * w + col[ids]
    order = np.lexsort((z[ids], pix))
    first = np.r_[True, pix[order][1:] != pix[order][:-1]]
    zbuf = np.full(h * w, -1, np.int64)
    zbuf[pix[order][first]] = ids[order][first]
    cen = regions.centroid[keep]
    rad = np.maximum(1.0, regions.axes[keep, 1])
    reach = 2
    cx = np.clip(np.round(cen[:, 0]).astype(np.int64), 0, w - 1)
    cy = np.clip(np.round(cen[:, 1]).astype(np.int64), 0, h - 1)
    anchor = np.full(len(keep), -1)
    best = np.full(len(keep), np.inf)
    for dy in range(-reach, reach + 1):
        for dx in range(-reach, reach + 1):
            x, y = cx + dx, cy + dy
            inb = (x >= 0) & (x < w) & (y >= 0) & (y < h)
            cand = np.where(inb, zbuf[np.clip(y, 0, h - 1) * w + np.clip(x, 0, w - 1)], -1)
            zc = np.where(cand >= 0, z[np.maximum(cand, 0)], np.inf)
            better = zc < best
            anchor[better], best[better] = cand[better], zc[better]
    pos = np.full((len(keep), 3), np.nan)
    got = anchor >= 0
    pos[got] = pts[anchor[got]]
    zs = np.full(len(keep), np.nan)
    zs[got] = z[anchor[got]]
    if len(skel_pts) and (~got).any():  # no leaf point on the line of sight: the nearest branch on it
        sok, _, _, sz = _pixels(skel_pts, w2c, K, (h, w))
        suv = _project(skel_pts, w2c, K)[0]
        if sok.any():
            st = cKDTree(suv[sok])
            sids = np.flatnonzero(sok)
            miss = np.flatnonzero(~got)
            for j, hs in zip(miss, st.query_ball_point(cen[miss], 2.0 * rad[miss])):
                if hs:
                    c = sids[hs][np.argmin(sz[sids[hs]])]
                    pos[j], zs[j] = skel_pts[c], sz[c]
    placed = np.isfinite(zs)
    if not placed.any():
        return None
    keep, cen, pos, zs = keep[placed], cen[placed], pos[placed], zs[placed]
    R = c2w[:3, :3]
    toward = c2w[:3, 3][None] - pos
    toward /= np.linalg.norm(toward, axis=1, keepdims=True)
    ang = regions.angle[keep]
    up = np.stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)], 1) @ R.T  # the ellipse's major axis
    normal = toward.copy()
    # SVD of the leaf points seen inside each region, near its leaf's depth: the leaf's plane
    reg = np.full(len(regions), -1)
    reg[keep] = np.arange(len(keep))
    r_of = np.where(ok, regions.labels[row, col], -1)
    r_of = np.where(r_of >= 0, reg[np.maximum(r_of, 0)], -1)
    near = r_of >= 0
    near[near] = np.abs(z[near] - zs[r_of[near]]) <= 2.0 * size
    j = r_of[near]
    if len(j):
        p = pts[near]
        n = np.bincount(j, minlength=len(keep)).astype(np.float64)
        mean = np.stack([np.bincount(j, p[:, c], len(keep)) for c in range(3)], 1) / np.maximum(n, 1)[:, None]
        d = p - mean[j]
        cov = np.zeros((len(keep), 3, 3))
        for a in range(3):
            for b in range(a, 3):
                cov[:, a, b] = cov[:, b, a] = np.bincount(j, d[:, a] * d[:, b], len(keep))
        fit = n > 3
        if fit.any():
            _, vec = np.linalg.eigh(cov[fit])
            nrm, major = vec[:, :, 0], vec[:, :, 2]
            flip = np.sum(nrm * toward[fit], axis=1) < 0
            nrm[flip] *= -1
            normal[fit], up[fit] = nrm, major
    # up normal to the normal
    up -= np.sum(up * normal, axis=1, keepdims=True) * normal
    bad = np.linalg.norm(up, axis=1) < 1e-6
    up[bad] = np.cross(normal[bad], R[:, 0])
    up /= np.linalg.norm(up, axis=1, keepdims=True)
    card = np.clip(2.0 * regions.axes[keep, 0] * zs / f, 0.25 * size, 4.0 * size)
    inside = regions.labels >= 0
    li = regions.labels[inside]
    a = np.maximum(np.bincount(li, minlength=len(regions)), 1)
    rgb = np.stack([np.bincount(li, img[..., c][inside].astype(np.float64), len(regions)) for c in range(3)],
                   1) / a[:, None] / 255.0
    return pos, normal, up, card, rgb[keep], regions.area[keep].astype(np.float64)


def segmented_leaves(points, skeleton, K, cam_to_world, labels, images, *, size: float, leaves: int, rng,
                     card_scale: float = 1.0, seed: int = 0, threads: int = 2, rounds: int = 1):
    """Leaves from every view's leaf regions, de-duplicated, plus the synthesized ones (seed 002 §6.2).

    Parameters
    ----------
    points : ndarray, shape (P, 3)
        The carved leaf points.
    skeleton : TreeSkeleton
        The grown tree (the fallback anchors, and the branches for the synthesis).
    K, cam_to_world : sequences of (3, 3) and (4, 4) arrays
        The views' intrinsics at the mattes' size and poses (OpenCV axes).
    labels, images : sequences of arrays
        The views' mattes (0/1/2) and photos at the mattes' size.
    size : float
        A leaf cluster's card edge in metres (the regions' size is this at the tree's depth).
    leaves : int
        At most this many leaves (the synthesized ones go first, then the smallest regions').
    rng : numpy.random.Generator
    card_scale : float
        Each card's edge over its region's ellipse (a photo-textured card is cut larger, then
        carved by the views).
    seed : int
        The regions' k-means (view k uses ``seed + k``).
    threads : int
        Views segmented at once.
    rounds : int
        Rounds of the synthesis at most (:func:`fill_sparse`); it stops earlier once the
        budget ``leaves`` is spent.

    Returns
    -------
    (Foliage, dict)
        The leaves and counts (``from_regions``, ``duplicates``, ``synthesized``).
    """
    from scipy.spatial import cKDTree

    from treeform.structures import Foliage

    pts = np.asarray(points, np.float64)
    skel = np.asarray(skeleton.positions, np.float64)
    from concurrent.futures import ThreadPoolExecutor

    def one(k):
        c2w = np.asarray(cam_to_world[k], np.float64)
        return _view_leaves(pts, skel, np.asarray(K[k], np.float64), np.linalg.inv(c2w), c2w, labels[k],
                            images[k], size, seed + k)

    # the views on threads (OpenCV's mean shift and NumPy release the GIL), gathered in view order
    with ThreadPoolExecutor(max_workers=max(1, min(threads, len(labels)))) as pool:
        got = [out for out in pool.map(one, range(len(labels))) if out is not None]
    stats = {"from_regions": 0, "duplicates": 0, "synthesized": 0}
    if not got:
        return Foliage.empty(), stats
    pos, nrm, up, card, rgb, area = (np.concatenate(x) for x in zip(*got))
    order = np.argsort(-area, kind="stable")  # larger regions first: they keep their leaf
    pos, nrm, up, card, rgb = pos[order], nrm[order], up[order], card[order], rgb[order]
    alive = np.ones(len(pos), bool)
    for i, j in sorted(cKDTree(pos).query_pairs(0.5 * float(np.median(card)))):
        if alive[i] and alive[j] and np.linalg.norm(pos[i] - pos[j]) < 0.5 * card[i]:
            alive[j] = False
    stats["duplicates"] = int((~alive).sum())
    pos, nrm, up, card, rgb = pos[alive], nrm[alive], up[alive], card[alive], rgb[alive]
    stats["from_regions"] = len(pos)
    node = cKDTree(skel).query(pos)[1]
    card = card * float(card_scale)
    n_real = min(len(pos), leaves)
    if n_real < len(pos):  # over the budget: the smallest regions' leaves go (they come last)
        pos, nrm, up, card, rgb, node = pos[:n_real], nrm[:n_real], up[:n_real], card[:n_real], rgb[:n_real], node[:n_real]
    hull = cKDTree(pts) if len(pts) else None
    inside = hull.query(skel, distance_upper_bound=size)[0] <= size if hull is not None else None
    idx, spos, snode = fill_sparse(pos, node, skeleton, rng, budget=max(0, leaves - len(pos)), rounds=rounds,
                                   inside=inside, volume=hull, reach=size)
    stats["synthesized"] = len(idx)
    foliage = Foliage(np.concatenate([pos, spos]), np.concatenate([nrm, nrm[idx]]), np.concatenate([up, up[idx]]),
                      np.concatenate([card, card[idx]]), np.concatenate([rgb, rgb[idx]]).clip(0, 1),
                      np.concatenate([node, snode]))
    return foliage, stats
