"""Direct rendering of a radial distance map by relief mapping in world space (seed 001 §4.1).

The crown is drawn as its RDM's bounding box; each fragment marches the view ray through the
box (a linear search of ``steps`` samples, then ``refine`` bisections) until the ray enters the
crown (``|p - c| <= R(p - c)``), takes its colour from the colour cubemap along the same
direction, lights it with the normal of the RDM's surface (central differences of
``|p - c| - R(p - c)``) and writes that point's depth, so impostors and meshes occlude each
other correctly. Fragments whose ray misses the crown are discarded: the silhouette from any
direction is the RDM's.

A crown is porous, and the RDM (the farthest surface in each direction) fills its gaps: from
afar the mesh shows sky through the crown where the relief shows a solid envelope. Given the
tree's :class:`~treeform.structures.OpacityGrid` (the leaves' and wood's extinction per voxel,
:func:`treeform.geometry.opacity_grid`), the ray instead marches that grid accumulating optical
depth (Beer-Lambert) and hits where half its light is blocked (depth ln 2), or is discarded
where the tree lets more through; colour and normal come from the cubemaps along the hit's
direction as before. The grid's capsules (the trunk and thickest limbs, which a grid of its voxel
would fade) are hit exactly where they lie in front of that point, lit by their own normal and
coloured with the bark's albedo.

:class:`ReliefPass` draws any number of instances of one tree in one draw call (the box is
turned and scaled per instance; each fragment marches in the tree's own frame), as a pass of
:meth:`treeform.render.Renderer.render_scene`; :func:`render_rdm_impostor` draws one.
"""

from __future__ import annotations

import numpy as np

from treeform._shared.checks import check_int
from treeform._shared.errors import InputError, RenderError
from treeform.render.context import get_context
from treeform.render.gpu import GLResources, _mat_bytes, _set
from treeform.render.instances import check_instances
from treeform.render.result import RenderResult
from treeform.render.shaders import YAW_GLSL
from treeform.structures.camera import Camera
from treeform.structures.opacity import MAX_WOOD

WOOD_GROUP = 8  # capsules the relief shader skips at once by their bounding sphere (wood_uniforms)

__all__ = ["ReliefPass", "relief_bounds", "relief_box", "render_rdm_impostor", "wood_uniforms"]

_VS = "#version 330\n" + YAW_GLSL + """
uniform mat4 u_view;
uniform mat4 u_proj;
in vec3 in_pos;     // a corner of the RDM's box, the tree's own frame
in vec4 in_inst;    // x, y, z, scale
in vec2 in_extra;   // yaw, (count: unused)
out vec3 v_local;
flat out vec4 v_inst;
flat out float v_yaw;
void main() {
    v_local = in_pos;
    v_inst = in_inst;
    v_yaw = in_extra.x;
    gl_Position = u_proj * u_view * vec4(yaw_rotate(in_pos * in_inst.w, in_extra.x) + in_inst.xyz, 1.0);
}
"""

