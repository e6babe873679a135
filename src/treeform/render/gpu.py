"""GPU resources shared by every :class:`~treeform.render.Renderer` in the process's context.

Compiled programs (one per pass and material variant, :mod:`treeform.render.shaders`), vertex
buffers of mesh parts and textures, cached on the identity of their arrays (least recently used
first out), and the shadow map. Everything lives in the context of
:func:`treeform.render.context.get_context` and is released with it.
"""

from __future__ import annotations

import weakref
from collections import OrderedDict

import numpy as np

from treeform._shared.errors import RenderError
from treeform.render.context import get_context, on_release
from treeform.render.shaders import _FRAGMENT, _FRAGMENT_MASK, _LAYOUT, INSTANCE_FORMAT, _source, _vertex
from treeform.structures.mesh import MeshPart

__all__ = ["clear_cache"]

_MAX_CACHED_PARTS = 64
_MAX_CACHED_TEXTURES = 64


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
                shadows: bool = False, prepassed: bool = False, instanced: bool = False):
        """The (cached) program for one pass ("shade" or "mask") and material variant.

        ``prepassed``: the shading pass of a MASK part whose depth a pre-pass already wrote
        (depth test "==": no alpha test, so the rasterizer tests depth before shading).
        ``instanced``: drawn once per instance (:data:`~treeform.render.shaders.INSTANCE_FORMAT`).
        """
        if pass_ == "mask":
            flat = has_ntex = shadows = prepassed = False
            has_tex = has_tex and alpha_mode != 0
        prepassed = bool(prepassed) and alpha_mode == 1
        key = (pass_, alpha_mode, bool(has_tex), bool(flat), bool(has_ntex), bool(shadows), prepassed, bool(instanced))
        prog = self.programs.get(key)
        if prog is None:
            fs = _FRAGMENT if pass_ == "shade" else _FRAGMENT_MASK
            try:
                prog = self.ctx.program(vertex_shader=_vertex(pass_ != "shade", bool(instanced)),
                                        fragment_shader=_source(fs, *key[1:7]))
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

    def vao(self, ctx, key, program, instances=None):
        """The part's vertex array for ``program``; with ``instances`` (a buffer of
        :data:`~treeform.render.shaders.INSTANCE_FORMAT`) a new one the caller releases."""
        if instances is not None:
            fmt, names = _vao_format(program)
            return ctx.vertex_array(program, [(self.vbo, fmt, *names), (instances, *INSTANCE_FORMAT)],
                                    index_buffer=self.ibo, index_element_size=4)
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
    if texture.shape[2] == 4 and texture[..., 3].min() < 255:  # alpha-tested: keep its coverage at distance
        for level, img in enumerate(coverage_mipmaps(texture)[1:], start=1):
            tex.write(img.tobytes(), level=level)
    import moderngl

    tex.filter = (moderngl.LINEAR_MIPMAP_LINEAR, moderngl.LINEAR)
    tex.repeat_x = tex.repeat_y = True
    state.textures[id(texture)] = (weakref.ref(texture), key, tex)
    while len(state.textures) > _MAX_CACHED_TEXTURES:
        state.textures.popitem(last=False)[1][2].release()
    return tex


on_release(_clear_gpu_state)


