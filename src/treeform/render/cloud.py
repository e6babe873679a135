"""Clipped billboard clouds (seed 001 §4.2): leaflet billboards on a tree's branch points.

For trees near the camera the crown is drawn as camera-facing billboards of a leaflet cluster
(``treeform leaflets``, seed 001 §3.6), centred on points of the
tree's branching structure. One vertex buffer of points is shared by every instance of a
species; each instance draws the first ``count`` of them (its row's last column, 16 to 144 by
screen size in the forest, :mod:`treeform.render.instances`), and a geometry shader turns each
point into a quad. The points are ordered so that every prefix is spread over the crown, and
fewer billboards are drawn larger (edge ``size * sqrt(P / count)``) so the crown stays about
as dense.

Per fragment (seed 001 Fig. 12-13):

* alpha test on the leaflet's RGBA (coverage-preserving mip levels);
* **per-leaf clipping**: the centroid channel gives the centre of the leaf the pixel belongs
  to; that point, placed on the quad, is tested against the radial distance map (one cubemap
  lookup) and the whole leaf is discarded when it lies outside the crown, so the crown keeps
  the species' shape without cutting leaves in half;
* shading with the stored normal (billboard frame: x right, y up, z toward the viewer),
  ambient occlusion, and a small specular term on leaves only (the type bit);
* depth: the stored depth channel moves each fragment toward or away from the viewer within
  the cluster, so crossing billboards interleave instead of cutting along a straight line;
* colour: the leaflet's own, or (``tint``) the tree's colour cubemap in the leaf's direction
  modulated by the leaflet's brightness, so near and far trees share their colours.
"""

from __future__ import annotations

import numpy as np

from treeform._shared.checks import check_array
from treeform._shared.errors import InputError, RenderError
from treeform.render.context import get_context
from treeform.render.gpu import GLResources, _mat_bytes, _set, coverage_mipmaps
from treeform.render.impostor import _check_lighting, _light_uniforms
from treeform.render.instances import check_instances
from treeform.render.shaders import INSTANCE_FORMAT, YAW_GLSL
from treeform.structures.camera import Camera

__all__ = ["CloudPass", "MIN_BILLBOARDS", "MAX_BILLBOARDS", "WEB_VS", "billboard_count", "leaflet_textures"]

MIN_BILLBOARDS, MAX_BILLBOARDS = 16, 144
"""Billboards per tree instance (seed 001 §5.1: 16 to 144 by screen-projected area)."""

# what a billboard's corner hands the fragment shader (from the geometry shader here, from WEB_VS in a browser)
_BILLBOARD_OUT = """
out vec2 f_uv;
flat out vec3 f_center;
flat out vec3 f_right;
flat out vec3 f_up;
flat out vec4 f_inst;
flat out float f_yaw;
flat out float f_size;
"""

_VS = "#version 330\n" + YAW_GLSL + """
uniform float u_size;      // billboard edge (tree frame, metres) with all the points drawn
uniform float u_full;      // number of points
in vec3 in_point;          // a billboard centre, the tree's own frame
in vec4 in_inst;           // x, y, z, scale
in vec2 in_extra;          // yaw, count
out float g_keep;
out vec4 g_inst;
out float g_yaw;
out float g_size;
out float g_roll;
void main() {
    float count = max(in_extra.y, 1.0);
    g_keep = float(gl_VertexID) < count ? 1.0 : 0.0;
    g_inst = in_inst;
    g_yaw = in_extra.x;
    g_size = u_size * in_inst.w * sqrt(u_full / min(count, u_full));
    g_roll = fract(sin(float(gl_VertexID) * 12.9898 + 4.1414) * 43758.5453) * 6.2831853;
    gl_Position = vec4(yaw_rotate(in_point * in_inst.w, in_extra.x) + in_inst.xyz, 1.0);
}
"""

