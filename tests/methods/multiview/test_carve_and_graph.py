"""Visual hull carving and the visible branch graph of the multi-view route, on analytic scenes."""

import numpy as np
import pytest

from treeform._shared.errors import InputError, NoTreeFoundError
from treeform.methods.multiview.branch_graph import branch_skeleton
from treeform.methods.multiview.carve import carve_tree


def _ring_cameras(n=12, radius=12.0, height=1.6, target=(0, 3, 0), size=(160, 120), f=140.0):
    K, c2w = [], []
    for k in range(n):
        a = 2 * np.pi * k / n
        c = np.array([radius * np.sin(a), height, radius * np.cos(a)])
        fwd = np.asarray(target, float) - c
        fwd /= np.linalg.norm(fwd)
        right = np.cross(fwd, [0, 1, 0])
        right /= np.linalg.norm(right)
        down = np.cross(fwd, right)
        T = np.eye(4)
        T[:3, :3] = np.column_stack([right, down, fwd])
        T[:3, 3] = c
        K.append([[f, 0, size[0] / 2], [0, f, size[1] / 2], [0, 0, 1]])
        c2w.append(T)
    return np.array(K, float), np.array(c2w), size


def _tree_points(rng):
    """A trunk (radius 0.15 m, 0..3 m) under a crown (a ball of radius 2 m at 4.5 m)."""
    t = rng.uniform(0, 3.0, 20000)
    a = rng.uniform(0, 2 * np.pi, 20000)
    trunk = np.column_stack([0.15 * np.cos(a), t, 0.15 * np.sin(a)])
    d = rng.normal(size=(60000, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    crown = d * 2.0 * rng.uniform(0, 1, (60000, 1)) ** (1 / 3) + [0, 4.5, 0]
    return trunk, crown


def _masks(K, c2w, size, trunk, crown):
    labels = []
    for k in range(len(K)):
        lab = np.zeros((size[1], size[0]), np.uint8)
        w2c = np.linalg.inv(c2w[k])
        for pts, value in ((crown, 1), (trunk, 2)):
            pc = pts @ w2c[:3, :3].T + w2c[:3, 3]
            uv = (pc @ K[k].T)[:, :2] / pc[:, 2:3]
            ok = (uv[:, 0] >= 0) & (uv[:, 0] < size[0]) & (uv[:, 1] >= 0) & (uv[:, 1] < size[1])
            lab[uv[ok, 1].astype(int), uv[ok, 0].astype(int)] = value
        labels.append(lab)
    return labels


@pytest.fixture(scope="module")
def scene():
    rng = np.random.default_rng(0)
    K, c2w, size = _ring_cameras()
    trunk, crown = _tree_points(rng)
    return K, c2w, _masks(K, c2w, size, trunk, crown), trunk, crown


def test_hull_holds_the_tree_and_nothing_far_from_it(scene):
    K, c2w, labels, trunk, crown = scene
    ct = carve_tree(K, c2w, labels, box=([-4, -0.2, -4], [4, 8, 4]), voxel=0.05, tolerance=0.1)
    assert len(ct) > 100
    from scipy.spatial import cKDTree

    # every true point lies in (or next to) a kept cell
    d_true = cKDTree(ct.points).query(np.concatenate([trunk[::20], crown[::60]]))[0]
    assert np.percentile(d_true, 99) < 0.35
    # the hull hugs the trunk: no cell between 1 and 3 m high farther than 0.5 m from its axis
    low = (ct.points[:, 1] > 1.0) & (ct.points[:, 1] < 2.5)
    assert low.any() and np.hypot(ct.points[low, 0], ct.points[low, 2]).max() < 0.5
    # thickness: thin on the trunk, wide in the crown; wood votes on the trunk
    assert np.median(ct.thickness[low]) < 0.4
    top = np.linalg.norm(ct.points - [0, 4.5, 0], axis=1) < 1.0
    assert np.median(ct.thickness[top]) > 0.8
    assert np.median(ct.wood[low]) > 0.5 and np.median(ct.wood[top]) < 0.2
    # coarse cells inside the crown, fine ones along the trunk
    assert ct.size[top].max() > ct.size[low].min()


def test_carve_is_deterministic_and_checks_its_input(scene):
    K, c2w, labels, _, _ = scene
    a = carve_tree(K, c2w, labels, box=([-4, -0.2, -4], [4, 8, 4]), voxel=0.1)
    b = carve_tree(K, c2w, labels, box=([-4, -0.2, -4], [4, 8, 4]), voxel=0.1)
    assert np.array_equal(a.points, b.points) and np.array_equal(a.thickness, b.thickness)
    with pytest.raises(InputError, match="voxel"):
        carve_tree(K, c2w, labels, box=([-4, 0, -4], [4, 8, 4]), voxel=0)
    with pytest.raises(InputError, match="label images"):
        carve_tree(K, c2w, labels[:-1], box=([-4, 0, -4], [4, 8, 4]), voxel=0.1)
    empty = carve_tree(K, c2w, [np.zeros_like(x) for x in labels], box=([-4, 0, -4], [4, 8, 4]), voxel=0.1)
    assert len(empty) == 0


def _y_points(rng, gap=False):
    """A trunk 0..2 m forking into two limbs to (+-1, 3.5, 0); points on the axes with jitter."""
    segs = [((0, 0, 0), (0, 2, 0)), ((0, 2, 0), (1, 3.5, 0)), ((0, 2, 0), (-1, 3.5, 0))]
    pts, th = [], []
    for (a, b), r in zip(segs, (0.12, 0.06, 0.06)):
        a, b = np.asarray(a, float), np.asarray(b, float)
        t = rng.uniform(0, 1, 800)
        if gap and r < 0.1:
            t = t[(t < 0.4) | (t > 0.5)]  # a 15 cm hole in each limb (a leaf in front of it)
        pts.append(a + np.outer(t, b - a) + rng.normal(0, 0.01, (len(t), 3)))
        th.append(np.full(len(t), r))
    return np.concatenate(pts), np.concatenate(th)


@pytest.mark.parametrize("gap", [False, True])
def test_branch_skeleton_of_a_fork(gap):
    pts, th = _y_points(np.random.default_rng(1), gap=gap)
    sk = branch_skeleton(pts, th, link=0.06, gap=0.3, bin_width=0.15, root=np.zeros(3))
    assert np.allclose(sk.positions[0], pts[np.argmin(np.linalg.norm(pts, axis=1))])
    children = np.bincount(sk.parent[1:], minlength=sk.n_nodes)
    tips = np.flatnonzero(children == 0)
    assert len(tips) == 2  # one fork, two limbs; binning noise pruned
    assert sorted(np.sign(sk.positions[tips, 0]).tolist()) == [-1.0, 1.0]
    assert np.all(sk.positions[tips, 1] > 3.2)
    # radii from the thickness: the trunk's nodes thicker than the limbs'
    trunk = sk.positions[:, 1] < 1.8
    assert np.median(sk.radius[trunk]) == pytest.approx(0.12, abs=0.01)
    assert np.median(sk.radius[sk.positions[:, 1] > 2.6]) == pytest.approx(0.06, abs=0.01)
    # nodes lie on the true axes
    on_axis = np.minimum.reduce([np.hypot(sk.positions[:, 0], 0) + 10 * (sk.positions[:, 1] > 2.05),
                                 np.abs(sk.positions[:, 1] - 2 - 1.5 * np.abs(sk.positions[:, 0])) / 1.8])
    assert np.median(on_axis) < 0.05


def test_a_stray_speck_nearest_the_foot_does_not_root_the_skeleton():
    """Mattes that lost the lower trunk: the branch point nearest the foot is a speck (a hedge's wood)
    that no gap joins to the tree; the tree's network (the largest piece) roots the skeleton at its
    point nearest the foot."""
    rng = np.random.default_rng(2)
    pts, th = _y_points(rng)
    keep = pts[:, 1] > 1.2  # the trunk's lowest 1.2 m unseen
    speck = np.array([0.9, 0.4, 0.2]) + rng.normal(0, 0.02, (12, 3))
    pts, th = np.concatenate([speck, pts[keep]]), np.concatenate([np.full(12, 0.3), th[keep]])
    sk = branch_skeleton(pts, th, link=0.06, gap=0.3, bin_width=0.15, root=np.zeros(3))
    assert sk.positions[0, 1] == pytest.approx(1.2, abs=0.05) and abs(sk.positions[0, 0]) < 0.05
    tips = np.flatnonzero(np.bincount(sk.parent[1:], minlength=sk.n_nodes) == 0)
    assert len(tips) == 2 and np.all(sk.positions[tips, 1] > 3.2)


def test_branch_skeleton_needs_points():
    with pytest.raises(NoTreeFoundError):
        branch_skeleton(np.zeros((1, 3)), np.ones(1), link=0.1, gap=0.2, bin_width=0.1)


def test_main_component_keeps_the_tree_not_its_neighbour():
    """Two blocks of cells: the one on the cameras' axis is the tree, the other (a neighbour at the
    ring's edge) goes; cells touching at edges and corners are one piece, octree sizes mixed."""
    from treeform.methods.multiview.carve import CarvedTree, main_component

    tree = np.array([[x, y, z] for x in (-0.5, 0.5) for y in np.arange(0.5, 6) for z in (-0.5, 0.5)])
    twig = np.array([[1.25, 5.75, 0.75]])  # a half-size cell touching the tree at a corner
    far = np.array([[x, y, 0.5] for x in (6.5, 7.5) for y in np.arange(0.5, 9)])  # bigger, but off the axis
    pts = np.concatenate([tree, twig, far])
    size = np.concatenate([np.ones(len(tree)), [0.5], np.ones(len(far))])
    n = len(pts)
    c = CarvedTree(pts, size, np.ones(n), np.zeros(n), np.ones(n, int), np.zeros((n, 3), np.uint8), np.zeros(n),
                   np.ones(n))
    keep = main_component(c, [0, 0, 0], 2.0)
    assert keep[: len(tree) + 1].all() and not keep[len(tree) + 1:].any()
    assert not main_component(c, [30, 0, 30], 2.0).any()  # nothing on the axis: nothing kept
    sub = c.subset(keep).transformed(2.0, [0, 1, 0])
    assert len(sub) == len(tree) + 1
    np.testing.assert_allclose(sub.points, 2.0 * pts[keep] + [0, 1, 0])
    np.testing.assert_allclose(sub.size, 2.0 * size[keep])


def test_surface_voxel_refines_the_crown_surface(scene):
    """With surface_voxel the wide crown's boundary reaches that cell size (the leaves follow its
    outline); without, it stays coarse."""
    K, c2w, labels, _, _ = scene
    box = ([-4, -0.2, -4], [4, 8, 4])
    coarse = carve_tree(K, c2w, labels, box=box, voxel=0.05, tolerance=0.1)
    fine = carve_tree(K, c2w, labels, box=box, voxel=0.05, tolerance=0.1, surface_voxel=0.1)

    def crown(c):  # the crown's surface
        return (c.points[:, 1] > 3.5) & (c.edge < 0.15)

    assert crown(fine).sum() > 50 and np.median(fine.size[crown(fine)]) <= 0.1 + 1e-9
    assert np.median(coarse.size[crown(coarse)]) > 0.1
    assert (fine.support >= 0.9 - 1e-9).all() and (fine.support <= 1).all()
    # edge: about 0 on the surface, about the radius at the crown's centre
    centre = np.linalg.norm(fine.points - [0, 4.5, 0], axis=1) < 0.3
    assert np.median(fine.edge[centre]) > 1.2
    with pytest.raises(InputError, match="surface_voxel"):
        carve_tree(K, c2w, labels, box=box, voxel=0.05, surface_voxel=0.01)


def test_wood_votes_go_to_the_limbs_not_along_their_rays():
    """30 limbs seen through a crown from 24 views: the rays through their wood pixels cross the
    crown at every depth, and with raw votes hundreds of cells far from any limb are called wood
    by a quarter of the views; explained votes keep the trunk and every limb and drop most of those."""
    from scipy.ndimage import grey_dilation
    from scipy.spatial import cKDTree

    from treeform.methods.multiview.carve import explain_wood

    rng = np.random.default_rng(0)
    K, c2w, size = _ring_cameras(n=24)
    trunk, crown = _tree_points(rng)
    d = rng.normal(size=(30, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    d[:, 1] = np.abs(d[:, 1])
    ends = np.array([0, 4.5, 0]) + 1.7 * d
    limbs = np.concatenate([np.array([0, 3.0, 0]) + rng.uniform(0, 1, (2000, 1)) * (e - [0, 3.0, 0]) for e in ends])
    # the limbs drawn over the crown (seen through its gaps), a pixel wider (a segmenter's blur)
    labels = [np.where(grey_dilation((lab == 2).astype(np.uint8), size=(3, 3)) > 0, 2, lab) * (lab > 0)
              for lab in _masks(K, c2w, size, np.concatenate([trunk, limbs]), crown)]
    box = ([-4, -0.2, -4], [4, 8, 4])
    ct = carve_tree(K, c2w, labels, box=box, voxel=0.05, tolerance=0.1)
    votes = explain_wood(ct.points, ct.wood, K, c2w, labels, size=ct.size)
    assert np.array_equal(votes, explain_wood(ct.points, ct.wood, K, c2w, labels, size=ct.size))
    far = cKDTree(np.concatenate([trunk, limbs])).query(ct.points)[0] > 0.3
    on_trunk = cKDTree(trunk).query(ct.points)[0] < 0.08
    on_limb = (cKDTree(limbs).query(ct.points)[0] < 0.08) & ~on_trunk
    assert on_limb.sum() >= 10 and on_trunk.sum() > 100
    ghosts_raw, ghosts = int((ct.wood[far] > 0.25).sum()), int((votes[far] > 0.25).sum())
    assert ghosts_raw > 300 and ghosts < 0.6 * ghosts_raw
    assert (votes[on_limb] > 0.25).all() and np.median(votes[on_trunk]) > 0.5
    # no cell gains a vote
    assert np.all(votes <= ct.wood + 1e-12)
    with pytest.raises(InputError, match="tolerance"):
        explain_wood(ct.points, ct.wood, K, c2w, labels, tolerance=1.5)


def test_tree_pieces_keep_the_tree_and_its_clumps_and_drop_a_far_crown(scene):
    from treeform.methods.multiview.carve import CarvedTree, tree_pieces

    K, c2w, labels, _, _ = scene
    ct = carve_tree(K, c2w, labels, box=([-4, -0.2, -4], [4, 8, 4]), voxel=0.05, tolerance=0.1)
    g = (np.stack(np.meshgrid(*[np.arange(10)] * 3, indexing="ij"), -1).reshape(-1, 3) + 0.5) * 0.1
    clump = g * 0.5 + [ct.points[:, 0].max() + 0.3, 4.2, -0.25]  # 0.5 m of 5-cm cells, 0.25 m off the crown
    far = g + [6.0, 4.0, -0.5]  # a neighbour's crown 4 m off, out of the column
    extra = np.concatenate([clump, far])
    n = len(extra)
    both = CarvedTree(np.concatenate([ct.points, extra]), np.concatenate([ct.size, np.r_[np.full(len(clump), 0.05),
                                                                                        np.full(len(far), 0.1)]]),
                      np.concatenate([ct.thickness, np.ones(n)]), np.concatenate([ct.wood, np.zeros(n)]),
                      np.concatenate([ct.seen, np.full(n, 12)]), np.concatenate([ct.colors, np.zeros((n, 3), np.uint8)]),
                      np.concatenate([ct.edge, np.zeros(n)]), np.concatenate([ct.support, np.ones(n)]))
    keep = tree_pieces(both, [0, 0, 0], 1.0, gap=0.4)
    assert keep[:len(ct)].all()  # the tree's own pieces, in the column or joined to it
    assert keep[len(ct):len(ct) + len(clump)].all()  # a clump a gap of 0.25 m off
    assert not keep[len(ct) + len(clump):].any()  # the far crown
    assert not tree_pieces(both, [0, 0, 0], 1.0, gap=0.1)[len(ct):len(ct) + len(clump)].any()


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_the_per_view_median_is_numpys_nanmedian(dtype):
    """The carving's and the leaf colours' per-view median: NumPy's values exactly, any count of views."""
    import warnings

    from treeform._shared.nanstats import nanmedian_views

    rng = np.random.default_rng(3)
    for shape in [(24, 5000), (7, 300, 3), (1, 10), (2, 4)]:
        a = (rng.normal(size=shape) * 50).astype(dtype)
        a[rng.random(shape) < 0.45] = np.nan
        a[:, 0] = np.nan  # a point no view sees
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            ref = np.nanmedian(a, axis=0)
        got = nanmedian_views(a)
        assert got.dtype == ref.dtype and got.shape == ref.shape
        assert np.array_equal(got, ref, equal_nan=True)
