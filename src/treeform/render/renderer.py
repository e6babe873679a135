"""Rasterize a :class:`~treeform.structures.mesh.Mesh` seen by a :class:`~treeform.structures.camera.Camera`.

One :meth:`Renderer.render` call gives a lit RGBA preview, the silhouette mask and the depth
along the view axis, all with row 0 at the top of the image and pixel centres at +0.5, i.e.
exactly the pixel grid of :meth:`Camera.project`.

Passes
------
* **colour** – multisampled (``samples``) when ``samples > 1``: Lambert key light plus
  hemisphere ambient; albedo = ``material.base_color * texture(uv) * vertex colour``.
* **mask / depth** – always single-sample, so MSAA never blurs the silhouette. When
  ``samples <= 1`` the colour, mask and depth come from one pass (multiple render targets).

Conventions
-----------
* Textures and vertex colours are treated as display colours and multiplied (no sRGB decode).
* UVs follow glTF: ``(0, 0)`` is the first row (top-left) of the ``(H, W, 4)`` texture array.
* Front faces are counter-clockwise (glTF). Single-sided materials cull back faces;
  double-sided ones draw both sides and flip the normal on back faces.
* ``MASK`` materials discard fragments with alpha < ``alpha_cutoff``; ``BLEND`` materials are
  alpha-blended in the colour pass (after the opaque parts, depth writes on, no sorting) and
  count as covered in the mask where their alpha is above 1/512.
* A vertex with a zero normal is shaded with the flat face normal (facing the viewer).
"""

from __future__ import annotations

import weakref
from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np

from treeform._shared.checks import check_choice
from treeform._shared.errors import InputError, RenderError
from treeform.render.context import get_context
from treeform.structures.camera import Camera
from treeform.structures.mesh import Mesh, MeshPart

__all__ = ["Lighting", "RenderResult", "Renderer", "render_views", "view_camera", "to_uint8_rgb", "clear_cache"]

# --------------------------------------------------------------------------------------------
# shaders

_VERTEX = """
#version 330
uniform mat4 u_view;
uniform mat4 u_proj;
in vec3 in_pos;
in vec3 in_nrm;
in vec2 in_uv;
in vec4 in_col;
out vec3 v_pos;
out vec3 v_nrm;
out vec2 v_uv;
out vec4 v_col;
out float v_depth;
invariant gl_Position;  // the depth pre-pass and the shading pass must agree bit for bit
void main() {
    vec4 eye = u_view * vec4(in_pos, 1.0);
    v_pos = in_pos;
    v_nrm = in_nrm;
    v_uv = in_uv;
    v_col = in_col;
    v_depth = -eye.z;
    gl_Position = u_proj * eye;
}
"""

_VERTEX_MASK = """
#version 330
uniform mat4 u_view;
uniform mat4 u_proj;
in vec3 in_pos;
in vec3 in_nrm;
in vec2 in_uv;
in vec4 in_col;
out vec3 v_nrm;
out vec2 v_uv;
out float v_alpha;
out float v_depth;
invariant gl_Position;
void main() {
    vec4 eye = u_view * vec4(in_pos, 1.0);
    v_nrm = in_nrm;
    v_uv = in_uv;
    v_alpha = in_col.a;
    v_depth = -eye.z;
    gl_Position = u_proj * eye;
}
"""

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
    vec3 rgb = clamp(albedo.rgb * (ambient + diffuse) + u_specular * spec, 0.0, 1.0);
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
_MAX_CACHED_PARTS = 64
_MAX_CACHED_TEXTURES = 64


# --------------------------------------------------------------------------------------------
# GPU state shared by every Renderer (programs, mesh and texture caches)