_GS = """
#version 330
layout(points) in;
layout(triangle_strip, max_vertices = 4) out;
uniform mat4 u_view;
uniform mat4 u_proj;
uniform vec3 u_cam_right;
uniform vec3 u_cam_up;
in float g_keep[];
in vec4 g_inst[];
in float g_yaw[];
in float g_size[];
in float g_roll[];
""" + _BILLBOARD_OUT + """
void main() {
    if (g_keep[0] < 0.5) return;
    vec3 c = gl_in[0].gl_Position.xyz;
    float cr = cos(g_roll[0]), sr = sin(g_roll[0]);
    vec3 r = cr * u_cam_right + sr * u_cam_up;
    vec3 u = -sr * u_cam_right + cr * u_cam_up;
    float h = 0.5 * g_size[0];
    for (int k = 0; k < 4; k++) {
        float sx = (k & 1) == 0 ? -1.0 : 1.0;
        float sy = k < 2 ? -1.0 : 1.0;
        gl_Position = u_proj * u_view * vec4(c + h * (sx * r + sy * u), 1.0);
        f_uv = vec2(0.5 + 0.5 * sx, 0.5 - 0.5 * sy);  // texture row 0 (v = 0) at the top
        f_center = c;
        f_right = r;
        f_up = u;
        f_inst = g_inst[0];
        f_yaw = g_yaw[0];
        f_size = g_size[0];
        EmitVertex();
    }
    EndPrimitive();
}
"""

_FS = "#version 330\n" + YAW_GLSL + """
uniform mat4 u_view;
uniform mat4 u_proj;
uniform sampler2D u_rgba;    // leaflet colour, straight alpha
uniform sampler2D u_shade;   // rgb: (n + 1) / 2, a: ambient occlusion
uniform sampler2D u_geo;     // rg: leaf centroid (x / W, y / H), b: type (1 leaf, 0.5 branch), a: depth (0 near)
uniform samplerCube u_rdm;
uniform samplerCube u_color;
uniform vec3 u_center;       // the RDM's centre (tree frame)
uniform vec3 u_eye;
uniform vec3 u_light;        // toward the key light (world), and the Lighting's colours
uniform vec3 u_key;
uniform vec3 u_sky;
uniform vec3 u_ground;
uniform int u_clip;          // 0 none, 1 per leaf (centroid), 2 per fragment
uniform int u_tint;
uniform float u_leaf_luma;   // the leaflet's mean brightness over its leaves
uniform float u_ao;          // how much the stored ambient occlusion darkens the ambient light (0..1)
uniform float u_cutoff;
uniform float u_id;
in vec2 f_uv;
flat in vec3 f_center;
flat in vec3 f_right;
flat in vec3 f_up;
flat in vec4 f_inst;
flat in float f_yaw;
flat in float f_size;
layout(location = 0) out vec4 f_color;
layout(location = 1) out vec4 f_ids;

vec3 to_crown(vec3 w) {  // a world point -> its offset from the crown centre in the tree's frame
    return yaw_rotate((w - f_inst.xyz) / f_inst.w, -f_yaw) - u_center;
}

void main() {
    vec4 c = texture(u_rgba, f_uv);
    if (c.a < u_cutoff) discard;
    vec4 geo = texture(u_geo, f_uv);
    vec3 toward = normalize(u_eye - f_center);
    vec3 here = f_center + f_size * ((f_uv.x - 0.5) * f_right + (0.5 - f_uv.y) * f_up);
    vec3 leaf = u_clip == 2 ? here : f_center + f_size * ((geo.r - 0.5) * f_right + (0.5 - geo.g) * f_up);
    vec3 d = to_crown(leaf);
    if (u_clip != 0 && length(d) > texture(u_rdm, d).r) discard;
    vec4 sh = texture(u_shade, f_uv);
    vec3 nb = sh.rgb * 2.0 - 1.0;
    vec3 n = normalize(nb.x * f_right + nb.y * f_up + nb.z * toward + 1e-6);
    bool is_leaf = geo.b > 0.75;
    vec3 albedo = c.rgb;
    if (u_tint == 1 && is_leaf) {
        float luma = dot(c.rgb, vec3(0.299, 0.587, 0.114));
        albedo = texture(u_color, d).rgb * clamp(luma / max(u_leaf_luma, 1e-3), 0.5, 1.6);
    }
    vec3 l = normalize(u_light);
    float ndl = max(dot(n, l), 0.0);
    // lit as the mesh renderer lights: hemisphere ambient (occluded by the stored AO) + key light
    vec3 rgb = albedo * (mix(u_ground, u_sky, 0.5 + 0.5 * n.y) * mix(1.0, sh.a, u_ao) + u_key * ndl);
    if (is_leaf && ndl > 0.0) {  // leaves shine a little, bark does not (the type bit, seed 001 §4.2)
        vec3 h = normalize(l + toward);
        rgb += vec3(0.06) * pow(max(dot(n, h), 0.0), 24.0);
    }
    f_color = vec4(clamp(rgb, 0.0, 1.0), 1.0);
    // depth within the cluster: the stored depth over the cluster's bounding sphere (about the quad's edge)
    vec3 p = here + toward * ((0.5 - geo.a) * 0.5 * f_size);
    vec4 view = u_view * vec4(p, 1.0);
    vec4 clip = u_proj * view;
    gl_FragDepth = 0.5 * clip.z / clip.w + 0.5;
    f_ids = vec4(-view.z, u_id, 0.0, 1.0);
}
"""

