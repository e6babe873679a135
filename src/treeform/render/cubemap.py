"""Radial distance cubemaps rasterized on the GPU (seed 001 §3.5: the RDM).

:func:`render_radial_cubemap` draws a closed triangle mesh into the six faces of a cubemap
centred at ``c`` and keeps, per texel, the largest distance ``|p - c|`` of any surface point
along that direction (blend equation MAX into an R32F target, no depth test). The face order and
texel layout are those of :mod:`treeform.structures.rdm`, so the result is directly the
``radii`` of a :class:`~treeform.structures.rdm.RadialDistanceMap`.

:func:`bake_color_cubemap` gives a relief impostor the colours of a full 3D mesh (a grown tree,
a multi-view reconstruction): what the mesh shows, seen from outside, where each texel's
direction meets the RDM's surface.
"""

from __future__ import annotations

import math

import numpy as np

from treeform._shared.checks import check_array, check_finite
from treeform._shared.errors import InputError, RenderError
from treeform.render.context import get_context
from treeform.structures.rdm import CUBE_FACE_MATRICES

__all__ = ["render_radial_cubemap", "bake_color_cubemap"]

_VERTEX = """
#version 330
uniform mat3 u_m;          // cube-face matrix @ rotation about +Y
in vec3 in_off;            // p - c
in float in_h;
out vec3 v_q;
out float v_h;
void main() {
    vec3 q = u_m * in_off;  // (sc, tc, ma)
    v_q = q;
    v_h = in_h;
    gl_Position = vec4(q.x, q.y, 0.0, q.z);  // NDC = (sc / ma, tc / ma); ma <= 0 is clipped
}
"""

_FRAGMENT = """
#version 330
uniform float u_rho;
in vec3 v_q;
in float v_h;
layout(location = 0) out vec4 f_r;
void main() {
    f_r = vec4(max(length(v_q) * (1.0 + u_rho * (v_h - 0.5)), 0.0), 0.0, 0.0, 0.0);
}
"""

_programs: dict = {}


def _program(ctx):
    prog = _programs.get(id(ctx))
    if prog is None or prog[0] is not ctx:
        try:
            prog = (ctx, ctx.program(vertex_shader=_VERTEX, fragment_shader=_FRAGMENT))
        except Exception as exc:
            raise RenderError(f"OpenGL shader compilation failed: {exc}") from None
        _programs.clear()
        _programs[id(ctx)] = prog
    return prog[1]


