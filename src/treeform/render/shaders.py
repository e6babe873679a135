"""GLSL sources of the renderer's passes: shading (lights, shadows, normal maps) and mask/ids.

:func:`_source` prefixes a fragment body with the ``#define`` switches of one material variant
(alpha mode, texture, flat-normal fallback, normal map, shadows, depth pre-pass); the programs
are compiled and cached per variant by :mod:`treeform.render.gpu`.
"""

from __future__ import annotations

# Instances (forests): each instance is (x, y, z, scale) and (yaw, count); a model point p is
# drawn at yaw_rotate(p * scale, yaw) + (x, y, z): turned about +Y, then moved (Y up, metres).
# ``count`` is for passes that draw a prefix of their points per instance (billboard clouds).
YAW_GLSL = """
vec3 yaw_rotate(vec3 v, float yaw) {
    float c = cos(yaw), s = sin(yaw);
    return vec3(c * v.x + s * v.z, v.y, -s * v.x + c * v.z);
}
"""
INSTANCE_FORMAT = ("4f 2f/i", "in_inst", "in_extra")
"""moderngl buffer format and attribute names of the per-instance data, 24 bytes an instance."""

# One vertex shader for both passes (``MASK_PASS`` picks the outputs): the depth pre-pass and the
# shading pass then compute gl_Position from the same source, bit for bit. ``INSTANCED`` draws
# the part once per instance (:data:`INSTANCE_FORMAT`).
_VERTEX_BODY = YAW_GLSL + """
uniform mat4 u_view;
uniform mat4 u_proj;
#if INSTANCED
in vec4 in_inst;
in vec2 in_extra;
#endif
in vec3 in_pos;
in vec3 in_nrm;
in vec2 in_uv;
in vec4 in_col;
out vec3 v_nrm;
out vec2 v_uv;
out float v_depth;
#if MASK_PASS
out float v_alpha;
#else
out vec3 v_pos;
out vec4 v_col;
#endif
invariant gl_Position;  // the depth pre-pass and the shading pass must agree bit for bit
void main() {
#if INSTANCED
    vec3 pos = yaw_rotate(in_pos * in_inst.w, in_extra.x) + in_inst.xyz;
    vec3 nrm = yaw_rotate(in_nrm, in_extra.x);
#else
    vec3 pos = in_pos;
    vec3 nrm = in_nrm;
#endif
    vec4 eye = u_view * vec4(pos, 1.0);
    v_nrm = nrm;
    v_uv = in_uv;
    v_depth = -eye.z;
#if MASK_PASS
    v_alpha = in_col.a;
#else
    v_pos = pos;
    v_col = in_col;
#endif
    gl_Position = u_proj * eye;
}
"""


def _vertex(mask: bool, instanced: bool) -> str:
    return f"#version 330\n#define MASK_PASS {int(mask)}\n#define INSTANCED {int(instanced)}\n" + _VERTEX_BODY