def coverage_mipmaps(rgba: np.ndarray, cutoff: float = 0.5) -> list:
    """Mip levels of an alpha-tested RGBA texture that keep its coverage (Castaño 2010).

    Averaging alpha over 2x2 texels lowers it wherever leaves and gaps mix, so an alpha test
    at ``cutoff`` passes fewer and fewer texels down the chain: a needle or a leaf card seen
    from far away fades to nothing. Here each level (box-filtered from the one above, its
    colour averaged with alpha as the weight so that transparent texels do not darken the
    edges) gets its alpha scaled by the factor whose alpha test passes the same share of
    texels as the full-size texture's.

    Parameters
    ----------
    rgba : ndarray, shape (H, W, 4), uint8
    cutoff : float
        The alpha test's threshold in [0, 1] (glTF's default 0.5).

    Returns
    -------
    list of ndarray
        ``[rgba, level1, level2, ...]`` down to 1x1, each (max(1, H >> k), max(1, W >> k), 4) uint8.

    Examples
    --------
    Sixty small leaves on a 128-texel texture: plain box-filtered alpha passes 15 %, 14 %, 14 %,
    10 %, 3 % and 0 % of the texels down the chain; these levels keep about 15 %.

    >>> import cv2
    >>> rng = np.random.default_rng(0)
    >>> tex = np.zeros((128, 128, 4), np.uint8)
    >>> for _ in range(60):
    ...     _ = cv2.circle(tex, (int(rng.integers(128)), int(rng.integers(128))), int(rng.integers(2, 6)),
    ...                    (40, 120, 30, 255), -1)
    >>> levels = coverage_mipmaps(tex)
    >>> [lv.shape[0] for lv in levels]
    [128, 64, 32, 16, 8, 4, 2, 1]
    >>> [round(float((lv[..., 3] >= 128).mean()), 2) for lv in levels[:5]]
    [0.15, 0.16, 0.16, 0.16, 0.16]
    >>> bool((levels[3][..., :3][levels[3][..., 3] > 0] == (40, 120, 30)).all())  # no dark fringes
    True
    """
    import cv2

    rgba = np.ascontiguousarray(rgba, np.uint8)
    c = cutoff * 255.0
    target = float((rgba[..., 3] >= c).mean())
    out = [rgba]
    a = rgba[..., 3].astype(np.float32)
    plain = rgba[..., :3].astype(np.float32)
    prem = plain * a[..., None]  # colour weighted by alpha
    while a.shape[0] > 1 or a.shape[1] > 1:
        h, w = a.shape
        size = (max(1, w >> 1), max(1, h >> 1))
        a = cv2.resize(a, size, interpolation=cv2.INTER_AREA).reshape(size[1], size[0])
        prem = cv2.resize(prem, size, interpolation=cv2.INTER_AREA).reshape(size[1], size[0], 3)
        plain = cv2.resize(plain, size, interpolation=cv2.INTER_AREA).reshape(size[1], size[0], 3)
        # the scale whose test passes ``target`` of the texels: the one that lifts the m-th largest alpha to
        # the cutoff (ties pass together, so at least ``target`` passes), at most 64
        m = int(np.ceil(target * a.size - 1e-9))
        k = 1.0
        if m > 0:
            t = float(np.partition(a.ravel(), a.size - m)[a.size - m])
            k = min(c / t, 64.0) if t > 0 else 64.0
        level = np.empty((size[1], size[0], 4), np.uint8)
        level[..., :3] = np.clip(np.rint(np.where(a[..., None] > 1e-3, prem / np.maximum(a, 1e-3)[..., None], plain)),
                                 0, 255)
        level[..., 3] = np.clip(np.rint(a * k), 0, 255)
        out.append(level)
    return out


class GLResources:
    """Base of the renderer's passes: the GL objects they made (``_objs``), freed by :meth:`release`."""

    _objs: list

    def release(self) -> None:
        """Free the textures, buffers and program."""
        for obj in reversed(getattr(self, "_objs", [])):
            obj.release()
        self._objs = []


def _set(program, name, value):
    """Set a uniform, skipping one the compiler optimised away; bytes are written raw (matrices)."""
    try:
        u = program[name]
    except KeyError:  # optimised away
        return
    if isinstance(value, bytes):
        u.write(value)
    else:
        u.value = value


def _mat_bytes(m: np.ndarray) -> bytes:
    """A (4, 4) matrix as the column-major float32 bytes of a GLSL ``mat4`` uniform."""
    return np.ascontiguousarray(np.asarray(m, np.float64).T, np.float32).tobytes()