def _rot_y(deg: float) -> np.ndarray:
    a = math.radians(deg)
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def render_radial_cubemap(positions: np.ndarray, faces: np.ndarray, center, *, values=None, rho: float = 0.0,
                          resolution: int = 256, rotations_deg=()) -> np.ndarray:
    """Rasterize the radial distance map of a closed triangle mesh (seed 001 §3.5).

    For every fragment on the surface, at point ``p``, the map stores
    ``r = |p - c| * (1 + rho * (h - 0.5))`` and keeps the maximum over all fragments that fall
    in a texel, where ``h`` is ``values`` interpolated across the triangle (0.5 when ``values``
    is None, so ``r = |p - c|``). For each angle in ``rotations_deg`` a copy of the mesh rotated
    by that angle about the vertical (+Y) axis through ``c`` is drawn too (counter-clockwise
    seen from above, i.e. the right-handed rotation about +Y), and the maximum is kept.

    Parameters
    ----------
    positions : ndarray, shape (V, 3)
        Vertex positions in metres.
    faces : ndarray, shape (F, 3), int
        Triangle vertex indices (winding does not matter).
    center : sequence of 3 floats
        Cubemap centre ``c``.
    values : ndarray, shape (V,), float in [0, 1], optional
        Per-vertex value ``h`` (e.g. a relief or density), interpolated across triangles.
    rho : float
        Strength of the ``values`` modulation; 0 disables it.
    resolution : int
        Side ``R`` of each cubemap face in texels.
    rotations_deg : sequence of float
        Extra copies rotated about +Y through ``c`` (degrees).

    Returns
    -------
    ndarray, shape (6, R, R), float32
        Radius per texel, faces in OpenGL order (+X, -X, +Y, -Y, +Z, -Z); texel ``[f, row, col]``
        is the direction ``texel_directions(R)[f, row, col]`` of :mod:`treeform.structures.rdm`.
        Texels that no fragment reaches are 0.

    Raises
    ------
    InputError
        For a bad argument.
    RenderError
        If no OpenGL context can be created.

    Examples
    --------
    >>> from treeform.structures import RadialDistanceMap
    >>> radii = render_radial_cubemap(verts, tris, (0, 1, 0), resolution=64)  # doctest: +SKIP
    >>> rdm = RadialDistanceMap((0, 1, 0), radii)                               # doctest: +SKIP
    """
    pos = check_array(positions, "positions", ndim=2, dtype_kind="iuf", shape=(None, 3))
    tri = check_array(faces, "faces", ndim=2, dtype_kind="iu", shape=(None, 3))
    c = check_array(center, "center", dtype_kind="iuf").astype(np.float64).reshape(-1)
    if c.shape != (3,) or not np.all(np.isfinite(c)):
        raise InputError(f"center: expected 3 finite numbers, got {center!r}")
    if len(tri) and (int(tri.min()) < 0 or int(tri.max()) >= len(pos)):
        raise InputError(f"faces: indices must lie in [0, {len(pos)}), got range "
                         f"[{int(tri.min())}, {int(tri.max())}]")
    if values is None:
        h = np.full(len(pos), 0.5, np.float32)
    else:
        h = check_array(values, "values", ndim=1, dtype_kind="iuf", shape=(len(pos),)).astype(np.float32)
        if len(h) and (h.min() < 0 or h.max() > 1):
            raise InputError(f"values: expected values in [0, 1], got range [{h.min():.4g}, {h.max():.4g}]")
    rho = check_finite(rho, "rho")
    if isinstance(resolution, bool) or not isinstance(resolution, (int, np.integer)) or resolution < 1:
        raise InputError(f"resolution: expected a positive integer, got {resolution!r}")
    res = int(resolution)
    try:
        angles = [float(a) for a in np.atleast_1d(np.asarray(rotations_deg, np.float64))]
    except (TypeError, ValueError):
        raise InputError(f"rotations_deg: expected a sequence of angles in degrees, got {rotations_deg!r}") from None
    if not all(math.isfinite(a) for a in angles):
        raise InputError(f"rotations_deg: expected finite angles, got {rotations_deg!r}")

    import moderngl

    ctx = get_context()
    limit = min(int(ctx.info.get("GL_MAX_RENDERBUFFER_SIZE", 8192)), int(ctx.info.get("GL_MAX_VIEWPORT_DIMS", (8192,))[0]))
    if 3 * res > limit:
        raise InputError(f"resolution: {res} too large for this device (at most {limit // 3})")
    out_w, out_h = 3 * res, 2 * res  # faces tiled 3 x 2: face f at column f % 3, row f // 3
    if len(tri) == 0:
        return np.zeros((6, res, res), np.float32)

    # offsets from the centre in float64 before the float32 upload (keeps precision far from 0)
    vdata = np.empty((len(pos), 4), np.float32)
    vdata[:, :3] = np.asarray(pos, np.float64) - c
    vdata[:, 3] = h
    prog = _program(ctx)
    objs = []
    try:
        vbo = ctx.buffer(vdata.tobytes())
        objs.append(vbo)
        ibo = ctx.buffer(np.ascontiguousarray(tri, np.uint32).tobytes())
        objs.append(ibo)
        vao = ctx.vertex_array(prog, [(vbo, "3f 1f", "in_off", "in_h")], index_buffer=ibo, index_element_size=4)
        objs.append(vao)
        rb = ctx.renderbuffer((out_w, out_h), 1, dtype="f4")
        objs.append(rb)
        fbo = ctx.framebuffer([rb])
        objs.append(fbo)

        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, 0.0)
        ctx.enable_only(moderngl.BLEND)
        ctx.blend_equation = moderngl.MAX
        ctx.blend_func = moderngl.ONE, moderngl.ONE
        prog["u_rho"].value = rho
        rots = [np.eye(3)] + [_rot_y(a) for a in angles]
        for f in range(6):
            fbo.viewport = ((f % 3) * res, (f // 3) * res, res, res)
            ctx.viewport = fbo.viewport
            for rot in rots:
                m = CUBE_FACE_MATRICES[f] @ rot
                prog["u_m"].write(np.ascontiguousarray(m.T, np.float32).tobytes())  # column-major
                vao.render(moderngl.TRIANGLES)
        fbo.viewport = (0, 0, out_w, out_h)
        raw = fbo.read(viewport=(0, 0, out_w, out_h), components=1, dtype="f4")
    except moderngl.Error as exc:
        raise RenderError(f"OpenGL cubemap render failed: {exc}") from None
    finally:
        ctx.blend_equation = moderngl.FUNC_ADD
        ctx.enable_only(moderngl.NOTHING)
        for obj in reversed(objs):
            obj.release()
    # readback row 0 = window y 0 = NDC y -1 = t -1 = rdm row 0: no flip
    tiles = np.frombuffer(raw, np.float32).reshape(2, res, 3, res)
    return np.ascontiguousarray(tiles.transpose(0, 2, 1, 3).reshape(6, res, res))


# the directions the mesh is drawn from: the six axes and the eight cube diagonals (azimuth, elevation)
_BAKE_VIEWS = ([(az, 0.0) for az in (0.0, 90.0, 180.0, 270.0)] + [(0.0, 90.0), (0.0, -90.0)]
               + [(az, el) for az in (45.0, 135.0, 225.0, 315.0) for el in (35.26, -35.26)])


def bake_color_cubemap(mesh, rdm, *, face: int = 128, view_size: int = 512) -> np.ndarray:
    """Colour cubemap of a mesh on its radial distance map's surface, baked from views of the mesh.

    Each texel's direction ``d`` from the RDM's centre ``c`` gives the point
    ``p = c + R(d) d`` on the RDM's surface. The mesh is drawn (unlit albedo, alpha-tested
    leaves) from the six axes and the eight cube diagonals by narrow-angle cameras, and the
    texel takes the colour seen at ``p``'s pixel in the view that faces ``d`` the most among
    the views in which that pixel shows the tree: the mesh's own colours on every side, where
    :func:`treeform.crown.color_cubemap.color_cubemap` synthesizes them from one front view
    (the only choice for a single photo). Texels that no view covers (a gap through the whole
    crown) take the colour of the nearest covered texel of their face.

    Parameters
    ----------
    mesh : Mesh or MeshPart
    rdm : RadialDistanceMap
        Its surface carries the colours; its centre is the cubemap's.
    face : int
        Edge of a colour face in texels.
    view_size : int
        Edge of each baking view in pixels.

    Returns
    -------
    ndarray, shape (6, face, face, 3), uint8
        Faces in OpenGL order (+X, -X, +Y, -Y, +Z, -Z), laid out as
        :func:`treeform.structures.rdm.texel_directions`.
    """
    import cv2
    from scipy import ndimage

    from treeform._shared.checks import check_int
    from treeform.render.lighting import Lighting
    from treeform.render.renderer import Renderer, _as_mesh
    from treeform.structures.camera import box_camera
    from treeform.structures.rdm import texel_directions

    face = check_int(face, "face", 4, 4096)
    view_size = check_int(view_size, "view_size", 16, 8192)
    mesh = _as_mesh(mesh)
    pts = [p.positions for p in mesh.parts if p.n_vertices]
    if not pts:
        raise InputError("mesh: nothing to bake (no vertices)")
    pts = np.concatenate(pts).astype(np.float64)
    lo, hi = np.minimum(pts.min(0), rdm.bounds()[0]), np.maximum(pts.max(0), rdm.bounds()[1])
    dirs = texel_directions(face).reshape(-1, 3)
    surface = np.asarray(rdm.center, np.float64) + dirs * rdm.lookup(dirs)[:, None]
    best = np.full(len(dirs), -np.inf)
    color = np.zeros((len(dirs), 3), np.uint8)
    unlit = Lighting(key=(0.0, 0.0, 0.0), sky=(1.0, 1.0, 1.0), ground=(1.0, 1.0, 1.0))
    for az, el in _BAKE_VIEWS:
        cam = box_camera(lo, hi, az, el, view_size)
        r = Renderer(cam, samples=1, background=(0.0, 0.0, 0.0, 0.0), lighting=unlit)
        try:
            res = r.render(mesh)
        finally:
            r.release()
        uvz = cam.project(surface)
        u = np.clip(np.floor(uvz[:, 0]).astype(np.int64), 0, view_size - 1)
        v = np.clip(np.floor(uvz[:, 1]).astype(np.int64), 0, view_size - 1)
        seen = res.mask[v, u]
        toward = -np.asarray(cam.axes()[2])  # from the tree toward this view's camera
        score = np.where(seen, dirs @ toward, -np.inf)
        take = score > best
        best[take] = score[take]
        color[take] = res.color[v[take], u[take], :3]
    color = color.reshape(6, face, face, 3)
    covered = np.isfinite(best).reshape(6, face, face)
    for f in range(6):
        if covered[f].any() and not covered[f].all():
            _, (ri, ci) = ndimage.distance_transform_edt(~covered[f], return_indices=True)
            color[f] = color[f][ri, ci]
        elif not covered[f].any():
            color[f] = np.median(color[covered], axis=0).astype(np.uint8) if covered.any() else 0
    # one texel a leaf, the next the sky through a gap: a 3x3 median per face settles the speckle
    return np.stack([cv2.medianBlur(np.ascontiguousarray(c), 3) for c in color])