_FS = "#version 330\n" + f"#define MAX_WOOD {MAX_WOOD}\n#define WOOD_GROUP {WOOD_GROUP}\n" + YAW_GLSL + """
uniform samplerCube u_rdm;
uniform samplerCube u_color;
uniform mat4 u_view;
uniform mat4 u_proj;
uniform vec3 u_eye;
uniform vec3 u_center;
uniform vec3 u_lo;
uniform vec3 u_hi;
uniform float u_rmax;       // the RDM's largest and smallest radius: every ray meets its surface between
uniform float u_rmin;       // the sphere of the one and the sphere of the other
uniform vec3 u_light;       // toward the key light (world), and the Lighting's colours
uniform vec3 u_key;
uniform vec3 u_sky;
uniform vec3 u_ground;
uniform int u_steps;
uniform int u_refine;
uniform float u_eps;
uniform float u_id;         // written to the id buffer (part + 1)
uniform int u_planar;       // 1: colour from the front view as a billboard facing the camera (distant trees)
uniform sampler2D u_front;  // the front view, RGBA (alpha: the tree)
uniform vec3 u_right;       // the camera's right and up axes (world)
uniform vec3 u_up;
uniform vec2 u_front_px;    // the crown centre's pixel in the front view
uniform vec2 u_front_size;  // the front view's size in pixels
uniform float u_front_scale;  // its pixels per metre at the crown centre
uniform sampler3D u_opacity;  // extinction coefficient (1/m) per voxel (OpacityGrid), when u_use_opacity is 1
uniform int u_use_opacity;
uniform vec3 u_olo;         // the opacity cube's lowest corner and edge (the tree's frame)
uniform float u_oext;
uniform float u_ovox;       // its voxel's edge
uniform int u_osteps;
uniform int u_nwood;        // the opacity grid's capsules (wood_uniforms): a (xyz, radius), b (xyz), in groups
uniform vec4 u_wa[MAX_WOOD];  // of WOOD_GROUP neighbours, each group's bounding sphere in u_wg
uniform vec4 u_wb[MAX_WOOD];
uniform vec4 u_wg[MAX_WOOD / WOOD_GROUP];
uniform vec3 u_bark;        // their albedo
in vec3 v_local;
flat in vec4 v_inst;
flat in float v_yaw;
layout(location = 0) out vec4 f_color;
layout(location = 1) out vec4 f_depth;

float inside(vec3 p) {  // <= 0 inside the crown (p in the tree's frame)
    vec3 d = p - u_center;
    return length(d) - texture(u_rdm, d).r;
}

float rdm_march(vec3 eye, vec3 dir, float t0, float t1) {  // the first hit on the RDM's surface in [t0, t1], or -1
    // empty-space skipping: the surface lies between the spheres of radius u_rmax and u_rmin about the
    // centre, so a ray that misses the outer one is done, and one that meets the inner one has hit by then
    vec3 oc = eye - u_center;
    float bq = dot(oc, dir), cq = dot(oc, oc);
    float outer = bq * bq - cq + u_rmax * u_rmax;
    if (outer <= 0.0) return -1.0;
    float so = sqrt(outer);
    t0 = max(t0, -bq - so);
    t1 = min(t1, -bq + so);
    float inner = bq * bq - cq + u_rmin * u_rmin;
    if (inner > 0.0) t1 = min(t1, max(-bq - sqrt(inner), t0) + 1e-3 * u_rmin);
    if (t1 <= t0) return -1.0;
    float dt = (t1 - t0) / float(u_steps);
    float prev = t0;
    float hit = -1.0;
    for (int i = 0; i <= u_steps; i++) {  // linear search
        float t = t0 + dt * float(i);
        if (inside(eye + dir * t) <= 0.0) { hit = t; break; }
        prev = t;
    }
    if (hit < 0.0) return -1.0;
    float a = prev;
    float b = hit;
    for (int i = 0; i < u_refine; i++) {  // binary refinement between the last miss and the hit
        float m = 0.5 * (a + b);
        if (inside(eye + dir * m) <= 0.0) b = m; else a = m;
    }
    return b;
}

float opacity_march(vec3 eye, vec3 dir, vec3 inv) {  // where the ray has lost half its light, or -1
    // through a porous crown: Beer-Lambert along the ray through the opacity cube (midpoint rule); the
    // tree is hit where half the light is blocked (optical depth ln 2), between two samples by linear
    // interpolation; a ray that keeps more than half its light sees through the tree
    vec3 oa = (u_olo - eye) * inv, ob = (u_olo + vec3(u_oext) - eye) * inv;
    vec3 omin = min(oa, ob), omax = max(oa, ob);
    float s0 = max(max(max(omin.x, omin.y), omin.z), 0.0);
    float s1 = min(min(omax.x, omax.y), omax.z);
    // only inside the sphere that holds the tree (the RDM's largest radius, a voxel to spare for the
    // grid's linear filter): the cube's corners are empty, and a ray that misses the sphere is done
    vec3 oc = eye - u_center;
    float bq = dot(oc, dir), cq = dot(oc, oc);
    float rs = u_rmax + 1.75 * u_ovox;
    float outer = bq * bq - cq + rs * rs;
    if (outer <= 0.0) return -1.0;
    float so = sqrt(outer);
    s0 = max(s0, -bq - so);
    s1 = min(s1, -bq + so);
    if (s1 <= s0) return -1.0;
    float ds = (s1 - s0) / float(u_osteps);
    float tau = 0.0;
    for (int i = 0; i < u_osteps; i++) {
        float t = s0 + ds * (float(i) + 0.5);
        float s = texture(u_opacity, (eye + dir * t - u_olo) / u_oext).r * ds;
        if (tau + s >= 0.69314718) return s0 + ds * (float(i) + (0.69314718 - tau) / max(s, 1e-12));
        tau += s;
    }
    return -1.0;
}

float capsule_hit(vec3 ro, vec3 rd, vec3 a, vec3 b, float r) {  // where the ray enters the capsule, or -1
    // (structures/opacity.py capsule_hit): the side of the cylinder about a-b, then the sphere at the
    // end that hit went past; solved from the ray's point nearest the capsule's middle (a far eye's
    // large terms would cancel in single precision)
    float tm = dot(0.5 * (a + b) - ro, rd);
    vec3 ba = b - a, oa = ro + rd * tm - a;
    float L2 = dot(ba, ba), bd = dot(ba, rd), bo = dot(ba, oa);
    float qa = L2 - bd * bd, qb = L2 * dot(rd, oa) - bo * bd, qc = L2 * dot(oa, oa) - bo * bo - r * r * L2;
    float h = qb * qb - qa * qc;
    if (h < 0.0) return -1.0;
    float y = -bd;  // (along the axis: the end the ray comes to first)
    if (qa > 1e-9 * L2) {
        float t = (-qb - sqrt(h)) / qa;
        y = bo + t * bd;
        if (y > 0.0 && y < L2) return tm + t > 0.0 ? tm + t : -1.0;
    }
    vec3 oc = oa - (y <= 0.0 ? vec3(0.0) : ba);
    float sb = dot(rd, oc), sc = dot(oc, oc) - r * r;
    float sh = sb * sb - sc;
    if (sh < 0.0) return -1.0;
    float ts = tm - sb - sqrt(sh);
    return ts > 0.0 ? ts : -1.0;
}

float wood_hit(vec3 eye, vec3 dir, float tmax, out vec3 n) {  // the first capsule along the ray nearer than
    // tmax (< 0: no bound), or -1; n its normal. A group's capsules are tested only when the ray meets the
    // group's bounding sphere in front of the nearest hit so far. The skip is a loop's count, not an if: a CPU
    // rasterizer (llvmpipe) runs both sides of an if under a mask, but leaves a loop no lane enters
    float best = tmax;
    int k = -1;
    for (int g = 0; g < MAX_WOOD / WOOD_GROUP; g++) {
        if (g * WOOD_GROUP >= u_nwood) break;
        vec3 oc = u_wg[g].xyz - eye;
        float tg = dot(oc, dir), rg = u_wg[g].w;
        bool meets = dot(oc, oc) - tg * tg <= rg * rg && tg + rg > 0.0 && (best <= 0.0 || tg - rg < best);
        int m = meets ? WOOD_GROUP : 0;
        for (int j = 0; j < m; j++) {
            int i = g * WOOD_GROUP + j;
            float t = capsule_hit(eye, dir, u_wa[i].xyz, u_wb[i].xyz, u_wa[i].w);
            if (t > 0.0 && (best <= 0.0 || t < best)) { best = t; k = i; }
        }
    }
    if (k < 0) best = -1.0;
    n = vec3(0.0, 1.0, 0.0);
    if (k >= 0) {
        vec3 a = u_wa[k].xyz, ba = u_wb[k].xyz - a, p = eye + dir * best;
        float f = clamp(dot(p - a, ba) / max(dot(ba, ba), 1e-12), 0.0, 1.0);
        n = normalize(p - (a + f * ba) + 1e-9);
    }
    return best;
}

void main() {
    // the ray in the tree's own frame (turned back, unscaled): the march is the same for every instance
    vec3 eye = yaw_rotate((u_eye - v_inst.xyz) / v_inst.w, -v_yaw);
    vec3 dir = normalize(v_local - eye);
    // the ray's span inside the box (slabs): from the eye (or the box's near side) to its far side
    vec3 inv = 1.0 / dir;
    vec3 ta = (u_lo - eye) * inv, tb = (u_hi - eye) * inv;
    vec3 tmin = min(ta, tb), tmax = max(ta, tb);
    float t0 = max(max(max(tmin.x, tmin.y), tmin.z), 0.0);
    float t1 = min(min(tmax.x, tmax.y), tmax.z);
    float b;
    vec3 wn;
    float tw = -1.0;
    if (u_use_opacity == 1) {
        b = opacity_march(eye, dir, inv);
        tw = wood_hit(eye, dir, b, wn);  // only a capsule in front of the crown's ln 2 point
        if (tw > 0.0) b = tw;
        if (b < 0.0) discard;
    } else {
        b = rdm_march(eye, dir, t0, t1);
        if (b < 0.0) discard;
    }
    vec3 p = eye + dir * b;
    vec3 e = vec3(u_eps, 0.0, 0.0);
    vec3 n = normalize(vec3(inside(p + e.xyy) - inside(p - e.xyy), inside(p + e.yxy) - inside(p - e.yxy),
                            inside(p + e.yyx) - inside(p - e.yyx)) + 1e-9);
    vec3 albedo = texture(u_color, p - u_center).rgb;
    if (tw > 0.0) {  // the trunk or a limb
        n = wn;
        albedo = u_bark;
    } else if (u_planar == 1) {  // seed 001 §4.1, second option: the same billboard texture from every direction
        vec3 q = p - u_center;
        vec2 px = u_front_px + u_front_scale * vec2(dot(q, yaw_rotate(u_right, -v_yaw)),
                                                    -dot(q, yaw_rotate(u_up, -v_yaw)));
        vec4 f = texture(u_front, px / u_front_size);
        if (f.a > 0.5) albedo = f.rgb;
    }
    vec3 nw = yaw_rotate(n, v_yaw);  // lit as the mesh renderer lights: hemisphere ambient + key light
    vec3 lit = mix(u_ground, u_sky, 0.5 + 0.5 * nw.y) + u_key * max(dot(nw, normalize(u_light)), 0.0);
    f_color = vec4(clamp(albedo * lit, 0.0, 1.0), 1.0);
    vec4 view = u_view * vec4(yaw_rotate(p * v_inst.w, v_yaw) + v_inst.xyz, 1.0);
    vec4 clip = u_proj * view;
    gl_FragDepth = 0.5 * clip.z / clip.w + 0.5;
    f_depth = vec4(-view.z, u_id, 0.0, 1.0);
}
"""

