"""Renderer: pixel alignment with Camera.project, silhouettes, depth, alpha test, double-sided."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import ConvexHull

from treeform._shared.errors import InputError
from treeform.render import Lighting, Renderer, RenderResult, render_views, to_uint8_rgb, view_camera
from treeform.structures import Camera, Material, Mesh, MeshPart

UNLIT = Lighting(key=(0, 0, 0), sky=(1, 1, 1), ground=(1, 1, 1))


def pixel_centres(cam: Camera):
    v, u = np.mgrid[0 : cam.height, 0 : cam.width] + 0.5
    return u, v


def inside_triangle(uv_tri: np.ndarray, u, v):
    """Pixel centres strictly inside a 2-D triangle, and their distance (px) to its nearest edge."""
    a, b, c = uv_tri[:, :2]
    pts = np.stack([u, v], -1)
    dist, sign = [], []
    for p0, p1 in ((a, b), (b, c), (c, a)):
        e = p1 - p0
        cross = e[0] * (pts[..., 1] - p0[1]) - e[1] * (pts[..., 0] - p0[0])
        sign.append(np.sign(cross))
        dist.append(np.abs(cross) / np.linalg.norm(e))
    sign = np.stack(sign)
    inside = np.all(sign > 0, axis=0) | np.all(sign < 0, axis=0)
    return inside, np.min(dist, axis=0)


def ray_box_depth(cam: Camera, lo, hi):
    """Analytic depth along the view axis of the first hit of each pixel-centre ray with a box."""
    u, v = pixel_centres(cam)
    ends = cam.unproject(u.ravel(), v.ravel(), np.ones(u.size))  # points at view depth 1
    o = np.asarray(cam.position)
    d = ends - o  # forward component is 1, so the ray parameter is the view depth
    with np.errstate(divide="ignore", invalid="ignore"):
        t0 = (np.asarray(lo) - o) / d
        t1 = (np.asarray(hi) - o) / d
    tn = np.nanmax(np.minimum(t0, t1), axis=1)
    tf = np.nanmin(np.maximum(t0, t1), axis=1)
    hit = (tf >= tn) & (tf > 0)
    return np.where(hit, tn, np.inf).reshape(cam.height, cam.width)


def test_vertices_land_on_their_projected_pixels(gl):
    # odd, non-square image and an off-axis camera catch flips, transposes and half-pixel shifts
    cam = Camera(97, 61, 50.0, (0.7, 0.4, 4.0), (0.1, -0.1, 0.0))
    rng = np.random.default_rng(3)
    tris = rng.uniform(-1.2, 1.2, (6, 3, 3)) * [1, 0.8, 0.6]
    r = Renderer(cam, samples=1, lighting=UNLIT)
    u, v = pixel_centres(cam)
    for tri in tris:
        part = MeshPart(tri, np.zeros((3, 3)), np.zeros((3, 2)), None, [[0, 1, 2]], Material(double_sided=True))
        res = r.render(part)
        uvz = cam.project(tri)
        inside, dist = inside_triangle(uvz, u, v)
        sure = dist > 1e-2  # pixel centres not within 1/100 px of an edge
        assert np.array_equal(res.mask[sure], inside[sure])
        # the interpolated view depth matches Camera.project where the vertex falls on the image
        for (pu, pv, pz) in uvz:
            col, row = int(np.floor(pu)), int(np.floor(pv))
            if 0 <= col < cam.width and 0 <= row < cam.height and res.mask[row, col]:
                assert abs(res.depth[row, col] - pz) < 0.05 * pz


def test_small_square_around_projected_vertex(gl):
    cam = Camera(80, 50, 45.0, (0.3, 0.5, 3.0), (0.0, 0.0, 0.0))
    p = np.array([0.37, -0.21, 0.15])
    uvz = cam.project(p[None])[0]
    r_, up, f = cam.axes()
    s = 1.2 * uvz[2] / cam.focal  # square 2.4 px wide, facing the camera
    quad = p + np.array([-r_ - up, r_ - up, r_ + up, -r_ + up]) * s
    part = MeshPart(quad, np.tile(-f, (4, 1)), np.zeros((4, 2)), None, [[0, 1, 2], [0, 2, 3]])
    res = Renderer(cam, samples=4).render(part)
    row, col = int(uvz[1]), int(uvz[0])
    assert res.mask[row, col]
    assert 1 <= res.mask.sum() <= 9
    rows, cols = np.nonzero(res.mask)
    assert abs(cols.mean() + 0.5 - uvz[0]) < 0.75 and abs(rows.mean() + 0.5 - uvz[1]) < 0.75
    assert res.depth[row, col] == pytest.approx(uvz[2], rel=1e-3)


@pytest.fixture(scope="module")
def cube_render(gl, meshes):
    cam = Camera(160, 120, 40.0, (2.2, 1.7, 3.6), (0.05, 0.0, 0.0))
    part = meshes.cube(half=(0.5, 0.5, 0.5), material=Material(base_color=(0.8, 0.7, 0.5, 1.0)))
    return cam, Renderer(cam).render(Mesh([part]))


def test_cube_silhouette_matches_projected_hull(cube_render):
    cam, res = cube_render
    corners = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
    hull = ConvexHull(cam.project(corners)[:, :2])
    u, v = pixel_centres(cam)
    pts = np.stack([u.ravel(), v.ravel()], 1)
    analytic = np.all(pts @ hull.equations[:, :2].T + hull.equations[:, 2] <= 0, axis=1).reshape(u.shape)
    iou = (analytic & res.mask).sum() / (analytic | res.mask).sum()
    assert iou >= 0.98
    assert res.color.shape == (120, 160, 4) and res.color.dtype == np.uint8
    assert res.mask.dtype == bool and res.depth.dtype == np.float32
    # alpha 0 where nothing is drawn, opaque inside; MSAA only touches the silhouette's edge
    assert np.all(res.color[~res.mask & ~_dilate(res.mask), 3] == 0)
    assert np.all(res.color[res.mask & ~_dilate(~res.mask), 3] == 255)


def _dilate(m):
    out = m.copy()
    out[1:] |= m[:-1]
    out[:-1] |= m[1:]
    out[:, 1:] |= m[:, :-1]
    out[:, :-1] |= m[:, 1:]
    return out


def test_cube_depth_matches_ray_cast(cube_render):
    cam, res = cube_render
    analytic = ray_box_depth(cam, (-0.5, -0.5, -0.5), (0.5, 0.5, 0.5))
    both = res.mask & np.isfinite(analytic)
    assert both.sum() > 0.98 * res.mask.sum()
    rel = np.abs(res.depth[both] - analytic[both]) / analytic[both]
    assert rel.max() < 1e-3
    assert np.all(np.isinf(res.depth[~res.mask]))


def test_cube_lighting_top_brighter_than_front_brighter_than_right(cube_render):
    cam, res = cube_render
    rows, cols = np.nonzero(res.mask & ~_dilate(~res.mask))
    pts = cam.unproject(cols + 0.5, rows + 0.5, res.depth[rows, cols])
    axis = np.argmax(np.abs(pts), axis=1)
    lum = res.color[rows, cols, :3].astype(float).mean(axis=1)
    top, right, front = (lum[axis == a].mean() for a in (1, 0, 2))
    assert top > front > right > 20


def test_alpha_mask_texture_left_half_transparent(gl, meshes):
    cam = Camera(64, 64, 60.0, (0.0, 0.0, 2.5), (0.0, 0.0, 0.0))
    tex = np.zeros((8, 8, 4), np.uint8)
    tex[..., 0] = 255
    tex[:, 4:, 3] = 255  # right half opaque
    part = meshes.quad(material=Material("leaf", (1, 1, 1, 1), tex, "MASK", 0.5, False))
    res = Renderer(cam, lighting=UNLIT).render(part)
    quad_px = cam.project(np.array([[-1, -1, 0], [1, 1, 0]]))
    c0, c1 = int(round(quad_px[0, 0])), int(round(quad_px[1, 0]))
    r0, r1 = int(round(quad_px[1, 1])), int(round(quad_px[0, 1]))
    assert not res.mask[:, :32].any()
    assert res.mask[r0 + 1 : r1 - 1, 32 : c1 - 1].all()
    assert not res.mask[:, c1 + 1 :].any() and not res.mask[: r0 - 1].any() and not res.mask[r1 + 1 :].any()
    inner = res.color[r0 + 2 : r1 - 2, 34 : c1 - 2]
    assert np.all(inner == [255, 0, 0, 255])  # texture x base colour, unlit
    assert c0 < 32


def test_alpha_mask_uses_vertex_and_base_alpha(gl, meshes):
    cam = Camera(32, 32, 60.0, (0.0, 0.0, 2.5), (0.0, 0.0, 0.0))
    r = Renderer(cam, samples=1)
    cut = meshes.quad(material=Material(base_color=(1, 1, 1, 0.4), alpha_mode="MASK", alpha_cutoff=0.5))
    assert not r.render(cut).mask.any()
    keep = meshes.quad(material=Material(base_color=(1, 1, 1, 0.4), alpha_mode="OPAQUE"))
    assert r.render(keep).mask.any() and np.all(r.render(keep).color[r.render(keep).mask, 3] == 255)


def test_double_sided_back_faces_render_with_flipped_normal(gl, meshes):
    cam = Camera(48, 48, 60.0, (0.0, 0.0, 2.5), (0.0, 0.0, 0.0))
    r = Renderer(cam, samples=1)
    back_single = r.render(meshes.quad(material=Material(double_sided=False), facing=-1))
    assert not back_single.mask.any()
    back_double = r.render(meshes.quad(material=Material(double_sided=True), facing=-1))
    front = r.render(meshes.quad(material=Material(double_sided=False), facing=+1))
    assert back_double.mask.sum() > 0.3 * back_double.mask.size
    assert np.array_equal(back_double.mask, front.mask)
    # the back face's normal is flipped toward the viewer, so it is lit like the front face
    assert np.abs(back_double.color.astype(int) - front.color.astype(int)).max() <= 1


def test_vertex_colors_and_base_color_multiply(gl, meshes):
    cam = Camera(32, 32, 60.0, (0.0, 0.0, 2.5), (0.0, 0.0, 0.0))
    colors = np.tile([0.5, 1.0, 1.0, 1.0], (4, 1))
    part = meshes.quad(material=Material(base_color=(1.0, 0.5, 0.0, 1.0)), colors=colors)
    res = Renderer(cam, samples=1, lighting=UNLIT).render(part)
    px = res.color[16, 16].astype(int)
    assert np.abs(px - [128, 128, 0, 255]).max() <= 1


def test_unlit_material_shows_its_colour_under_any_light(gl, meshes, tmp_path):
    """KHR_materials_unlit: a lit quad takes the light's colour and strength, an unlit one shows
    its base colour as it is, under a dim red light too; the flag survives a GLB round trip."""
    from treeform.io.gltf import read_glb, read_glb_mesh, write_glb

    cam = Camera(32, 32, 60.0, (0.0, 0.0, 2.5), (0.0, 0.0, 0.0))
    dim_red = Lighting(key=(0.3, 0.0, 0.0), sky=(0.2, 0.05, 0.05), ground=(0.1, 0.0, 0.0), specular=0.0)
    colour = (0.2, 0.6, 0.4, 1.0)
    lit = Renderer(cam, samples=1, lighting=dim_red).render(meshes.quad(material=Material(base_color=colour)))
    unlit_part = meshes.quad(material=Material(base_color=colour, unlit=True))
    flat = Renderer(cam, samples=1, lighting=dim_red).render(unlit_part)
    assert lit.color[16, 16, 1] < 40  # green barely lit by a red light
    px = flat.color[16, 16, :3].astype(int)
    assert np.abs(px - np.rint(255 * np.array(colour[:3]))).max() <= 1, px
    write_glb(Mesh([unlit_part]), tmp_path / "u.glb")
    assert "KHR_materials_unlit" in read_glb(tmp_path / "u.glb")[0]["extensionsUsed"]
    back = read_glb_mesh(tmp_path / "u.glb")
    assert back.parts[0].material.unlit
    again = Renderer(cam, samples=1, lighting=dim_red).render(back)
    assert np.array_equal(again.color[16, 16], flat.color[16, 16])


def test_blend_material_gives_partial_alpha(gl, meshes):
    cam = Camera(32, 32, 60.0, (0.0, 0.0, 2.5), (0.0, 0.0, 0.0))
    part = meshes.quad(material=Material(base_color=(0.0, 0.0, 1.0, 0.5), alpha_mode="BLEND"))
    res = Renderer(cam, samples=1, lighting=UNLIT).render(part)
    assert res.mask[16, 16]
    assert abs(int(res.color[16, 16, 3]) - 128) <= 1 and res.color[16, 16, 2] >= 254
    rgb = to_uint8_rgb(res.color, background=(255, 255, 255))
    assert np.abs(rgb[16, 16].astype(int) - [127, 127, 255]).max() <= 2


def test_opaque_background_and_zero_normals(gl):
    cam = Camera(40, 30, 50.0, (0.0, 0.0, 3.0), (0.0, 0.0, 0.0))
    p = np.array([[-1, -1, 0], [1, -1, 0], [0, 1, 0]], float)
    part = MeshPart(p, np.zeros((3, 3)), np.zeros((3, 2)), None, [[0, 1, 2]])
    res = Renderer(cam, background=(0.0, 0.0, 0.0, 1.0)).render(part)
    assert np.all(res.color[..., 3] == 255)
    assert np.all(res.color[~res.mask & ~_dilate(res.mask), :3] == 0)
    assert res.color[res.mask, :3].mean() > 50  # flat normal fallback faces the camera: lit


def test_empty_mesh_gives_background(gl):
    cam = Camera(20, 10, 50.0)
    res = Renderer(cam, background=(1, 0, 0, 0)).render(Mesh())
    assert not res.mask.any() and np.all(np.isinf(res.depth))
    assert np.all(res.color == [255, 0, 0, 0])


def test_renders_are_deterministic(gl, meshes):
    cam = Camera(120, 90, 45.0, (0.0, 3.0, 9.0), (0.0, 3.0, 0.0))
    mesh = Mesh([meshes.leaves(1500, seed=1), meshes.cube(center=(0, 1, 0), half=(0.2, 1, 0.2))])
    a = Renderer(cam).render(mesh)
    b = Renderer(cam).render(mesh)
    for x, y in ((a, b),):
        assert x.color.tobytes() == y.color.tobytes()
        assert x.mask.tobytes() == y.mask.tobytes()
        assert x.depth.tobytes() == y.depth.tobytes()
    # the silhouette is independent of MSAA
    s1 = Renderer(cam, samples=1).render(mesh)
    assert np.array_equal(s1.mask, a.mask) and np.array_equal(s1.depth, a.depth)


def test_cache_sees_replaced_arrays(gl, meshes):
    cam = Camera(40, 40, 50.0, (0.0, 0.0, 3.0), (0.0, 0.0, 0.0))
    r = Renderer(cam, samples=1)
    part = meshes.cube(half=(0.3, 0.3, 0.3))
    m1 = r.render(part).mask.sum()
    part.positions = part.positions * 2
    m2 = r.render(part).mask.sum()
    assert m2 > 3 * m1


def test_render_views_side_and_top(gl, meshes):
    cam = Camera(64, 64, 40.0, (0.0, 0.0, 6.0), (0.0, 0.0, 0.0))
    # a marker cube in front (+Z) of a central one
    mesh = Mesh([meshes.cube(half=(0.4, 0.4, 0.4)), meshes.cube(center=(0, 0, 1.0), half=(0.15,) * 3)])
    views = render_views(mesh, cam, samples=1)
    assert list(views) == ["front", "side", "top"]
    assert all(isinstance(v, RenderResult) for v in views.values())
    top = views["top"]
    rows, _ = np.nonzero(top.mask)
    assert rows.max() > 44  # the front marker sits at the bottom of the top view
    marker = view_camera(cam, "top").project(np.array([[0, 0, 1.0]]))[0]
    assert top.mask[int(marker[1]), int(marker[0])] and marker[1] > 40
    side_cam = view_camera(cam, "side")
    assert np.allclose(side_cam.position, (6, 0, 0), atol=1e-9)
    m = side_cam.project(np.array([[0, 0, 1.0]]))[0]
    assert views["side"].mask[int(m[1]), int(m[0])]


def test_bad_inputs_raise_input_error(gl):
    cam = Camera(10, 10, 50.0)
    with pytest.raises(InputError, match="camera"):
        Renderer("not a camera")
    with pytest.raises(InputError, match="background"):
        Renderer(cam, background=(1, 1, 1))
    with pytest.raises(InputError, match="mesh"):
        Renderer(cam).render(np.zeros((3, 3)))
    with pytest.raises(InputError, match="views"):
        render_views(Mesh(), cam, views=("front", "diagonal"))
    with pytest.raises(InputError, match="color"):
        to_uint8_rgb(np.zeros((4, 4, 3), np.uint8))


def test_to_uint8_rgb_composites():
    px = np.array([[[200, 100, 0, 255], [0, 0, 0, 0], [255, 255, 255, 51]]], np.uint8)
    out = to_uint8_rgb(px, background=(0, 0, 100))
    assert out.dtype == np.uint8 and out.shape == (1, 3, 3)
    assert out.tolist() == [[[200, 100, 0], [0, 0, 100], [51, 51, 131]]]


def test_large_image_and_200k_triangles(gl, meshes):
    cam = Camera(1024, 1024, 45.0, (0.0, 3.0, 14.0), (0.0, 3.0, 0.0))
    part = meshes.leaves(100_000, seed=2)
    assert part.n_triangles == 200_000
    res = Renderer(cam, samples=1).render(part)
    assert res.color.shape == (1024, 1024, 4)
    assert 0.2 < res.mask.mean() < 0.9
    assert np.all(res.color[res.mask, 3] == 255) and np.all(res.color[~res.mask, 3] == 0)
    assert np.all(np.isfinite(res.depth[res.mask]))


def test_camera_relative_lighting_lights_every_view_alike(gl, meshes):
    cam = Camera(48, 48, 40.0, (0.0, 0.0, 4.0), (0.0, 0.0, 0.0))
    light = Lighting(direction=(0, 0, 1), camera_relative=True)
    sph = meshes.sphere((0, 0, 0), 1.0, 48, 24)
    part = MeshPart(sph[0], sph[1], np.zeros((len(sph[0]), 2)), None, sph[2])
    views = render_views(part, cam, views=("front", "side", "back"), samples=1, lighting=light)
    imgs = [v.color.astype(int) for v in views.values()]
    assert max(np.abs(imgs[0] - im).max() for im in imgs[1:]) <= 3
    with pytest.raises(InputError, match="direction"):
        Lighting(direction=(0, 0, 0))
    with pytest.raises(InputError, match="key"):
        Lighting(key=(1, 1))


def test_alpha_tested_leaves_keep_their_coverage_at_distance(gl, meshes):
    """Small leaves on a card (8 % of it): drawn 128 px wide and 16 px wide, about the same share of
    the card stays opaque (coverage-preserving mip levels; plain averaged alpha keeps 0.8 % at 16 px
    and nothing at 8 px)."""
    import cv2

    rng = np.random.default_rng(0)
    tex = np.zeros((256, 256, 4), np.uint8)
    for _ in range(120):
        cv2.circle(tex, (int(rng.integers(256)), int(rng.integers(256))), int(rng.integers(2, 6)), (40, 120, 30, 255), -1)
    base = float((tex[..., 3] >= 128).mean())
    part = meshes.quad(material=Material("leaf", (1, 1, 1, 1), tex, "MASK", 0.5, True))
    shares = []
    for size in (128, 16):
        cam = Camera(size, size, 2 * np.degrees(np.arctan(1 / 2.5)), (0.0, 0.0, 2.5), (0.0, 0.0, 0.0))
        res = Renderer(cam, lighting=UNLIT, samples=1).render(part)
        shares.append(float(res.mask.mean()))
    assert 0.05 < base < 0.12
    assert abs(shares[0] - base) < 0.02 and abs(shares[1] - base) < 0.02, (base, shares)
