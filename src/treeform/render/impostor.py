"""Direct rendering of a radial distance map by relief mapping in world space (seed 001 §4.1).

The crown is drawn as its RDM's bounding box; each fragment marches the view ray through the
box (a linear search of ``steps`` samples, then ``refine`` bisections) until the ray enters the
crown (``|p - c| <= R(p - c)``), takes its colour from the colour cubemap along the same
direction, lights it with the normal of the RDM's surface (central differences of
``|p - c| - R(p - c)``) and writes that point's depth, so impostors and meshes occlude each
other correctly. Fragments whose ray misses the crown are discarded: the silhouette from any
direction is the RDM's.
"""

from __future__ import annotations

import numpy as np

from treeform._shared.checks import check_int
from treeform._shared.errors import InputError, RenderError
from treeform.render.context import get_context
from treeform.render.gpu import _mat_bytes
from treeform.render.result import RenderResult
from treeform.structures.camera import Camera

__all__ = ["render_rdm_impostor"]

_VS = """
#version 330
uniform mat4 u_view;
uniform mat4 u_proj;
in vec3 in_pos;
out vec3 v_world;
void main() {
    v_world = in_pos;
    gl_Position = u_proj * u_view * vec4(in_pos, 1.0);
}
"""

_FS = """
#version 330
uniform samplerCube u_rdm;
uniform samplerCube u_color;
uniform mat4 u_view;
uniform mat4 u_proj;
uniform vec3 u_eye;
uniform vec3 u_center;
uniform vec3 u_lo;
uniform vec3 u_hi;
uniform vec3 u_light;
uniform int u_steps;
uniform int u_refine;
uniform float u_eps;
uniform int u_planar;       // 1: colour from the front view as a billboard facing the camera (distant trees)
uniform sampler2D u_front;  // the front view, RGBA (alpha: the tree)
uniform vec3 u_right;       // the camera's right and up axes (world)
uniform vec3 u_up;
uniform vec2 u_front_px;    // the crown centre's pixel in the front view
uniform vec2 u_front_size;  // the front view's size in pixels
uniform float u_front_scale;  // its pixels per metre at the crown centre
in vec3 v_world;
layout(location = 0) out vec4 f_color;
layout(location = 1) out vec4 f_depth;

float inside(vec3 p) {  // <= 0 inside the crown
    vec3 d = p - u_center;
    return length(d) - texture(u_rdm, d).r;
}

void main() {
    vec3 dir = normalize(v_world - u_eye);
    // the ray's span inside the box (slabs): from the eye (or the box's near side) to its far side
    vec3 inv = 1.0 / dir;
    vec3 ta = (u_lo - u_eye) * inv, tb = (u_hi - u_eye) * inv;
    vec3 tmin = min(ta, tb), tmax = max(ta, tb);
    float t0 = max(max(max(tmin.x, tmin.y), tmin.z), 0.0);
    float t1 = min(min(tmax.x, tmax.y), tmax.z);
    if (t1 <= t0) discard;
    float dt = (t1 - t0) / float(u_steps);
    float prev = t0;
    float hit = -1.0;
    for (int i = 0; i <= u_steps; i++) {  // linear search
        float t = t0 + dt * float(i);
        if (inside(u_eye + dir * t) <= 0.0) { hit = t; break; }
        prev = t;
    }
    if (hit < 0.0) discard;
    float a = prev, b = hit;
    for (int i = 0; i < u_refine; i++) {  // binary refinement between the last miss and the hit
        float m = 0.5 * (a + b);
        if (inside(u_eye + dir * m) <= 0.0) b = m; else a = m;
    }
    vec3 p = u_eye + dir * b;
    vec3 e = vec3(u_eps, 0.0, 0.0);
    vec3 n = normalize(vec3(inside(p + e.xyy) - inside(p - e.xyy), inside(p + e.yxy) - inside(p - e.yxy),
                            inside(p + e.yyx) - inside(p - e.yyx)) + 1e-9);
    vec3 albedo = texture(u_color, p - u_center).rgb;
    if (u_planar == 1) {  // seed 001 §4.1, second option: the same billboard texture from every direction
        vec3 q = p - u_center;
        vec2 px = u_front_px + u_front_scale * vec2(dot(q, u_right), -dot(q, u_up));
        vec4 f = texture(u_front, px / u_front_size);
        if (f.a > 0.5) albedo = f.rgb;
    }
    float lit = 0.55 + 0.45 * max(dot(n, normalize(u_light)), 0.0);
    f_color = vec4(albedo * lit, 1.0);
    vec4 view = u_view * vec4(p, 1.0);
    vec4 clip = u_proj * view;
    gl_FragDepth = 0.5 * clip.z / clip.w + 0.5;
    f_depth = vec4(-view.z, 1.0, 0.0, 1.0);
}
"""