# WebGL 2 has no geometry shader: the browser twin of _VS + _GS draws one instanced quad per
# billboard (its centre, edge and roll computed by the page), with the same outputs for _FS.
WEB_VS = """#version 330
uniform mat4 u_view;
uniform mat4 u_proj;
in vec2 in_corner;   // (+-1, +-1)
in vec4 in_bb;       // the billboard's centre (world) and edge
in vec4 in_inst;     // its tree: x, y, z, scale
in vec2 in_extra;    // its tree's yaw, the billboard's roll
""" + _BILLBOARD_OUT + """
void main() {
    vec3 cr = vec3(u_view[0][0], u_view[1][0], u_view[2][0]);  // the camera's right and up (world)
    vec3 cu = vec3(u_view[0][1], u_view[1][1], u_view[2][1]);
    float c = cos(in_extra.y), s = sin(in_extra.y);
    vec3 r = c * cr + s * cu;
    vec3 u = -s * cr + c * cu;
    f_uv = vec2(0.5 + 0.5 * in_corner.x, 0.5 - 0.5 * in_corner.y);
    f_center = in_bb.xyz;
    f_right = r;
    f_up = u;
    f_inst = in_inst;
    f_yaw = in_extra.x;
    f_size = in_bb.w;
    gl_Position = u_proj * u_view * vec4(in_bb.xyz + 0.5 * in_bb.w * (in_corner.x * r + in_corner.y * u), 1.0);
}
"""

_CLIP_MODES = {"none": 0, "leaf": 1, "fragment": 2}


def leaflet_textures(leaflets) -> tuple:
    """A leaflet billboard's channels packed as the cloud's shaders read them.

    Returns
    -------
    rgba, shade, geo : ndarray, shape (S, S, 4), uint8
        Colour; ``(n + 1) / 2`` and ambient occlusion; leaf centroid (R, G), type (B) and depth
        (A, 0 near, 8 bits).
    leaf_luma : float
        Mean brightness of the leaf texels (what the cubemap tint is relative to).
    """
    rgba = np.ascontiguousarray(leaflets.rgba, np.uint8)
    ao = leaflets.ao if leaflets.ao.ndim == 2 else leaflets.ao[..., 0]
    shade = np.ascontiguousarray(np.dstack([leaflets.normal[..., :3], ao]), np.uint8)
    depth = leaflets.depth.astype(np.float64) * (255.0 / 65535.0 if leaflets.depth.dtype == np.uint16 else 1.0)
    kind = leaflets.type if leaflets.type.ndim == 2 else leaflets.type[..., 0]
    geo = np.ascontiguousarray(np.dstack([leaflets.centroid[..., :2], kind, np.clip(np.rint(depth), 0, 255)]), np.uint8)
    leaf = (geo[..., 2] == 255) & (rgba[..., 3] >= 128)
    luma = rgba[..., :3].astype(np.float64) @ [0.299, 0.587, 0.114] / 255.0
    return rgba, shade, geo, float(luma[leaf].mean()) if leaf.any() else 0.5


