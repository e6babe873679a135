"""The relief-mapped RDM impostor (seed 001 §4.1): silhouette and depth equal the RDM's, colours from the cubemap."""

from __future__ import annotations

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.crown.sampling import ray_extents
from treeform.render.impostor import render_rdm_impostor
from treeform.structures import Camera, RadialDistanceMap
from treeform.structures.rdm import texel_directions


def _bumpy_rdm(res=32):
    d = texel_directions(res)
    radii = 2.0 + 0.6 * d[..., 1] + 0.3 * np.sin(5 * d[..., 0]) * np.cos(3 * d[..., 2])
    return RadialDistanceMap(np.array([0.5, 5.0, -0.3]), radii.astype(np.float32))


def _cpu_march(rdm, cam):
    """First hit of every pixel's ray, marched finely on the CPU: (mask, depth along the view axis)."""
    h, w = cam.height, cam.width
    vv, uu = np.mgrid[:h, :w]
    eye = np.asarray(cam.position, float)
    dirs = cam.unproject(uu.ravel() + 0.5, vv.ravel() + 0.5, np.full(h * w, 10.0)) - eye
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    t0, _ = ray_extents(rdm.contains, np.repeat(eye[None], h * w, 0), dirs, 0.0, 40.0, steps=2000)
    depth = t0 * (dirs @ np.asarray(cam.axes()[2]))
    return np.isfinite(t0).reshape(h, w), depth.reshape(h, w)


@pytest.mark.parametrize("view", ["front", "side", "back", "top"])
def test_silhouette_and_depth_are_the_rdms(gl, view):
    rdm = _bumpy_rdm()
    base = Camera(72, 60, 40.0, (0.5, 6.0, 12.0), tuple(rdm.center))
    cam = {"front": base, "side": base.orbit(yaw_deg=70), "back": base.orbit(yaw_deg=200),
           "top": Camera(48, 48, 50.0, (0.6, 14.0, -0.2), tuple(rdm.center), (0, 0, -1))}[view]
    res = render_rdm_impostor(rdm, cam, steps=128, refine=8)
    mask, depth = _cpu_march(rdm, cam)
    iou = (mask & res.mask).sum() / (mask | res.mask).sum()
    assert iou > 0.99, iou
    both = mask & res.mask
    assert np.median(np.abs(depth[both] - res.depth[both])) < 0.02
    assert np.all(np.isinf(res.depth[~res.mask])) and np.all(res.color[~res.mask] == 0)


def test_colours_come_from_the_cubemap_along_the_hit_direction(gl):
    rdm = RadialDistanceMap(np.zeros(3), np.full((6, 16, 16), 1.0, np.float32))  # a unit sphere
    faces = np.zeros((6, 8, 8, 3), np.uint8)
    faces[4] = (20, 40, 230)  # +Z blue, the others red
    faces[[0, 1, 2, 3, 5]] = (230, 30, 20)
    cam = Camera(40, 40, 30.0, (0.0, 0.0, 6.0), (0.0, 0.0, 0.0))
    res = render_rdm_impostor(rdm, cam, color=faces)
    c = res.color[20, 20, :3].astype(int)
    assert c[2] > 2 * c[0]  # the sphere's front (+Z) shows the +Z face
    side = render_rdm_impostor(rdm, cam.orbit(yaw_deg=90), color=faces).color[20, 20, :3].astype(int)
    assert side[0] > 2 * side[2]
    # lit by the RDM's normal: the half facing the light is brighter
    lum = res.color[..., :3].astype(float).sum(2)
    assert lum[10:20, 10:30][res.mask[10:20, 10:30]].mean() > lum[22:32, 10:30][res.mask[22:32, 10:30]].mean()


def test_bad_input(gl):
    cam = Camera(16, 16, 30.0, (0.0, 0.0, 6.0), (0.0, 0.0, 0.0))
    rdm = RadialDistanceMap(np.zeros(3), np.ones((6, 4, 4), np.float32))
    with pytest.raises(InputError, match="RadialDistanceMap"):
        render_rdm_impostor(np.ones((6, 4, 4)), cam)
    with pytest.raises(InputError, match="color"):
        render_rdm_impostor(rdm, cam, color=np.zeros((6, 4, 5, 3), np.uint8))
    with pytest.raises(InputError, match="steps"):
        render_rdm_impostor(rdm, cam, steps=1)