_BOX = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                 [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]], np.uint32)


def render_rdm_impostor(rdm, camera: Camera, *, color: np.ndarray | None = None, steps: int = 64, refine: int = 6,
                        light=(-0.4, 0.8, 0.5), planar: dict | None = None) -> RenderResult:
    """Draw a radial distance map as a relief-mapped impostor from ``camera``.

    Parameters
    ----------
    rdm : RadialDistanceMap
    camera : Camera
    color : ndarray, shape (6, F, F, 3), uint8, optional
        The colour cubemap (e.g. :func:`treeform.crown.color_cubemap.color_cubemap`), faces in
        the RDM's order and orientation; default a flat green.
    steps, refine : int
        Samples of the linear search through the bounding box, then bisections.
    light : sequence of 3 floats
        Direction toward the light (world).
    planar : dict, optional
        The paper's second colour option, for distant trees: the front view used as a
        billboard that faces the camera (sharper than the cubemap, but the same picture from
        every side). ``{"image": (H, W, 4) uint8 with alpha = the tree, "center_px": (u, v),
        the crown centre's pixel in it, "pixels_per_metre": scale at the crown centre}`` (what
        ``treeform impostor`` records in ``impostor.json`` as ``front``).
        Pixels where the billboard shows no tree keep the cubemap's colour; the silhouette is
        the RDM's either way.

    Returns
    -------
    RenderResult
        ``color`` RGBA (alpha 255 on the crown), ``mask``, ``depth`` (metres along the view
        axis, inf off the crown), ``camera``.
    """
    import moderngl

    from treeform.structures import RadialDistanceMap

    if not isinstance(rdm, RadialDistanceMap):
        raise InputError(f"rdm: expected a RadialDistanceMap, got {type(rdm).__name__}")
    steps = check_int(steps, "steps", 4, 4096)
    refine = check_int(refine, "refine", 0, 32)
    if color is None:
        color = np.broadcast_to(np.array([60, 110, 45], np.uint8), (6, 4, 4, 3))
    color = np.ascontiguousarray(color, np.uint8)
    front = None
    if planar is not None:
        try:
            front = np.ascontiguousarray(planar["image"], np.uint8)
            front_px = tuple(float(x) for x in planar["center_px"])
            front_scale = float(planar["pixels_per_metre"])
        except (KeyError, TypeError, ValueError):
            raise InputError("planar: expected {'image', 'center_px', 'pixels_per_metre'}") from None
        if front.ndim != 3 or front.shape[2] != 4 or len(front_px) != 2 or not front_scale > 0:
            raise InputError(f"planar: expected an (H, W, 4) uint8 image, a (u, v) pixel and a scale > 0, "
                             f"got {front.shape}, {front_px}, {front_scale}")
    if color.ndim != 4 or color.shape[0] != 6 or color.shape[1] != color.shape[2] or color.shape[3] != 3:
        raise InputError(f"color: expected (6, F, F, 3) uint8 faces, got {color.shape}")
    lo, hi = rdm.bounds()
    pad = 1e-3 * max(float(np.max(hi - lo)), 1e-6)
    lo, hi = lo - pad, hi + pad
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])],
                       np.float32)
    ctx = get_context()
    w, h = int(camera.width), int(camera.height)
    res = rdm.resolution
    objs = []
    try:
        prog = ctx.program(vertex_shader=_VS, fragment_shader=_FS)
        objs.append(prog)
        rtex = ctx.texture_cube((res, res), 1, data=np.ascontiguousarray(rdm.radii, np.float32).tobytes(), dtype="f4")
        rtex.filter = (moderngl.NEAREST, moderngl.NEAREST)
        ctex = ctx.texture_cube((color.shape[1], color.shape[1]), 3, data=color.tobytes())
        ctex.filter = (moderngl.LINEAR, moderngl.LINEAR)
        objs += [rtex, ctex]
        # (a 1x1 stand-in without a front view: a sampler2D and the RDM's samplerCube may not share a unit)
        fimg = front if front is not None else np.zeros((1, 1, 4), np.uint8)
        ftex = ctx.texture((fimg.shape[1], fimg.shape[0]), 4, data=fimg.tobytes())
        ftex.filter = (moderngl.LINEAR, moderngl.LINEAR)
        ftex.repeat_x = ftex.repeat_y = False
        objs.append(ftex)
        vbo = ctx.buffer(corners.tobytes())
        ibo = ctx.buffer(_BOX.tobytes())
        vao = ctx.vertex_array(prog, [(vbo, "3f", "in_pos")], index_buffer=ibo, index_element_size=4)
        objs += [vbo, ibo, vao]
        col_rb = ctx.renderbuffer((w, h), 4)
        dep_rb = ctx.renderbuffer((w, h), 4, dtype="f4")
        zbuf = ctx.depth_renderbuffer((w, h))
        fbo = ctx.framebuffer([col_rb, dep_rb], zbuf)
        objs += [col_rb, dep_rb, zbuf, fbo]
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        ctx.enable_only(moderngl.DEPTH_TEST | moderngl.CULL_FACE)
        ctx.cull_face = "front"  # the box's far faces: every ray through the box gets a fragment, eye inside or not
        for name, value in (("u_view", _mat_bytes(camera.view_matrix())), ("u_proj", _mat_bytes(camera.projection_matrix()))):
            prog[name].write(value)
        prog["u_eye"].value = tuple(float(x) for x in camera.position)
        prog["u_center"].value = tuple(float(x) for x in rdm.center)
        prog["u_lo"].value = tuple(float(x) for x in lo)
        prog["u_hi"].value = tuple(float(x) for x in hi)
        prog["u_light"].value = tuple(float(x) for x in light)
        prog["u_steps"].value = steps
        prog["u_refine"].value = refine
        prog["u_eps"].value = float(0.5 * np.max(hi - lo) / res)
        prog["u_rdm"].value = 0
        prog["u_color"].value = 1
        rtex.use(0)
        ctex.use(1)
        prog["u_planar"].value = int(front is not None)
        prog["u_front"].value = 2
        ftex.use(2)
        if front is not None:
            right, up, _ = camera.axes()
            prog["u_right"].value = tuple(float(x) for x in right)
            prog["u_up"].value = tuple(float(x) for x in up)
            prog["u_front_px"].value = front_px
            prog["u_front_size"].value = (float(front.shape[1]), float(front.shape[0]))
            prog["u_front_scale"].value = front_scale
        vao.render(moderngl.TRIANGLES)
        raw = fbo.read(components=4, attachment=0)
        draw = fbo.read(components=4, attachment=1, dtype="f4")
    except moderngl.Error as exc:
        raise RenderError(f"OpenGL impostor render failed: {exc}") from None
    finally:
        ctx.cull_face = "back"
        ctx.enable_only(moderngl.NOTHING)
        for obj in reversed(objs):
            obj.release()
    rgba = np.frombuffer(raw, np.uint8).reshape(h, w, 4)[::-1].copy()
    dd = np.frombuffer(draw, np.float32).reshape(h, w, 4)[::-1]
    mask = dd[..., 1] > 0.5
    depth = np.where(mask, dd[..., 0], np.float32(np.inf)).astype(np.float32)
    rgba[~mask] = 0
    return RenderResult(color=rgba, mask=mask, depth=depth, camera=camera)