class _State:
    """Programs and caches that live in one moderngl context."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.programs: dict[tuple, object] = {}
        self.white = ctx.texture((1, 1), 4, data=b"\xff\xff\xff\xff")
        self.parts: OrderedDict[int, _PartGPU] = OrderedDict()
        self.textures: OrderedDict[int, tuple] = OrderedDict()
        self.shadow = None

    def program(self, pass_: str, alpha_mode: int, has_tex: bool, flat: bool, has_ntex: bool = False,
                shadows: bool = False, prepassed: bool = False):
        """The (cached) program for one pass ("shade" or "mask") and material variant.

        ``prepassed``: the shading pass of a MASK part whose depth a pre-pass already wrote
        (depth test "==": no alpha test, so the rasterizer tests depth before shading).
        """
        if pass_ == "mask":
            flat = has_ntex = shadows = prepassed = False
            has_tex = has_tex and alpha_mode != 0
        prepassed = bool(prepassed) and alpha_mode == 1
        key = (pass_, alpha_mode, bool(has_tex), bool(flat), bool(has_ntex), bool(shadows), prepassed)
        prog = self.programs.get(key)
        if prog is None:
            vs, fs = (_VERTEX, _FRAGMENT) if pass_ == "shade" else (_VERTEX_MASK, _FRAGMENT_MASK)
            try:
                prog = self.ctx.program(vertex_shader=vs, fragment_shader=_source(fs, *key[1:]))
            except Exception as exc:  # moderngl.Error: compile/link failure
                raise RenderError(f"OpenGL shader compilation failed: {exc}") from None
            self.programs[key] = prog
        return key, prog

    def shadow_target(self, size: int):
        """The (cached) depth texture and framebuffer of the key light's shadow map."""
        if self.shadow is None or self.shadow[0].size != (size, size):
            if self.shadow is not None:
                self.shadow[1].release()
                self.shadow[0].release()
            tex = self.ctx.depth_texture((size, size))
            tex.compare_func = "<="
            tex.repeat_x = tex.repeat_y = False
            import moderngl

            tex.filter = (moderngl.LINEAR, moderngl.LINEAR)
            self.shadow = (tex, self.ctx.framebuffer(depth_attachment=tex))
        return self.shadow

    def release(self):
        clear_cache()
        for obj in self.programs.values():
            obj.release()
        self.programs.clear()
        if self.shadow is not None:
            self.shadow[1].release()
            self.shadow[0].release()
            self.shadow = None
        self.white.release()


_state: _State | None = None


def _get_state() -> _State:
    global _state
    ctx = get_context()
    if _state is None or _state.ctx is not ctx:
        _state = _State(ctx)
    return _state


def _clear_gpu_state() -> None:
    global _state
    if _state is not None:
        try:
            _state.release()
        finally:
            _state = None


def clear_cache() -> None:
    """Release every cached vertex buffer and texture (compiled programs stay).

    The caches are keyed on the identity of a part's arrays; call this after editing a
    mesh's arrays *in place* (assigning new arrays is detected automatically).
    """
    if _state is not None:
        for entry in _state.parts.values():
            entry.release()
        for _ref, _key, tex in _state.textures.values():
            tex.release()
        _state.parts.clear()
        _state.textures.clear()


def _vao_format(program) -> tuple[str, list[str]]:
    """Buffer format for the interleaved layout, skipping attributes the program lacks."""
    fmt, names = [], []
    for name, n in _LAYOUT:
        try:
            program[name]
        except KeyError:
            fmt.append(f"{4 * n}x")
        else:
            fmt.append(f"{n}f")
            names.append(name)
    return " ".join(fmt), names


def _part_key(part: MeshPart) -> tuple:
    arrays = (part.positions, part.normals, part.uvs, part.colors, part.indices)
    return tuple((id(a), a.shape, a.__array_interface__["data"][0]) for a in arrays)


class _PartGPU:
    """Interleaved vertex buffer, index buffer and per-program vertex arrays of one part."""

    __slots__ = ("ref", "key", "vbo", "ibo", "flat", "vaos")

    def __init__(self, state: _State, part: MeshPart):
        ctx = state.ctx
        v = np.empty((part.n_vertices, 12), np.float32)
        v[:, 0:3] = part.positions
        v[:, 3:6] = part.normals
        v[:, 6:8] = part.uvs
        v[:, 8:12] = part.colors
        self.ref = weakref.ref(part)
        self.key = _part_key(part)
        # zero normals anywhere -> the shader variant that falls back to flat face normals
        self.flat = bool(part.n_vertices and np.einsum("ij,ij->i", part.normals, part.normals).min() < 1e-24)
        self.vbo = ctx.buffer(v.tobytes())
        self.ibo = ctx.buffer(np.ascontiguousarray(part.indices, np.uint32).tobytes())
        self.vaos: dict = {}

    def vao(self, ctx, key, program):
        vao = self.vaos.get(key)
        if vao is None:
            fmt, names = _vao_format(program)
            vao = ctx.vertex_array(program, [(self.vbo, fmt, *names)], index_buffer=self.ibo,
                                   index_element_size=4)
            self.vaos[key] = vao
        return vao

    def release(self):
        for obj in (*self.vaos.values(), self.vbo, self.ibo):
            obj.release()
        self.vaos.clear()


def _part_gpu(state: _State, part: MeshPart) -> _PartGPU:
    # drop entries whose part has been garbage-collected
    for k in [k for k, e in state.parts.items() if e.ref() is None]:
        state.parts.pop(k).release()
    entry = state.parts.get(id(part))
    if entry is not None and entry.ref() is part and entry.key == _part_key(part):
        state.parts.move_to_end(id(part))
        return entry
    if entry is not None:
        state.parts.pop(id(part)).release()
    entry = _PartGPU(state, part)
    state.parts[id(part)] = entry
    while len(state.parts) > _MAX_CACHED_PARTS:
        state.parts.popitem(last=False)[1].release()
    return entry