def test_baked_colours_are_the_meshs_own_on_every_side(gl, meshes):
    """A sphere red where x > 0 and blue where x < 0: the baked cubemap is red toward +X, blue toward -X,
    and split down the middle on the +Y and +Z faces."""
    from treeform.render import bake_color_cubemap
    from treeform.structures import Material, Mesh, MeshPart

    pos, nrm, faces = meshes.sphere(center=(0.0, 3.0, 0.0), radius=2.0)
    east = pos[faces].mean(1)[:, 0] > 0
    uv = np.zeros((len(pos), 2))
    parts = [MeshPart(pos, nrm, uv, None, faces[side], Material(name, rgba, None, "OPAQUE", 0.5, True))
             for side, name, rgba in ((east, "red", (1, 0, 0, 1)), (~east, "blue", (0, 0, 1, 1)))]
    rdm = RadialDistanceMap(np.array([0.0, 3.0, 0.0]), np.full((6, 16, 16), 2.0, np.float32))
    col = bake_color_cubemap(Mesh(parts), rdm, face=16, view_size=96).astype(int)
    assert col.shape == (6, 16, 16, 3)
    d = texel_directions(16)
    red = col[..., 0] > col[..., 2] + 100
    blue = col[..., 2] > col[..., 0] + 100
    assert red[d[..., 0] > 0.15].mean() > 0.97 and blue[d[..., 0] < -0.15].mean() > 0.97
    assert red[0].all() and blue[1].all()  # +X and -X faces
    with pytest.raises(InputError, match="nothing to bake"):
        bake_color_cubemap(Mesh([]), rdm)


@pytest.mark.parametrize("yaw", [0.0, 100.0, 200.0])
def test_planar_colours_face_the_camera_from_every_side(gl, yaw):
    """Seed 001 §4.1's second option: the front view as a billboard. A front view red left of the
    crown centre and blue right of it gives red on the screen's left and blue on its right from any
    side; the silhouette stays the RDM's."""
    rdm = _bumpy_rdm()
    front = np.zeros((64, 64, 4), np.uint8)
    front[:, :32] = (255, 0, 0, 255)
    front[:, 32:] = (0, 0, 255, 255)
    planar = {"image": front, "center_px": (32.0, 32.0), "pixels_per_metre": 5.0}
    cam = Camera(64, 64, 40.0, (0.5, 5.0, 12.0), tuple(rdm.center)).orbit(yaw_deg=yaw)
    res = render_rdm_impostor(rdm, cam, planar=planar)
    plain = render_rdm_impostor(rdm, cam)
    assert np.array_equal(res.mask, plain.mask)
    cu = cam.project(np.asarray(rdm.center)[None])[0, 0]
    cols = np.nonzero(res.mask.any(0))[0]
    left = res.mask & (np.arange(64)[None, :] < cu - 2)
    right = res.mask & (np.arange(64)[None, :] > cu + 2)
    assert len(cols) > 10 and left.any() and right.any()
    img = res.color[..., :3].astype(int)
    assert (img[left][:, 0] > img[left][:, 2]).all() and (img[right][:, 2] > img[right][:, 0]).all()
    with pytest.raises(InputError, match="planar"):
        render_rdm_impostor(rdm, cam, planar={"image": front[..., :3], "center_px": (0, 0), "pixels_per_metre": 1})