def billboard_count(diameter_px, *, full_px: float = 400.0) -> np.ndarray:
    """Billboards for a crown ``diameter_px`` wide on screen: by projected area, 16 to 144.

    A crown ``full_px`` wide or more gets :data:`MAX_BILLBOARDS`.

    Examples
    --------
    >>> billboard_count([10, 200, 400, 900]).tolist()
    [16, 36, 144, 144]
    """
    d = np.asarray(diameter_px, np.float64)
    n = np.rint(MAX_BILLBOARDS * (d / float(full_px)) ** 2)
    return np.clip(n, MIN_BILLBOARDS, MAX_BILLBOARDS).astype(np.int64)


class CloudPass(GLResources):
    """The clipped billboard cloud of one tree, drawn for many instances in one draw call.

    A pass of :meth:`treeform.render.Renderer.render_scene` (set :attr:`instances`, rows
    ``(x, y, z, scale, yaw, count)``), like :class:`~treeform.render.impostor.ReliefPass`.

    Parameters
    ----------
    rdm : RadialDistanceMap
        The crown volume the billboards are clipped to (tree frame).
    points : array_like, shape (P, 3)
        Billboard centres on the branching structure (tree frame), every prefix well spread.
    size : float
        Billboard edge in metres when all P are drawn.
    leaflets : LeafletBillboard
        The RGBA texture and its channels (normal, centroid, ao, depth, type).
    color : ndarray, shape (6, F, F, 3), uint8, optional
        The tree's colour cubemap; with ``tint`` the leaves take its colour.
    clip : {'leaf', 'fragment', 'none'}
        Discard by the leaf's centroid (the paper's choice), by each fragment, or not at all.
    lighting : Lighting, optional
        As the mesh renderer's (default ``Lighting()``).
    ao : float in [0, 1]
        How much the stored ambient occlusion darkens the ambient light. The mesh renderer has
        no occlusion: at 1 the clouds of the sample, an oak and a pine come out 26-31 % darker
        than their meshes, at 0 within 6 %; 0.3 keeps some depth in the clusters and stays
        within about 10 % (what a switch from mesh to cloud shows).
    part_id : int
    """

    name = "cloud"

    def __init__(self, rdm, points, size: float, leaflets, *, color: np.ndarray | None = None, tint: bool = True,
                 clip: str = "leaf", lighting=None, ao: float = 0.3, cutoff: float = 0.5, part_id: int = 0):
        import moderngl

        from treeform.structures import RadialDistanceMap

        if not isinstance(rdm, RadialDistanceMap):
            raise InputError(f"rdm: expected a RadialDistanceMap, got {type(rdm).__name__}")
        pts = check_array(points, "points", shape=(None, 3), min_size=3).astype(np.float32)
        if not float(size) > 0:
            raise InputError(f"size: expected > 0 metres, got {size!r}")
        if clip not in _CLIP_MODES:
            raise InputError(f"clip: expected one of {sorted(_CLIP_MODES)}, got {clip!r}")
        if color is None:
            color = np.broadcast_to(np.array([60, 110, 45], np.uint8), (6, 4, 4, 3))
        color = np.ascontiguousarray(color, np.uint8)
        if color.ndim != 4 or color.shape[0] != 6 or color.shape[1] != color.shape[2] or color.shape[3] != 3:
            raise InputError(f"color: expected (6, F, F, 3) uint8 faces, got {color.shape}")
        rgba, shade, geo, self.leaf_luma = leaflet_textures(leaflets)
        h, w = rgba.shape[:2]
        self.rdm, self.points, self.size = rdm, pts, float(size)
        self.tint, self.clip, self.cutoff = bool(tint), _CLIP_MODES[clip], float(cutoff)
        if not 0.0 <= float(ao) <= 1.0:
            raise InputError(f"ao: expected a number in [0, 1], got {ao!r}")
        self.ao = float(ao)
        self.lighting = _check_lighting(lighting)
        self.part_id = int(part_id)
        self.instances = np.zeros((0, 6), np.float32)
        self.ctx = ctx = get_context()
        res = rdm.resolution
        self._objs = []
        try:
            self.prog = ctx.program(vertex_shader=_VS, geometry_shader=_GS, fragment_shader=_FS)
            self._objs.append(self.prog)
            self.tex_rgba = ctx.texture((w, h), 4, data=rgba.tobytes())
            for level, img in enumerate(coverage_mipmaps(rgba, cutoff)[1:], start=1):
                if level == 1:
                    self.tex_rgba.build_mipmaps()
                self.tex_rgba.write(img.tobytes(), level=level)
            self.tex_rgba.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
            self.tex_shade = ctx.texture((w, h), 4, data=shade.tobytes())
            self.tex_shade.build_mipmaps()
            self.tex_shade.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
            self.tex_geo = ctx.texture((w, h), 4, data=geo.tobytes())
            self.tex_geo.filter = (moderngl.NEAREST, moderngl.NEAREST)  # centroids are never blended
            self.tex_rdm = ctx.texture_cube((res, res), 1, data=np.ascontiguousarray(rdm.radii, np.float32).tobytes(),
                                            dtype="f4")
            self.tex_rdm.filter = (moderngl.NEAREST, moderngl.NEAREST)
            self.tex_color = ctx.texture_cube((color.shape[1], color.shape[1]), 3, data=color.tobytes())
            self.tex_color.filter = (moderngl.LINEAR, moderngl.LINEAR)
            for t in (self.tex_rgba, self.tex_shade, self.tex_geo):
                t.repeat_x = t.repeat_y = False
            self.vbo = ctx.buffer(pts.tobytes())
            self._objs += [self.tex_rgba, self.tex_shade, self.tex_geo, self.tex_rdm, self.tex_color, self.vbo]
        except moderngl.Error as exc:
            self.release()
            raise RenderError(f"OpenGL billboard cloud set-up failed: {exc}") from None

    @property
    def n_points(self) -> int:
        return len(self.points)

    def __call__(self, ctx, camera: Camera) -> None:
        import moderngl

        inst = check_instances(self.instances).copy()
        if not len(inst):
            return
        inst[:, 5] = np.clip(np.where(inst[:, 5] > 0, inst[:, 5], self.n_points), 1, self.n_points)
        prog = self.prog
        ibuf = ctx.buffer(inst.tobytes())
        vao = ctx.vertex_array(prog, [(self.vbo, "3f", "in_point"), (ibuf, *INSTANCE_FORMAT)])
        try:
            right, up, _ = camera.axes()
            _set(prog, "u_view", _mat_bytes(camera.view_matrix()))
            _set(prog, "u_proj", _mat_bytes(camera.projection_matrix()))
            for name, value in (("u_cam_right", right), ("u_cam_up", up), ("u_eye", camera.position),
                                ("u_center", self.rdm.center), *_light_uniforms(self.lighting, camera)):
                _set(prog, name, tuple(float(x) for x in value))
            for name, value in (("u_size", self.size), ("u_full", float(self.n_points)), ("u_leaf_luma", self.leaf_luma),
                                ("u_cutoff", self.cutoff), ("u_id", float(self.part_id + 1)), ("u_ao", self.ao)):
                _set(prog, name, float(value))
            _set(prog, "u_clip", self.clip)
            _set(prog, "u_tint", int(self.tint))
            for unit, (name, tex) in enumerate((("u_rgba", self.tex_rgba), ("u_shade", self.tex_shade),
                                                 ("u_geo", self.tex_geo), ("u_rdm", self.tex_rdm),
                                                 ("u_color", self.tex_color))):
                _set(prog, name, unit)
                tex.use(unit)
            vao.render(moderngl.POINTS, vertices=self.n_points, instances=len(inst))
        finally:
            vao.release()
            ibuf.release()