def _texture_gpu(state: _State, texture: np.ndarray | None):
    if texture is None:
        return state.white
    for k in [k for k, (ref, _key, _tex) in state.textures.items() if ref() is None]:
        state.textures.pop(k)[2].release()
    key = (texture.shape, texture.__array_interface__["data"][0])
    entry = state.textures.get(id(texture))
    if entry is not None and entry[0]() is texture and entry[1] == key:
        state.textures.move_to_end(id(texture))
        return entry[2]
    if entry is not None:
        state.textures.pop(id(texture))[2].release()
    h, w = texture.shape[:2]
    tex = state.ctx.texture((w, h), 4, data=np.ascontiguousarray(texture, np.uint8).tobytes())
    tex.build_mipmaps()
    import moderngl

    tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
    tex.repeat_x = tex.repeat_y = True
    state.textures[id(texture)] = (weakref.ref(texture), key, tex)
    while len(state.textures) > _MAX_CACHED_TEXTURES:
        state.textures.popitem(last=False)[1][2].release()
    return tex


# --------------------------------------------------------------------------------------------
# public API


MAX_LIGHTS = 8
"""Directional lights a :class:`Lighting` may hold (key light included)."""


def _vec3(value, name: str) -> tuple:
    try:
        v = tuple(float(x) for x in value)
    except (TypeError, ValueError):
        v = ()
    if len(v) != 3 or not all(np.isfinite(v)):
        raise InputError(f"{name}: expected 3 finite numbers, got {value!r}")
    return v


@dataclass(frozen=True)
class Lighting:
    """Directional lights plus hemisphere (sky / ground) ambient; Lambert + Blinn-Phong shading.

    Parameters
    ----------
    direction : sequence of 3 floats
        Direction *towards* the key light, in world coordinates (default upper-front-left:
        +Y up, +Z toward the photo's camera, -X left), or in camera coordinates
        (x right, y up, z toward the viewer) when ``camera_relative``.
    key : sequence of 3 floats
        Key light colour times intensity.
    sky, ground : sequence of 3 floats
        Ambient colour for normals pointing straight up / straight down (blended by ``n.y``).
    camera_relative : bool
        Interpret every light direction in the camera's frame, so every view is lit alike.
    lights : sequence of (direction, colour) pairs
        Further directional lights (at most ``MAX_LIGHTS - 1``), each two 3-vectors, in the
        same frame as ``direction`` (seed 003 §4.2.1: up to eight lights).
    shadow : float in [0, 1]
        Strength of the key light's shadows (0: none; 1: the key light is fully blocked):
        a ``shadow_resolution``² shadow map, alpha-tested like the mask, filtered 3x3 (PCF).
    shadow_resolution : int
        Edge of the square shadow map in texels.
    specular : float >= 0
        Weight of the normalised Blinn-Phong highlight; its exponent comes from each
        material's ``roughness`` (``2 / r**4 - 2``, as in Karis 2013).

    Notes
    -----
    ``Lighting(key=(0, 0, 0), sky=(1, 1, 1), ground=(1, 1, 1))`` renders unlit albedo.
    """

    direction: tuple = (-0.5, 0.75, 0.6)
    key: tuple = (0.62, 0.62, 0.58)
    sky: tuple = (0.45, 0.47, 0.52)
    ground: tuple = (0.22, 0.21, 0.19)
    camera_relative: bool = False
    lights: tuple = ()
    shadow: float = 0.0
    shadow_resolution: int = 1024
    specular: float = 0.0

    def __post_init__(self):
        for name in ("direction", "key", "sky", "ground"):
            object.__setattr__(self, name, _vec3(getattr(self, name), f"Lighting.{name}"))
        if not any(self.direction):
            raise InputError(f"Lighting.direction: expected a non-zero vector, got {self.direction!r}")
        try:
            pairs = [tuple(pair) for pair in self.lights]
        except TypeError:
            raise InputError(f"Lighting.lights: expected (direction, colour) pairs, got {self.lights!r}") from None
        if len(pairs) > MAX_LIGHTS - 1:
            raise InputError(f"Lighting.lights: at most {MAX_LIGHTS - 1} lights besides the key, got {len(pairs)}")
        lights = []
        for i, pair in enumerate(pairs):
            if len(pair) != 2:
                raise InputError(f"Lighting.lights[{i}]: expected a (direction, colour) pair, got {pair!r}")
            d = _vec3(pair[0], f"Lighting.lights[{i}] direction")
            if not any(d):
                raise InputError(f"Lighting.lights[{i}]: expected a non-zero direction, got {d!r}")
            lights.append((d, _vec3(pair[1], f"Lighting.lights[{i}] colour")))
        object.__setattr__(self, "lights", tuple(lights))
        if not (isinstance(self.shadow, (int, float)) and 0.0 <= float(self.shadow) <= 1.0):
            raise InputError(f"Lighting.shadow: expected a number in [0, 1], got {self.shadow!r}")
        if not (isinstance(self.specular, (int, float)) and 0.0 <= float(self.specular) < np.inf):
            raise InputError(f"Lighting.specular: expected a finite number >= 0, got {self.specular!r}")
        res = self.shadow_resolution
        if isinstance(res, bool) or not isinstance(res, (int, np.integer)) or not 16 <= res <= 8192:
            raise InputError(f"Lighting.shadow_resolution: expected an integer in [16, 8192], got {res!r}")

    def _to_world(self, d, camera: Camera) -> np.ndarray:
        d = np.asarray(d, np.float64)
        if self.camera_relative:
            r, u, f = camera.axes()
            d = d[0] * r + d[1] * u - d[2] * f
        return d / np.linalg.norm(d)

    def world_direction(self, camera: Camera) -> np.ndarray:
        """Unit vector (3,) towards the key light in world coordinates, for ``camera``."""
        return self._to_world(self.direction, camera)

    def world_lights(self, camera: Camera) -> tuple[np.ndarray, np.ndarray]:
        """Every light, key first: unit directions (L, 3) in world coordinates and colours (L, 3)."""
        dirs = [self.world_direction(camera)] + [self._to_world(d, camera) for d, _c in self.lights]
        cols = [self.key] + [c for _d, c in self.lights]
        return np.array(dirs), np.array(cols, np.float64)