def test_opacity_grid_hits_where_half_the_light_is_blocked(gl):
    """With an OpacityGrid the ray hits where its optical depth reaches ln 2 (Beer-Lambert) and is discarded
    where the tree lets more than half the light through: the same pixels and depths as a CPU march."""
    import scipy.ndimage as ndi

    from treeform.structures import OpacityGrid
    from treeform.structures.opacity import HALF_COVERAGE

    rng = np.random.default_rng(3)
    sigma = ndi.gaussian_filter(rng.random((16, 16, 16)), 2.0)
    sigma = np.clip(sigma - np.percentile(sigma, 50), 0, None) * 80.0  # porous: dense lumps and empty gaps
    grid = OpacityGrid(sigma.astype(np.float32), np.array([-1.0, -1.0, -1.0]), 2.0 / 16)
    rdm = RadialDistanceMap(np.zeros(3), np.full((6, 16, 16), 1.75, np.float32))  # around the whole cube
    cam = Camera(56, 56, 30.0, (1.5, 2.0, 6.0), (0.0, 0.0, 0.0))
    res = render_rdm_impostor(rdm, cam, opacity=grid, opacity_steps=256)
    plain = render_rdm_impostor(rdm, cam)
    h, w = cam.height, cam.width
    vv, uu = np.mgrid[:h, :w]
    eye = np.asarray(cam.position, float)
    dirs = cam.unproject(uu.ravel() + 0.5, vv.ravel() + 0.5, np.full(h * w, 5.0)) - eye
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    tau = grid.optical_depth(np.repeat(eye[None], h * w, 0), dirs, steps=256).reshape(h, w)
    clear = np.abs(tau - HALF_COVERAGE) > 0.05  # pixels whose ray is not on the edge of the threshold
    meets = tau > 0
    assert 0.2 < (tau >= HALF_COVERAGE)[meets].mean() < 0.8  # a porous tree: gaps seen through, lumps not
    agree = ((tau >= HALF_COVERAGE) == res.mask)[clear].mean()
    assert agree > 0.98, agree
    assert res.mask.sum() < 0.9 * plain.mask.sum() and not (res.mask & ~plain.mask).any()  # inside the RDM's
    # depth: where the CPU march's optical depth crosses ln 2 along a few of the hit rays
    ys, xs = np.nonzero(res.mask & clear)
    fwd = np.asarray(cam.axes()[2])
    for k in np.linspace(0, len(ys) - 1, 12).astype(int):
        d = dirs[ys[k] * w + xs[k]]
        ts = np.linspace(0, 12, 2401)[1:]
        dt = ts[1] - ts[0]
        cum = np.cumsum(grid.sample(eye + d * (ts - dt / 2)[:, None]) * dt)
        t_hit = ts[np.searchsorted(cum, HALF_COVERAGE)]
        assert abs(t_hit * (d @ fwd) - res.depth[ys[k], xs[k]]) < 0.05
    with pytest.raises(InputError, match="opacity"):
        render_rdm_impostor(rdm, cam, opacity=np.zeros((4, 4, 4)))


def test_a_trunk_thinner_than_a_voxel_stays_whole_through_its_capsules(gl):
    """A 6-m trunk 6-12 cm wide under a crown, in a grid of 23-cm voxels: alone in the grid it shows in
    pieces or not at all; with the skeleton's capsules the relief draws it in every row from its foot
    to the crown, bark-coloured and no wider than the trunk."""
    from treeform.geometry import branch_mesh, opacity_grid
    from treeform.structures import Material, Mesh, MeshPart, TreeSkeleton

    y = np.linspace(0.0, 6.0, 13)
    sk = TreeSkeleton(np.c_[0.3 * np.sin(y / 2.0), y, 0.1 * y], np.arange(-1, 12), np.linspace(0.06, 0.03, 13),
                      np.zeros(13, np.int32))
    bark = branch_mesh(sk, radial_segments=8)
    bark.material = Material("bark", texture=np.full((4, 4, 4), (120, 90, 60, 255), np.uint8))
    pos = np.array([[-2, 5.5, 0.6], [2, 5.5, 0.6], [2, 7.5, 0.6], [-2, 7.5, 0.6]], float)  # the crown: one card
    crown = MeshPart(pos, np.tile([0.0, 0.0, 1.0], (4, 1)), np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32),
                     np.ones((4, 4)), np.array([[0, 1, 2], [0, 2, 3]]), Material("leaf", double_sided=True))
    mesh = Mesh([bark, crown])
    rdm = RadialDistanceMap(np.array([0.0, 3.8, 0.5]), np.full((6, 8, 8), 4.5, np.float32))
    cam = Camera(96, 160, 20.0, (0.0, 3.8, -30.0), (0.0, 3.8, 0.5))
    rows = slice(int(cam.project(np.array([[0.0, 5.3, 0.6]]))[0, 1]) + 1, int(cam.project(np.zeros((1, 3)))[0, 1]))
    shown = {}
    for name, skel in (("grid", None), ("capsules", sk)):
        grid = opacity_grid(mesh, resolution=32, skeleton=skel)
        res = render_rdm_impostor(rdm, cam, opacity=grid)
        shown[name] = res.mask[rows].any(1)
        if skel is not None:
            assert len(grid.wood) >= 1
            width = res.mask[rows].sum(1)
            assert width.max() <= 3  # 0.12 m at most, 1.3 px at 30 m
            col = res.color[rows][res.mask[rows]].astype(float)
            assert (col[:, 0] > col[:, 1]).all() and (col[:, 1] > col[:, 2]).all()  # brown bark, not green
    assert shown["capsules"].all()
    assert shown["grid"].mean() < 0.6