def wood_uniforms(opacity) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """The grid's capsules as the shader's uniforms ``(u_wa, u_wb, u_wg, u_nwood)``.

    The capsules are split into groups of at most :data:`WOOD_GROUP` neighbours (halving the set
    along the widest spread of their middles until each part is small enough); each group fills
    :data:`WOOD_GROUP` rows, short ones repeating their first capsule (the same hit twice), and
    its bounding sphere lets the shader skip all of them at once.

    Returns
    -------
    wa, wb : ndarray, shape (MAX_WOOD, 4), float32
        ``(a, radius)`` and ``(b, 0)`` per row; unused rows zero.
    wg : ndarray, shape (MAX_WOOD // WOOD_GROUP, 4), float32
        Each group's sphere ``(centre, radius)``, holding its capsules (a thousandth to spare).
    n : int
        Rows in use, a multiple of :data:`WOOD_GROUP`.

    Examples
    --------
    >>> from treeform.structures.opacity import OpacityGrid
    >>> g = OpacityGrid(np.zeros((4, 4, 4), np.float32), np.zeros(3), 1.0,
    ...                 wood=np.array([[0, 0, 0, 0, 0.6, 0, 0.05]], np.float32))
    >>> wa, wb, wg, n = wood_uniforms(g)
    >>> wa.shape, wg.shape, n, [round(float(x), 3) for x in wg[0]]
    ((32, 4), (4, 4), 8, [0.0, 0.3, 0.0, 0.35])
    """
    w = np.asarray(opacity.wood, np.float64).reshape(-1, 7)
    wa = np.zeros((MAX_WOOD, 4), np.float32)
    wb = np.zeros((MAX_WOOD, 4), np.float32)
    wg = np.zeros((MAX_WOOD // WOOD_GROUP, 4), np.float32)
    mid = 0.5 * (w[:, :3] + w[:, 3:6])
    reach = 0.5 * np.linalg.norm(w[:, 3:6] - w[:, :3], axis=1) + w[:, 6]  # each capsule's own sphere

    def split(idx):
        if len(idx) <= WOOD_GROUP:
            return [idx]
        axis = int(np.argmax(np.ptp(mid[idx], axis=0)))
        idx = idx[np.argsort(mid[idx, axis], kind="stable")]
        return split(idx[:len(idx) // 2]) + split(idx[len(idx) // 2:])

    groups = split(np.arange(len(w))) if len(w) else []
    for g, idx in enumerate(groups):
        lo, hi = (mid[idx] - reach[idx, None]).min(0), (mid[idx] + reach[idx, None]).max(0)
        c = 0.5 * (lo + hi)
        wg[g, :3], wg[g, 3] = c, np.max(np.linalg.norm(mid[idx] - c, axis=1) + reach[idx]) * 1.001
        rows = np.concatenate([idx, np.repeat(idx[:1], WOOD_GROUP - len(idx))])
        r = slice(g * WOOD_GROUP, (g + 1) * WOOD_GROUP)
        wa[r, :3], wa[r, 3], wb[r, :3] = w[rows, :3], w[rows, 6], w[rows, 3:6]
    return wa, wb, wg, WOOD_GROUP * len(groups)


def relief_bounds(rdm) -> tuple:
    """What the relief march of ``rdm`` is bounded by: ``(lo, hi, rmin, rmax)``.

    ``lo`` / ``hi`` (3,) are the crown's box, padded by 0.1 % (the geometry drawn); ``rmin`` /
    ``rmax`` the radii of the spheres about the centre that lie inside / around the crown
    surface (the RDM's smallest and largest radius, a hair inside / outside), between which
    every ray meets it: the shaders skip the empty space outside them.
    """
    lo, hi = rdm.bounds()
    pad = 1e-3 * max(float(np.max(hi - lo)), 1e-6)
    radii = np.asarray(rdm.radii, np.float64)
    return lo - pad, hi + pad, float(max(radii.min(), 0.0)) * 0.999, float(radii.max()) * (1 + 1e-4) + 1e-6


def relief_box(rdm, opacity=None) -> tuple:
    """The box a relief impostor is drawn as: :func:`relief_bounds`' box, grown to hold the opacity
    cube when there is one (the RDM's median can trim a leaf the grid keeps). ``(lo, hi)``, (3,) each."""
    lo, hi, _, _ = relief_bounds(rdm)
    if opacity is not None:
        olo, ohi = opacity.bounds()
        lo, hi = np.minimum(lo, olo), np.maximum(hi, ohi)
    return lo, hi


_BOX = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                 [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]], np.uint32)


def _check_lighting(lighting):
    from treeform.render.lighting import Lighting

    if lighting is None:
        return Lighting()
    if not isinstance(lighting, Lighting):
        raise InputError(f"lighting: expected a Lighting, got {type(lighting).__name__}")
    return lighting


def _light_uniforms(lighting, camera: Camera) -> tuple:
    """(name, vec3) pairs of the key light's world direction and the Lighting's colours."""
    return (("u_light", lighting.world_direction(camera)), ("u_key", lighting.key), ("u_sky", lighting.sky),
            ("u_ground", lighting.ground))


class ReliefPass(GLResources):
    """The relief-mapped RDM of one tree, drawn for many instances in one draw call.

    A pass of :meth:`treeform.render.Renderer.render_scene`: set :attr:`instances` (rows
    ``(x, y, z, scale, yaw, count)``, :mod:`treeform.render.instances`), then the renderer calls
    the pass. GPU textures live until :meth:`release`.

    Parameters
    ----------
    rdm : RadialDistanceMap
        In the tree's own frame.
    color, steps, refine, lighting, planar, opacity, opacity_steps :
        As :func:`render_rdm_impostor`.
    part_id : int
        Reported as the part index of the impostor's pixels (:attr:`RenderResult.part`).
    """

    name = "relief"

    def __init__(self, rdm, *, color: np.ndarray | None = None, steps: int = 64, refine: int = 6,
                 lighting=None, planar: dict | None = None, part_id: int = 0, opacity=None,
                 opacity_steps: int | None = None):
        import moderngl

        from treeform.structures import OpacityGrid, RadialDistanceMap

        if not isinstance(rdm, RadialDistanceMap):
            raise InputError(f"rdm: expected a RadialDistanceMap, got {type(rdm).__name__}")
        if opacity is not None and not isinstance(opacity, OpacityGrid):
            raise InputError(f"opacity: expected an OpacityGrid or None, got {type(opacity).__name__}")
        self.opacity = opacity
        self.opacity_steps = 0 if opacity is None else check_int(
            2 * opacity.resolution if opacity_steps is None else opacity_steps, "opacity_steps", 4, 4096)
        self._wood = None if opacity is None else wood_uniforms(opacity)  # grouped once, drawn every frame
        self.steps = check_int(steps, "steps", 4, 4096)
        self.refine = check_int(refine, "refine", 0, 32)
        if color is None:
            color = np.broadcast_to(np.array([60, 110, 45], np.uint8), (6, 4, 4, 3))
        color = np.ascontiguousarray(color, np.uint8)
        front = None
        if planar is not None:
            try:
                front = np.ascontiguousarray(planar["image"], np.uint8)
                self._front_px = tuple(float(x) for x in planar["center_px"])
                self._front_scale = float(planar["pixels_per_metre"])
            except (KeyError, TypeError, ValueError):
                raise InputError("planar: expected {'image', 'center_px', 'pixels_per_metre'}") from None
            if front.ndim != 3 or front.shape[2] != 4 or len(self._front_px) != 2 or not self._front_scale > 0:
                raise InputError(f"planar: expected an (H, W, 4) uint8 image, a (u, v) pixel and a scale > 0, "
                                 f"got {front.shape}, {self._front_px}, {self._front_scale}")
        if color.ndim != 4 or color.shape[0] != 6 or color.shape[1] != color.shape[2] or color.shape[3] != 3:
            raise InputError(f"color: expected (6, F, F, 3) uint8 faces, got {color.shape}")
        self.rdm = rdm
        self.lighting = _check_lighting(lighting)
        self.part_id = int(part_id)
        self.front = front
        self.instances = np.zeros((0, 6), np.float32)
        _, _, self._rmin, self._rmax = relief_bounds(rdm)
        self.lo, self.hi = relief_box(rdm, opacity)
        corners = np.array([[x, y, z] for x in (self.lo[0], self.hi[0]) for y in (self.lo[1], self.hi[1])
                            for z in (self.lo[2], self.hi[2])], np.float32)
        self.ctx = ctx = get_context()
        res = rdm.resolution
        self._objs = []
        try:
            self.prog = ctx.program(vertex_shader=_VS, fragment_shader=_FS)
            self._objs.append(self.prog)
            self.rtex = ctx.texture_cube((res, res), 1, data=np.ascontiguousarray(rdm.radii, np.float32).tobytes(),
                                         dtype="f4")
            self.rtex.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self.ctex = ctx.texture_cube((color.shape[1], color.shape[1]), 3, data=color.tobytes())
            self.ctex.filter = (moderngl.LINEAR, moderngl.LINEAR)
            self._objs += [self.rtex, self.ctex]
            # (a 1x1 stand-in without a front view: a sampler2D and the RDM's samplerCube may not share a unit)
            fimg = front if front is not None else np.zeros((1, 1, 4), np.uint8)
            self.ftex = ctx.texture((fimg.shape[1], fimg.shape[0]), 4, data=fimg.tobytes())
            self.ftex.filter = (moderngl.LINEAR, moderngl.LINEAR)
            self.ftex.repeat_x = self.ftex.repeat_y = False
            # (a 1x1x1 stand-in without an opacity grid, for the same reason)
            sig = opacity.sigma if opacity is not None else np.zeros((1, 1, 1), np.float32)
            # (half floats: 2 bytes a voxel, linearly filtered everywhere; an extinction needs 3 digits)
            self.otex = ctx.texture3d(sig.shape[::-1], 1, data=np.ascontiguousarray(sig, np.float16).tobytes(),
                                      dtype="f2")
            self.otex.filter = (moderngl.LINEAR, moderngl.LINEAR)
            self.otex.repeat_x = self.otex.repeat_y = self.otex.repeat_z = False
            self.vbo = ctx.buffer(corners.tobytes())
            self.ibo = ctx.buffer(_BOX.tobytes())
            self._objs += [self.ftex, self.otex, self.vbo, self.ibo]
        except moderngl.Error as exc:
            self.release()
            raise RenderError(f"OpenGL impostor set-up failed: {exc}") from None

    def __call__(self, ctx, camera: Camera) -> None:
        import moderngl

        from treeform.render.shaders import INSTANCE_FORMAT

        inst = check_instances(self.instances)
        if not len(inst):
            return
        prog = self.prog
        ibuf = ctx.buffer(inst.tobytes())
        vao = ctx.vertex_array(prog, [(self.vbo, "3f", "in_pos"), (ibuf, *INSTANCE_FORMAT)],
                               index_buffer=self.ibo, index_element_size=4)
        try:
            ctx.enable(moderngl.CULL_FACE)
            ctx.cull_face = "front"  # the box's far faces: every ray through the box gets a fragment, eye inside or not
            _set(prog, "u_view", _mat_bytes(camera.view_matrix()))
            _set(prog, "u_proj", _mat_bytes(camera.projection_matrix()))
            for name, value in (("u_eye", camera.position), ("u_center", self.rdm.center), ("u_lo", self.lo),
                                ("u_hi", self.hi), *_light_uniforms(self.lighting, camera)):
                _set(prog, name, tuple(float(x) for x in value))
            _set(prog, "u_rmax", self._rmax)
            _set(prog, "u_rmin", self._rmin)
            _set(prog, "u_steps", self.steps)
            _set(prog, "u_refine", self.refine)
            _set(prog, "u_eps", float(0.5 * np.max(self.hi - self.lo) / self.rdm.resolution))
            _set(prog, "u_id", float(self.part_id + 1))
            _set(prog, "u_rdm", 0)
            _set(prog, "u_color", 1)
            _set(prog, "u_front", 2)
            _set(prog, "u_opacity", 3)
            self.rtex.use(0)
            self.ctex.use(1)
            self.ftex.use(2)
            self.otex.use(3)
            _set(prog, "u_use_opacity", int(self.opacity is not None))
            if self.opacity is not None:
                _set(prog, "u_olo", tuple(float(x) for x in self.opacity.origin))
                _set(prog, "u_oext", float(self.opacity.extent))
                _set(prog, "u_ovox", float(self.opacity.voxel))
                _set(prog, "u_osteps", self.opacity_steps)
                _set(prog, "u_bark", tuple(float(x) for x in self.opacity.bark))
                wa, wb, wg, nwood = self._wood
                _set(prog, "u_nwood", nwood)
                _set(prog, "u_wa", wa.tobytes())
                _set(prog, "u_wb", wb.tobytes())
                _set(prog, "u_wg", wg.tobytes())
            _set(prog, "u_planar", int(self.front is not None))
            if self.front is not None:
                right, up, _ = camera.axes()
                _set(prog, "u_right", tuple(float(x) for x in right))
                _set(prog, "u_up", tuple(float(x) for x in up))
                _set(prog, "u_front_px", self._front_px)
                _set(prog, "u_front_size", (float(self.front.shape[1]), float(self.front.shape[0])))
                _set(prog, "u_front_scale", self._front_scale)
            vao.render(moderngl.TRIANGLES, instances=len(inst))
        finally:
            ctx.cull_face = "back"
            ctx.disable(moderngl.CULL_FACE)
            vao.release()
            ibuf.release()



def render_rdm_impostor(rdm, camera: Camera, *, color: np.ndarray | None = None, steps: int = 64, refine: int = 6,
                        lighting=None, planar: dict | None = None, instances=None, opacity=None,
                        opacity_steps: int | None = None) -> RenderResult:
    """Draw a radial distance map as a relief-mapped impostor from ``camera``.

    Parameters
    ----------
    rdm : RadialDistanceMap
    camera : Camera
    color : ndarray, shape (6, F, F, 3), uint8, optional
        The colour cubemap (e.g. :func:`treeform.crown.color_cubemap.color_cubemap`), faces in
        the RDM's order and orientation; default a flat green.
    steps, refine : int
        Samples of the linear search along the part of the ray that can meet the crown (inside
        its box, from where it enters the sphere of the largest radius to where it enters that
        of the smallest, :func:`relief_bounds`), then bisections.
    lighting : Lighting, optional
        Hemisphere ambient plus the key light, as the mesh renderer lights meshes (default
        ``Lighting()``, the renderer's default), with the RDM's normal.
    planar : dict, optional
        The paper's second colour option, for distant trees: the front view used as a
        billboard that faces the camera (sharper than the cubemap, but the same picture from
        every side). ``{"image": (H, W, 4) uint8 with alpha = the tree, "center_px": (u, v),
        the crown centre's pixel in it, "pixels_per_metre": scale at the crown centre}`` (what
        ``treeform impostor`` records in ``impostor.json`` as ``front``).
        Pixels where the billboard shows no tree keep the cubemap's colour; the silhouette is
        the RDM's either way.
    instances : array_like, shape (N, 6), optional
        Placements (:mod:`treeform.render.instances`); default one, where the RDM is.
    opacity : OpacityGrid, optional
        The tree's extinction per voxel (:func:`treeform.geometry.opacity_grid`, in the RDM's
        frame): the ray then hits the tree where it has lost half its light (Beer-Lambert), so a
        porous crown's gaps stay open and the silhouette is the mesh's as seen from afar, not
        the RDM's; the colour and the normal still come from the cubemaps along the hit's
        direction. Without it the hit is the RDM's surface (seed 001 §4.1 as published).
    opacity_steps : int, optional
        Samples of that march through the opacity cube (default twice its resolution).

    Returns
    -------
    RenderResult
        ``color`` RGBA (alpha 255 on the crown), ``mask``, ``depth`` (metres along the view
        axis, inf off the crown), ``camera``.
    """
    from treeform.render.renderer import Renderer

    if not isinstance(camera, Camera):
        raise InputError(f"camera: expected a treeform Camera, got {type(camera).__name__}")
    relief = ReliefPass(rdm, color=color, steps=steps, refine=refine, lighting=lighting, planar=planar,
                        opacity=opacity, opacity_steps=opacity_steps)
    renderer = Renderer(camera, samples=1, background=(0.0, 0.0, 0.0, 0.0))
    try:
        relief.instances = [[0, 0, 0, 1, 0, 0]] if instances is None else instances
        return renderer.render_scene([], passes=[relief])
    finally:
        renderer.release()
        relief.release()