@dataclass
class RenderResult:
    """What one render produced; every array has row 0 at the top of the image.

    Attributes
    ----------
    color : ndarray, shape (H, W, 4), uint8
        Display-referred RGBA, straight (not premultiplied) alpha; alpha 0 (and RGB = the
        background colour) where nothing was drawn and the background is transparent.
    mask : ndarray, shape (H, W), bool
        Silhouette: pixel centres covered by any geometry after the alpha test (no MSAA).
    depth : ndarray, shape (H, W), float32
        Distance along the camera's view axis in metres (as ``Camera.project(...)[:, 2]``);
        ``np.inf`` where ``mask`` is False.
    camera : Camera
        The camera the image was rendered with.
    part : ndarray, shape (H, W), int16
        Index into the rendered mesh's ``parts`` of the surface seen at each pixel centre
        (the same samples as ``mask``); -1 where ``mask`` is False. E.g. a label image is
        ``np.where(part >= 0, labels_of_parts[part], 0)``.
    triangle : ndarray, shape (H, W), int32
        Index of the triangle within that part (``gl_PrimitiveID``); -1 where empty.
    normal : ndarray, shape (H, W, 3), float32, or None
        World-space unit normal of the surface (flipped toward the viewer on the back of
        double-sided parts; without normal maps); zeros where empty. Only with ``aux=True``.
    uv : ndarray, shape (H, W, 2), float32, or None
        Interpolated texture coordinates; zeros where empty. Only with ``aux=True``.
    """

    color: np.ndarray
    mask: np.ndarray
    depth: np.ndarray
    camera: Camera | None = field(default=None, repr=False)
    part: np.ndarray | None = field(default=None, repr=False)
    triangle: np.ndarray | None = field(default=None, repr=False)
    normal: np.ndarray | None = field(default=None, repr=False)
    uv: np.ndarray | None = field(default=None, repr=False)

    def rgb(self, background=(255, 255, 255)) -> np.ndarray:
        """``color`` composited over ``background``: (H, W, 3) uint8."""
        return to_uint8_rgb(self.color, background)


def to_uint8_rgb(color: np.ndarray, background=(255, 255, 255)) -> np.ndarray:
    """Composite straight-alpha RGBA over an opaque background colour (for previews).

    Parameters
    ----------
    color : ndarray, shape (H, W, 4), uint8
        RGBA image, e.g. ``RenderResult.color``.
    background : sequence of 3 ints in [0, 255]
        Background RGB.

    Returns
    -------
    ndarray, shape (H, W, 3), uint8

    Examples
    --------
    >>> px = np.array([[[255, 0, 0, 255], [255, 0, 0, 0], [0, 0, 0, 128]]], np.uint8)
    >>> to_uint8_rgb(px, background=(0, 0, 255)).tolist()
    [[[255, 0, 0], [0, 0, 255], [0, 0, 127]]]
    """
    c = np.asarray(color)
    if c.ndim != 3 or c.shape[2] != 4:
        raise InputError(f"color: expected an (H, W, 4) RGBA array, got shape {c.shape}")
    if c.dtype != np.uint8:
        raise InputError(f"color: expected dtype uint8, got {c.dtype}")
    bg = np.asarray(background, np.float32).reshape(-1)
    if bg.shape != (3,) or not np.all((bg >= 0) & (bg <= 255)):
        raise InputError(f"background: expected 3 values in [0, 255], got {background!r}")
    a = c[..., 3:4].astype(np.float32) / 255.0
    out = c[..., :3].astype(np.float32) * a + bg * (1.0 - a)
    return np.clip(np.rint(out), 0, 255).astype(np.uint8)