def _scattered_capsules(n, seed):
    rng = np.random.default_rng(seed)
    a = rng.uniform(-0.8, 0.8, (n, 3))
    b = a + rng.normal(0.0, 0.35, (n, 3))
    return np.c_[a, b, rng.uniform(0.02, 0.09, n)].astype(np.float32)


@pytest.mark.parametrize("n", [1, 7, 9, 30, 32])
def test_wood_uniforms_keep_every_capsule_inside_its_groups_sphere(n):
    """Every capsule fills a row of the shader's arrays, each group's rows are its own capsules, and its
    bounding sphere holds them whole (both ends, their radius included)."""
    from treeform.render.impostor import WOOD_GROUP, wood_uniforms
    from treeform.structures import OpacityGrid

    wood = _scattered_capsules(n, n)
    wa, wb, wg, rows = wood_uniforms(OpacityGrid(np.zeros((4, 4, 4), np.float32), -np.ones(3), 0.5, wood=wood))
    assert rows % WOOD_GROUP == 0 and n <= rows <= len(wa)
    got = {tuple(np.r_[wa[i, :3], wb[i, :3], wa[i, 3]]) for i in range(rows)}
    assert got == {tuple(c) for c in wood}  # every capsule, and only those (short groups repeat their own)
    assert not wa[rows:].any() and not wg[rows // WOOD_GROUP:].any()
    for i in range(rows):
        c, rg = wg[i // WOOD_GROUP, :3], wg[i // WOOD_GROUP, 3]
        for end in (wa[i, :3], wb[i, :3]):
            assert np.linalg.norm(end - c) + wa[i, 3] <= rg + 1e-6


def test_many_capsules_are_hit_as_the_cpu_hits_them(gl):
    """30 capsules (several groups the shader skips by their spheres) in an empty grid, seen from four
    sides: the relief draws the pixels whose rays meet a capsule on the CPU, at the same depth."""
    from treeform.structures import OpacityGrid

    grid = OpacityGrid(np.zeros((16, 16, 16), np.float32), np.array([-1.6, -1.6, -1.6]), 0.2,
                       wood=_scattered_capsules(30, 5))
    rdm = RadialDistanceMap(np.zeros(3), np.full((6, 16, 16), 2.8, np.float32))
    for eye in ((0.0, 0.5, 7.0), (7.0, 1.0, 0.0), (-4.0, 3.0, -5.0), (0.3, 8.0, 0.2)):
        cam = Camera(64, 64, 30.0, eye, (0.0, 0.0, 0.0))
        res = render_rdm_impostor(rdm, cam, opacity=grid)
        h, w = cam.height, cam.width
        vv, uu = np.mgrid[:h, :w]
        o = np.asarray(cam.position, float)
        dirs = cam.unproject(uu.ravel() + 0.5, vv.ravel() + 0.5, np.full(h * w, 5.0)) - o
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        t = grid.wood_hit(np.repeat(o[None], h * w, 0), dirs).reshape(h, w)
        hit = np.isfinite(t)
        assert 0.03 < hit.mean() < 0.7
        assert (hit == res.mask).mean() > 0.995  # the odd pixel grazing a capsule's edge
        both = hit & res.mask
        depth = t * (dirs @ np.asarray(cam.axes()[2])).reshape(h, w)
        assert np.median(np.abs(depth[both] - res.depth[both])) < 1e-3
