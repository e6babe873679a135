"""Instanced drawing for forests: meshes, relief-mapped RDMs and clipped billboard clouds (seed 001 §4.1-4.2, §5.1)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import ndimage

from treeform._shared.errors import InputError
from treeform.crown.sampling import billboard_centres, farthest_point_order, ray_extents
from treeform.methods.envelope.leaflets import LeafletBillboard
from treeform.render import Renderer
from treeform.render.cloud import CloudPass, billboard_count
from treeform.render.impostor import ReliefPass, render_rdm_impostor
from treeform.render.instances import check_instances, instance_points
from treeform.structures import Camera, Mesh, RadialDistanceMap
from treeform.structures.rdm import texel_directions

INSTANCES = np.array([[0.0, 0.0, 0.0, 1.0, 0.0, 0], [4.0, 0.0, -1.0, 1.5, 1.1, 0], [-3.5, 0.5, 1.0, 0.7, 2.5, 0]],
                     np.float32)


def test_instanced_mesh_equals_the_meshes_placed_by_hand(gl, meshes):
    """A box drawn with three instance rows = the three boxes moved, turned and scaled on the CPU."""
    part = meshes.cube(center=(0.3, 0.5, 0.1), half=(0.4, 0.5, 0.2))
    placed = []
    for row in INSTANCES:
        p = meshes.cube(center=(0.3, 0.5, 0.1), half=(0.4, 0.5, 0.2))
        p.positions = instance_points(row[None], p.positions)[0].astype(np.float32)
        p.normals = instance_points(np.r_[0, 0, 0, 1, row[4], 0][None], p.normals)[0].astype(np.float32)
        placed.append(p)
    cam = Camera(160, 96, 40.0, (0.3, 2.5, 6.5), (0.2, 0.5, 0.0))
    r = Renderer(cam, samples=1)
    a = r.render(Mesh([part]), instances=INSTANCES)
    b = r.render(Mesh(placed))
    assert a.mask.sum() > 500 and np.array_equal(a.mask, b.mask)
    assert np.allclose(a.depth[a.mask], b.depth[b.mask], atol=1e-4)
    assert np.abs(a.color.astype(int) - b.color.astype(int)).max() <= 2
    with pytest.raises(InputError, match="instances"):
        r.render(Mesh([part]), instances=np.zeros((2, 3)))
    with pytest.raises(InputError, match="scales"):
        check_instances([[0, 0, 0, 0, 0, 0]])


def _bumpy_rdm(res=32):
    d = texel_directions(res)
    radii = 1.5 + 0.5 * d[..., 1] + 0.3 * np.sin(5 * d[..., 0]) * np.cos(3 * d[..., 2])
    return RadialDistanceMap(np.array([0.2, 2.0, -0.1]), radii.astype(np.float32))


def test_relief_instances_march_in_each_trees_frame(gl):
    """Three placed copies of an RDM: the GPU silhouette and depth equal a fine CPU march of the placed crowns."""
    rdm = _bumpy_rdm()
    cam = Camera(120, 72, 40.0, (0.5, 5.0, 14.0), (0.0, 1.5, 0.0))
    res = render_rdm_impostor(rdm, cam, steps=128, refine=8, instances=INSTANCES)
    inst = INSTANCES.astype(np.float64)

    def contains(p):
        inside = np.zeros(len(p), bool)
        for x, y, z, s, yaw, _ in inst:
            c, sn = np.cos(-yaw), np.sin(-yaw)
            q = (p - [x, y, z]) / s
            q = np.stack([c * q[:, 0] + sn * q[:, 2], q[:, 1], -sn * q[:, 0] + c * q[:, 2]], 1)
            inside |= rdm.contains(q)
        return inside

    h, w = cam.height, cam.width
    vv, uu = np.mgrid[:h, :w]
    eye = np.asarray(cam.position, float)
    dirs = cam.unproject(uu.ravel() + 0.5, vv.ravel() + 0.5, np.full(h * w, 10.0)) - eye
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    t0, _ = ray_extents(contains, np.repeat(eye[None], h * w, 0), dirs, 0.0, 40.0, steps=2000)
    mask = np.isfinite(t0).reshape(h, w)
    depth = (t0 * (dirs @ np.asarray(cam.axes()[2]))).reshape(h, w)
    iou = (mask & res.mask).sum() / (mask | res.mask).sum()
    assert iou > 0.98, iou
    both = mask & res.mask
    assert np.median(np.abs(depth[both] - res.depth[both])) < 0.03
    # every placed crown's centre is covered
    centres = instance_points(INSTANCES[:, :6], rdm.center[None])[:, 0]
    for u, v, _ in cam.project(centres):
        assert res.mask[int(v), int(u)]


def _leaflet(size=64, quadrants=False):
    """A square opaque leaflet texture; with ``quadrants`` four leaves, each with its own centroid."""
    rgba = np.zeros((size, size, 4), np.uint8)
    rgba[...] = (60, 140, 50, 255)
    yy, xx = np.mgrid[:size, :size]
    if quadrants:
        qx, qy = xx >= size // 2, yy >= size // 2
        cx = np.where(qx, 0.75, 0.25)
        cy = np.where(qy, 0.75, 0.25)
    else:
        cx = np.full((size, size), 0.5)
        cy = np.full((size, size), 0.5)
    centroid = np.dstack([np.rint(cx * 255), np.rint(cy * 255), np.zeros_like(cx)]).astype(np.uint8)
    normal = np.zeros((size, size, 3), np.uint8)
    normal[...] = (128, 128, 255)
    return LeafletBillboard("sphere", rgba, normal, centroid, np.zeros((size, size, 3), np.uint8),
                            np.full((size, size), 255, np.uint8), np.zeros((size, size), np.uint16),
                            np.full((size, size), 255, np.uint8), 4 if quadrants else 1, 1)


def _draw(pass_, cam, rows):
    pass_.instances = rows
    r = Renderer(cam, samples=1, background=(0, 0, 0, 0))
    try:
        return r.render_scene([], passes=[pass_])
    finally:
        r.release()


def test_cloud_draws_the_first_count_billboards_of_each_instance(gl):
    """Points far apart, billboards small: k drawn per instance = k separate squares per instance."""
    rdm = RadialDistanceMap(np.zeros(3), np.full((6, 8, 8), 50.0, np.float32))
    pts = np.stack([np.linspace(-8, 8, 9), np.zeros(9), np.zeros(9)], 1)
    cloud = CloudPass(rdm, pts, 0.6, _leaflet(), clip="none")
    try:
        cam = Camera(200, 120, 30.0, (0.0, 0.0, 40.0), (0.0, 0.0, 0.0))
        for k in (3, 9):
            res = _draw(cloud, cam, [[0, 0, 0, 1, 0, k]])
            assert ndimage.label(res.mask)[1] == k
        res = _draw(cloud, cam, [[0, 4, 0, 1, 0, 4], [0, -4, 0, 1, 0, 2]])  # two instances, 4 and 2
        assert ndimage.label(res.mask)[1] == 6
        # fewer billboards are drawn larger (edge x sqrt(P / count)): about the same cover per tree
        one = _draw(cloud, cam, [[0, 0, 0, 1, 0, 1]]).mask.sum()
        all9 = _draw(cloud, cam, [[0, 0, 0, 1, 0, 9]]).mask.sum()
        assert abs(one - all9 / 9 * 9) / all9 < 0.2
        with pytest.raises(InputError, match="ao"):
            CloudPass(rdm, pts, 0.6, _leaflet(), ao=2.0)
    finally:
        cloud.release()


def test_per_leaf_clipping_keeps_leaves_whole(gl):
    """A billboard straddling the crown's edge: per-fragment clipping cuts its leaves along the
    RDM; per-leaf clipping (seed 001 Fig. 12d) keeps or drops each leaf whole, by its centroid."""
    rdm = RadialDistanceMap(np.zeros(3), np.full((6, 16, 16), 1.0, np.float32))  # unit sphere
    pts = np.array([[1.0, 0.0, 0.0]])  # on the sphere's rim, seen from +Z
    cam = Camera(96, 96, 20.0, (1.0, 0.0, 12.0), (1.0, 0.0, 0.0))
    masks = {}
    for clip in ("none", "fragment", "leaf"):
        cloud = CloudPass(rdm, pts, 1.6, _leaflet(quadrants=True), clip=clip)
        try:
            # roll 0: the GS rolls each billboard by a hash of its index; one instance of point 0
            masks[clip] = _draw(cloud, cam, [[0, 0, 0, 1, 0, 1]]).mask
        finally:
            cloud.release()
    full, frag, leaf = masks["none"], masks["fragment"], masks["leaf"]
    assert frag.sum() < 0.8 * full.sum() and leaf.sum() < 0.8 * full.sum()
    assert (frag & ~full).sum() == 0 and (leaf & ~full).sum() == 0
    # per leaf: the drawn part is a union of whole quadrants (leaves) -> ~ k/4 of the full square
    share = leaf.sum() / full.sum()
    assert min(abs(share - q) for q in (0.25, 0.5, 0.75)) < 0.03, share
    # per fragment: the cut follows the sphere, not the quadrant edges
    share_f = frag.sum() / full.sum()
    assert min(abs(share_f - q) for q in (0.25, 0.5, 0.75)) > 0.03, share_f


def test_billboard_centres_and_counts():
    rdm = RadialDistanceMap(np.array([0.0, 5.0, 0.0]), np.full((6, 8, 8), 3.0, np.float32))
    rng = np.random.default_rng(0)
    nodes = rng.normal(size=(3000, 3)) * 1.5 + [0, 5, 0]
    pts = billboard_centres(rdm, nodes, 144, seed=0)
    assert pts.shape == (144, 3) and rdm.contains(pts).all()
    r = np.linalg.norm(pts - rdm.center, axis=1)
    assert r.min() >= 0.35 * 3.0 - 1e-6  # not in the core
    # every prefix spread: the first 16 are farther apart than 16 random ones of the set
    from scipy.spatial.distance import pdist

    assert pdist(pts[:16]).min() > 1.5 * np.median([pdist(pts[rng.choice(144, 16, replace=False)]).min()
                                                   for _ in range(20)])
    assert np.array_equal(pts, billboard_centres(rdm, nodes, 144, seed=0))
    shell = billboard_centres(rdm, None, 32, seed=1)  # no skeleton: the RDM's shell
    assert shell.shape == (32, 3) and rdm.contains(shell).all()
    assert farthest_point_order(np.eye(3), 5).tolist() == [0, 1, 2]
    assert billboard_count([0, 100, 200, 300, 400, 5000]).tolist() == [16, 16, 36, 81, 144, 144]


def test_passes_need_a_single_sample_renderer(gl):
    rdm = _bumpy_rdm(8)
    relief = ReliefPass(rdm)
    try:
        r = Renderer(Camera(16, 16, 30.0, (0, 2, 8), (0, 2, 0)), samples=4)
        if r.samples > 1:
            with pytest.raises(InputError, match="samples"):
                r.render_scene([], passes=[relief])
    finally:
        relief.release()