def _as_mesh(mesh) -> Mesh:
    if isinstance(mesh, MeshPart):
        return Mesh([mesh])
    if not isinstance(mesh, Mesh):
        raise InputError(f"mesh: expected a treeform Mesh or MeshPart, got {type(mesh).__name__}")
    return mesh


def _check_rgba(value, name) -> tuple:
    try:
        v = tuple(float(x) for x in value)
    except (TypeError, ValueError):
        raise InputError(f"{name}: expected 4 floats in [0, 1], got {value!r}") from None
    if len(v) != 4 or not all(0.0 <= x <= 1.0 for x in v):
        raise InputError(f"{name}: expected 4 floats in [0, 1], got {value!r}")
    return v


def _mat_bytes(m: np.ndarray) -> bytes:
    return np.ascontiguousarray(np.asarray(m, np.float64).T, np.float32).tobytes()  # column-major


def _set(program, name, value):
    try:
        u = program[name]
    except KeyError:  # optimised away
        return
    if isinstance(value, bytes):
        u.write(value)
    else:
        u.value = value


class Renderer:
    """Headless rasterizer for one camera: lit previews, silhouette masks and depth maps.

    Parameters
    ----------
    camera : Camera
        Pinhole camera; its ``width`` x ``height`` is the image size.
    samples : int
        MSAA samples of the colour pass (clamped to the device maximum); ``<= 1`` renders
        colour, mask and depth in a single pass.
    background : sequence of 4 floats in [0, 1]
        RGBA drawn where no geometry is; alpha 0 (default) gives a transparent background.
    lighting : Lighting, optional
        Lights, shadows and ambient; ``Lighting()`` when omitted.
    aux : bool
        Also read back per-pixel world normals and UVs (:attr:`RenderResult.normal`,
        :attr:`RenderResult.uv`); part and triangle indices are always returned.

    Raises
    ------
    RenderError
        If no OpenGL context can be created.
    InputError
        For a bad argument.

    Notes
    -----
    Vertex buffers and textures are cached per part (shared by all renderers) and re-uploaded
    when a part's arrays are replaced; see :func:`clear_cache` for in-place edits. On Mesa
    llvmpipe (CPU) 4x MSAA costs about 3x a single-sample render for dense alpha-tested
    foliage (two passes, four samples a pixel): use ``samples=1`` where speed matters more
    than smooth edges. Masks and depths are identical for every ``samples``.

    Examples
    --------
    >>> cam = Camera(64, 48, 40.0, (0, 1, 5), (0, 1, 0))
    >>> r = Renderer(cam, samples=1)                                  # doctest: +SKIP
    >>> res = r.render(mesh)                                          # doctest: +SKIP
    >>> res.color.shape, res.mask.shape, res.depth.dtype              # doctest: +SKIP
    ((48, 64, 4), (48, 64), dtype('float32'))
    """

    def __init__(self, camera: Camera, *, samples: int = 4, background=(1.0, 1.0, 1.0, 0.0),
                 lighting: Lighting | None = None, aux: bool = False):
        try:
            samples = int(samples)
        except (TypeError, ValueError):
            raise InputError(f"samples: expected an integer, got {samples!r}") from None
        if samples < 0:
            raise InputError(f"samples: expected >= 0, got {samples}")
        self.background = _check_rgba(background, "background")
        if lighting is None:
            lighting = Lighting()
        if not isinstance(lighting, Lighting):
            raise InputError(f"lighting: expected a Lighting, got {type(lighting).__name__}")
        self.lighting = lighting
        self.aux = bool(aux)
        self._state = _get_state()
        ctx = self._state.ctx
        self.samples = 1 if samples <= 1 else int(min(samples, max(int(ctx.max_samples), 1)))
        self._targets = None
        self._size = None
        self.camera = camera

    # -- camera / framebuffers ---------------------------------------------------------
    @property
    def camera(self) -> Camera:
        return self._camera

    @camera.setter
    def camera(self, camera: Camera) -> None:
        if not isinstance(camera, Camera):
            raise InputError(f"camera: expected a treeform Camera, got {type(camera).__name__}")
        camera.validate()
        self._camera = camera
        size = (int(camera.width), int(camera.height))
        if size != self._size:
            self._release_targets()
            self._size = size

    def _make_targets(self) -> dict:
        ctx = self._state.ctx
        w, h = self._size
        limit = int(ctx.info.get("GL_MAX_RENDERBUFFER_SIZE", 8192))
        if w > limit or h > limit:
            raise InputError(f"camera: image size {w}x{h} exceeds the device limit {limit}")
        t = {}
        try:
            ids = ["dval"] + (["nrm", "uvs"] if self.aux else [])
            for name in ids:
                t[name] = ctx.renderbuffer((w, h), 4, dtype="f4")
            t["depth"] = ctx.depth_renderbuffer((w, h))
            if self.samples > 1:
                t["ms_color"] = ctx.renderbuffer((w, h), 4, samples=self.samples)
                t["ms_depth"] = ctx.depth_renderbuffer((w, h), samples=self.samples)
                t["color_fbo"] = ctx.framebuffer([t["ms_color"]], t["ms_depth"])
                t["resolved"] = ctx.renderbuffer((w, h), 4)
                t["resolve_fbo"] = ctx.framebuffer([t["resolved"]])
                t["mask_fbo"] = ctx.framebuffer([t[k] for k in ids], t["depth"])
            else:
                t["color"] = ctx.renderbuffer((w, h), 4)
                t["color_fbo"] = ctx.framebuffer([t["color"]] + [t[k] for k in ids], t["depth"])
                t["prepass_fbo"] = ctx.framebuffer([], t["depth"])
                t["dval_fbo"] = ctx.framebuffer([t[k] for k in ids])
        except Exception as exc:
            for obj in t.values():
                obj.release()
            raise RenderError(f"could not create {w}x{h} framebuffers ({self.samples} samples): {exc}") from None
        return t

    def _release_targets(self) -> None:
        if self._targets:
            # framebuffers first, then their attachments
            for k in sorted(self._targets, key=lambda k: not k.endswith("fbo")):
                self._targets[k].release()
        self._targets = None

    def release(self) -> None:
        """Free this renderer's framebuffers (cached meshes and programs are shared and stay)."""
        self._release_targets()

    # -- rendering ------------------------------------------------------------------------
    def render(self, mesh: Mesh) -> RenderResult:
        """Render ``mesh`` (or a single :class:`MeshPart`) from :attr:`camera`.

        Parameters
        ----------
        mesh : Mesh or MeshPart

        Returns
        -------
        RenderResult
            ``color`` (H, W, 4) uint8, ``mask`` (H, W) bool, ``depth`` (H, W) float32.
        """
        import moderngl

        mesh = _as_mesh(mesh)
        state = _get_state()
        if state is not self._state:  # context was re-created
            self._state = state
            self._targets = None
        ctx = state.ctx
        if self._targets is None:
            self._targets = self._make_targets()
        t = self._targets
        cam = self._camera
        w, h = self._size

        parts = [(i, p) for i, p in enumerate(mesh.parts) if p.n_triangles]
        for _i, p in parts:
            p.validate()
        parts.sort(key=lambda ip: ip[1].material.alpha_mode == "BLEND")  # stable: opaque first
        gpu = [(i, p, _part_gpu(state, p), _texture_gpu(state, p.material.texture),
                _texture_gpu(state, p.material.normal_texture) if p.material.normal_texture is not None else None)
               for i, p in parts]

        lt = self.lighting
        dirs, cols = lt.world_lights(cam)
        shadows = lt.shadow > 0 and lt.key != (0.0, 0.0, 0.0) and bool(gpu)
        shared = {
            "u_view": _mat_bytes(cam.view_matrix()),
            "u_proj": _mat_bytes(cam.projection_matrix()),
            "u_n_lights": len(dirs),
            "u_light_dirs": np.asarray(dirs, np.float32).tobytes() + bytes(12 * (MAX_LIGHTS - len(dirs))),
            "u_light_cols": np.asarray(cols, np.float32).tobytes() + bytes(12 * (MAX_LIGHTS - len(dirs))),
            "u_sky": tuple(float(x) for x in lt.sky),
            "u_ground": tuple(float(x) for x in lt.ground),
            "u_eye": tuple(float(x) for x in cam.position),
            "u_specular": float(lt.specular),
            "u_tex": 0,
            "u_ntex": 1,
        }
        if shadows:
            light_view, light_proj, texel = _light_matrices(mesh, dirs[0], lt.shadow_resolution)
            shared.update(u_shadow_map=2, u_light_vp=_mat_bytes(light_proj @ light_view), u_shadow=float(lt.shadow),
                          u_shadow_texel=1.0 / lt.shadow_resolution, u_shadow_offset=1.5 * texel)
        br, bgc, bb, ba = self.background
        ctx.front_face = "ccw"
        ctx.cull_face = "back"
        ctx.depth_func = "<"
        ctx.blend_equation = moderngl.FUNC_ADD
        ctx.blend_func = moderngl.ONE, moderngl.ONE_MINUS_SRC_ALPHA
        prepared: set = set()

        def draw(pass_: str, blend: bool, overrides: dict | None = None, only=None, prepassed: bool = False):
            for i, p, g, tex, ntex in gpu:
                m = p.material
                mode = _ALPHA_MODES[m.alpha_mode]
                if only is not None and (mode == 2) != (only == "blend"):
                    continue
                key, program = state.program(pass_, mode, m.texture is not None, g.flat, ntex is not None,
                                             shadows, prepassed)
                if overrides is not None:  # shadow pass: the light's matrices, not cached as prepared
                    for name, value in overrides.items():
                        _set(program, name, value)
                elif key not in prepared:
                    for name, value in shared.items():
                        _set(program, name, value)
                    prepared.add(key)
                flags = moderngl.DEPTH_TEST
                if not m.double_sided and overrides is None:
                    flags |= moderngl.CULL_FACE
                if blend and mode == 2:  # opaque fragments (alpha 1) need no blending
                    flags |= moderngl.BLEND
                ctx.enable_only(flags)
                _set(program, "u_base_color", tuple(float(x) for x in m.base_color))
                _set(program, "u_cutoff", float(m.alpha_cutoff))
                _set(program, "u_double_sided", int(bool(m.double_sided)))
                _set(program, "u_part", float(i))
                if pass_ == "shade":
                    r4 = max(float(m.roughness), 0.02) ** 4
                    _set(program, "u_shininess", float(min(max(2.0 / r4 - 2.0, 1.0), 4096.0)))
                    _set(program, "u_nscale", float(m.normal_scale))
                    if ntex is not None:
                        ntex.use(1)
                tex.use(0)
                g.vao(ctx, key, program).render(moderngl.TRIANGLES)

        try:
            if shadows:  # key light's depth map, alpha-tested like the mask, both faces drawn
                smap, sfbo = state.shadow_target(lt.shadow_resolution)
                sfbo.use()
                sfbo.clear(depth=1.0)
                draw("mask", False, {"u_view": _mat_bytes(light_view), "u_proj": _mat_bytes(light_proj)})
                smap.use(2)
            # colour pass: premultiplied alpha over the premultiplied background
            fbo = t["color_fbo"]
            fbo.use()
            fbo.clear(br * ba, bgc * ba, bb * ba, ba, depth=1.0)
            if self.samples <= 1:
                t["dval_fbo"].clear(0.0, 0.0, 0.0, 0.0)
            if self.samples <= 1 and any(_ALPHA_MODES[p.material.alpha_mode] != 2 for _i, p, *_ in gpu):
                # depth pre-pass of the opaque and alpha-tested parts: the costly shading then
                # runs once per pixel (depth "=="), not once per overlapping leaf card (measured
                # on llvmpipe: 1.9x faster single-sampled, slower with MSAA, so not there)
                t["prepass_fbo"].use()
                draw("mask", False, only="solid")
                fbo.use()
                ctx.depth_func = "=="
                draw("shade", True, only="solid", prepassed=True)
                ctx.depth_func = "<"
            else:
                draw("shade", True, only="solid")
            fbo.use()
            draw("shade", True, only="blend")
            if self.samples > 1:
                ctx.copy_framebuffer(t["resolve_fbo"], fbo)
                raw = t["resolve_fbo"].read(components=4)
                # silhouette + ids pass: single-sample, no blending
                mfbo = t["mask_fbo"]
                mfbo.use()
                mfbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
                draw("mask", False)
                buffers, first = mfbo, 0
            else:
                raw = fbo.read(components=4, attachment=0)
                buffers, first = fbo, 1
            ids_raw = buffers.read(components=4, dtype="f4", attachment=first)
            aux_raw = ([buffers.read(components=4, dtype="f4", attachment=first + k) for k in (1, 2)]
                       if self.aux else None)
        except moderngl.Error as exc:
            raise RenderError(f"OpenGL render failed: {exc}") from None
        finally:
            ctx.enable_only(moderngl.NOTHING)

        color = np.frombuffer(raw, np.uint8).reshape(h, w, 4)[::-1]
        color = _unpremultiply(color, self.background)
        ids = np.frombuffer(ids_raw, np.float32).reshape(h, w, 4)[::-1]
        mask = ids[..., 3] > 0
        depth = np.where(mask, ids[..., 0], np.float32(np.inf)).astype(np.float32, copy=False)
        part = np.rint(ids[..., 1]).astype(np.int16) - 1
        triangle = np.rint(ids[..., 2]).astype(np.int64).astype(np.int32) - 1
        normal = uv = None
        if aux_raw is not None:
            normal = np.ascontiguousarray(np.frombuffer(aux_raw[0], np.float32).reshape(h, w, 4)[::-1, :, :3])
            uv = np.ascontiguousarray(np.frombuffer(aux_raw[1], np.float32).reshape(h, w, 4)[::-1, :, :2])
        return RenderResult(color=color, mask=mask, depth=depth, camera=cam, part=part, triangle=triangle,
                            normal=normal, uv=uv)

    def __repr__(self) -> str:
        return f"Renderer({self._size[0]}x{self._size[1]}, samples={self.samples})"