# Fragment shaders are compiled per variant (alpha mode, texture or not, flat-normal fallback,
# normal map, shadows) so that OPAQUE parts have no ``discard`` (llvmpipe then tests depth
# before shading). ALPHA_MODE: 0 OPAQUE, 1 MASK, 2 BLEND.
# Outputs: 0 colour (premultiplied); 1 ids = (view depth, part + 1, triangle + 1, 1);
# 2 world normal (facing the viewer on double-sided back faces); 3 uv.
_FRAGMENT = """
uniform vec4 u_base_color;
uniform sampler2D u_tex;
uniform sampler2D u_ntex;
uniform float u_nscale;
uniform float u_cutoff;
uniform int u_double_sided;
uniform float u_part;
uniform int u_n_lights;
uniform vec3 u_light_dirs[8];
uniform vec3 u_light_cols[8];
uniform vec3 u_sky;
uniform vec3 u_ground;
uniform vec3 u_eye;
uniform float u_specular;
uniform float u_shininess;
uniform int u_unlit;
#if SHADOWS
uniform sampler2DShadow u_shadow_map;
uniform mat4 u_light_vp;
uniform float u_shadow;
uniform float u_shadow_texel;
uniform float u_shadow_offset;
#endif
in vec3 v_pos;
in vec3 v_nrm;
in vec2 v_uv;
in vec4 v_col;
in float v_depth;
layout(location = 0) out vec4 f_color;
layout(location = 1) out vec4 f_ids;
layout(location = 2) out vec4 f_normal;
layout(location = 3) out vec4 f_uv;

#if SHADOWS
float light_visibility(vec3 p, vec3 n) {
    vec4 q = u_light_vp * vec4(p + n * u_shadow_offset, 1.0);
    vec3 c = q.xyz / q.w * 0.5 + 0.5;
    if (any(lessThan(c, vec3(0.0))) || any(greaterThan(c, vec3(1.0)))) return 1.0;
    float lit = 0.0;
    for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx)
            lit += texture(u_shadow_map, vec3(c.xy + vec2(dx, dy) * u_shadow_texel, c.z));
    return 1.0 - u_shadow * (1.0 - lit / 9.0);
}
#endif

void main() {
    // derivatives first: before any discard, in uniform control flow
    vec3 dpx = dFdx(v_pos);
    vec3 dpy = dFdy(v_pos);
#if HAS_NTEX
    vec2 duvx = dFdx(v_uv);
    vec2 duvy = dFdy(v_uv);
#endif
    vec4 albedo = u_base_color * v_col;
#if HAS_TEX
    albedo *= texture(u_tex, v_uv);
#endif
#if ALPHA_MODE == 1 && !PREPASSED
    if (albedo.a < u_cutoff) discard;
#elif ALPHA_MODE == 2
    if (albedo.a < 0.001953125) discard;
#endif
    float len = length(v_nrm);
    vec3 n;
#if FLAT_FALLBACK
    if (len > 1e-12) {
        n = v_nrm / len;
        if (u_double_sided != 0 && !gl_FrontFacing) n = -n;
    } else {
        vec3 flat_n = cross(dpx, dpy);  // faces the viewer
        float fl = length(flat_n);
        n = fl > 0.0 ? flat_n / fl : vec3(0.0, 1.0, 0.0);
    }
#else
    n = v_nrm / max(len, 1e-30);
    if (u_double_sided != 0 && !gl_FrontFacing) n = -n;
#endif
    vec3 geo_n = n;
#if HAS_NTEX
    // cotangent frame from screen-space derivatives (no stored tangents); glTF's v grows
    // downwards, so the map's +Y (up in the texture) is -dp/dv
    vec3 tn = texture(u_ntex, v_uv).xyz * 2.0 - 1.0;
    tn.xy *= u_nscale;
    vec3 dp2perp = cross(dpy, n);
    vec3 dp1perp = cross(n, dpx);
    vec3 T = dp2perp * duvx.x + dp1perp * duvy.x;
    vec3 B = dp2perp * duvx.y + dp1perp * duvy.y;
    float tb = max(dot(T, T), dot(B, B));
    if (tb > 1e-30) {
        float inv = inversesqrt(tb);
        vec3 m = T * inv * tn.x - B * inv * tn.y + n * max(tn.z, 0.0);
        float ml = length(m);
        if (ml > 1e-12) n = m / ml;
    }
#endif
    vec3 view_dir = normalize(u_eye - v_pos);
    vec3 ambient = mix(u_ground, u_sky, 0.5 + 0.5 * n.y);
    vec3 diffuse = vec3(0.0);
    vec3 spec = vec3(0.0);
    for (int i = 0; i < 8; ++i) {
        if (i >= u_n_lights) break;
        vec3 l = u_light_dirs[i];
        float ndl = max(dot(n, l), 0.0);
        float vis = 1.0;
#if SHADOWS
        if (i == 0) vis = light_visibility(v_pos, geo_n);
#endif
        diffuse += u_light_cols[i] * (ndl * vis);
        if (u_specular > 0.0 && ndl > 0.0) {  // normalised Blinn-Phong
            vec3 h = normalize(l + view_dir);
            float s = pow(max(dot(n, h), 0.0), u_shininess) * (u_shininess + 8.0) / 25.13274;
            spec += u_light_cols[i] * (s * ndl * vis);
        }
    }
    // KHR_materials_unlit: the colour is the albedo, its light baked in
    vec3 rgb = u_unlit != 0 ? clamp(albedo.rgb, 0.0, 1.0)
                            : clamp(albedo.rgb * (ambient + diffuse) + u_specular * spec, 0.0, 1.0);
#if ALPHA_MODE == 2
    float a = clamp(albedo.a, 0.0, 1.0);
#else
    float a = 1.0;
#endif
    f_color = vec4(rgb * a, a);  // premultiplied
    f_ids = vec4(v_depth, u_part + 1.0, float(gl_PrimitiveID) + 1.0, 1.0);
    f_normal = vec4(geo_n, 1.0);
    f_uv = vec4(v_uv, 0.0, 1.0);
}
"""

_FRAGMENT_MASK = """
uniform vec4 u_base_color;
uniform sampler2D u_tex;
uniform float u_cutoff;
uniform int u_double_sided;
uniform float u_part;
in vec3 v_nrm;
in vec2 v_uv;
in float v_alpha;
in float v_depth;
layout(location = 0) out vec4 f_ids;
layout(location = 1) out vec4 f_normal;
layout(location = 2) out vec4 f_uv;
void main() {
#if ALPHA_MODE != 0
    float a = u_base_color.a * v_alpha;
#if HAS_TEX
    a *= texture(u_tex, v_uv).a;
#endif
#if ALPHA_MODE == 1
    if (a < u_cutoff) discard;
#else
    if (a < 0.001953125) discard;
#endif
#endif
    vec3 n = v_nrm / max(length(v_nrm), 1e-30);
    if (u_double_sided != 0 && !gl_FrontFacing) n = -n;
    f_ids = vec4(v_depth, u_part + 1.0, float(gl_PrimitiveID) + 1.0, 1.0);
    f_normal = vec4(n, 1.0);
    f_uv = vec4(v_uv, 0.0, 1.0);
}
"""


def _source(body: str, alpha_mode: int, has_tex: bool, flat: bool, has_ntex: bool = False,
            shadows: bool = False, prepassed: bool = False) -> str:
    return (f"#version 330\n#define ALPHA_MODE {alpha_mode}\n#define HAS_TEX {int(has_tex)}\n"
            f"#define FLAT_FALLBACK {int(flat)}\n#define HAS_NTEX {int(has_ntex)}\n"
            f"#define SHADOWS {int(shadows)}\n#define PREPASSED {int(prepassed)}\n" + body)


_ALPHA_MODES = {"OPAQUE": 0, "MASK": 1, "BLEND": 2}
_LAYOUT = (  # interleaved, 48 bytes a vertex
    ("in_pos", 3), ("in_nrm", 3), ("in_uv", 2), ("in_col", 4))