def _light_matrices(mesh: Mesh, direction: np.ndarray, resolution: int):
    """Orthographic view and projection (4, 4) of a directional light enclosing ``mesh``.

    Returns the two matrices and the world size of one shadow-map texel.
    """
    lo, hi = mesh.bounds()
    center = 0.5 * (lo + hi)
    radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-3)
    d = np.asarray(direction, np.float64)
    up = np.array([0.0, 1.0, 0.0]) if abs(d[1]) < 0.99 else np.array([0.0, 0.0, 1.0])
    f = -d  # the light looks along -direction
    r = np.cross(f, up)
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    eye = center + d * 2.0 * radius
    view = np.eye(4)
    view[0, :3], view[1, :3], view[2, :3] = r, u, -f
    view[:3, 3] = -view[:3, :3] @ eye
    near, far = radius, 3.0 * radius
    proj = np.diag([1.0 / radius, 1.0 / radius, -2.0 / (far - near), 1.0])
    proj[2, 3] = -(far + near) / (far - near)
    return view, proj, 2.0 * radius / resolution


def _unpremultiply(premult: np.ndarray, background) -> np.ndarray:
    """Premultiplied (H, W, 4) uint8 -> straight alpha; background RGB where alpha is 0."""
    out = np.array(premult)  # contiguous copy
    a = out[..., 3]
    zero = a == 0
    if zero.any():
        out[zero, :3] = np.rint(np.asarray(background[:3]) * 255).astype(np.uint8)
    partial = (a > 0) & (a < 255)
    if partial.any():
        px = out[partial].astype(np.float32)
        rgb = np.clip(np.rint(px[:, :3] * 255.0 / px[:, 3:4]), 0, 255)
        out[partial, :3] = rgb.astype(np.uint8)
    return out


_VIEWS = ("front", "side", "back", "top")


def view_camera(camera: Camera, view: str) -> Camera:
    """The camera for a named view of the scene ``camera`` looks at.

    ``front`` is ``camera`` itself; ``side`` orbits it 90° about the target around +Y;
    ``back`` orbits 180°; ``top`` looks straight down from the same distance with image-up
    = -Z, so the front of the tree (+Z) is at the bottom of the image.
    """
    check_choice(view, "view", _VIEWS)
    if view == "front":
        return camera
    if view == "side":
        return camera.orbit(yaw_deg=90.0)
    if view == "back":
        return camera.orbit(yaw_deg=180.0)
    dist = float(np.linalg.norm(np.subtract(camera.position, camera.target)))
    pos = np.asarray(camera.target) + np.array([0.0, dist, 0.0])
    return Camera(camera.width, camera.height, camera.fov_y, tuple(pos), camera.target, (0.0, 0.0, -1.0),
                  camera.near, camera.far)


def render_views(mesh: Mesh, camera: Camera, *, views=("front", "side", "top"), samples: int = 4,
                 background=(1.0, 1.0, 1.0, 0.0), lighting: Lighting | None = None) -> dict[str, RenderResult]:
    """Render ``mesh`` from several named views around ``camera``'s target.

    Parameters
    ----------
    mesh : Mesh or MeshPart
    camera : Camera
        The ``front`` view; the others are derived with :func:`view_camera`.
    views : sequence of {"front", "side", "back", "top"}
    samples, background, lighting
        As for :class:`Renderer`.

    Returns
    -------
    dict of str -> RenderResult
        In the order of ``views``.
    """
    if isinstance(views, str):
        views = (views,)
    for v in views:
        check_choice(v, "views", _VIEWS)
    renderer = Renderer(camera, samples=samples, background=background, lighting=lighting)
    out = {}
    try:
        for v in views:
            renderer.camera = view_camera(camera, v)
            out[v] = renderer.render(mesh)
    finally:
        renderer.release()
    return out
