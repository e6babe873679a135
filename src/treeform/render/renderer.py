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

import numpy as np

from treeform._shared.checks import check_choice
from treeform._shared.errors import InputError, RenderError
from treeform.render.gpu import _get_state, _mat_bytes, _part_gpu, _set, _texture_gpu, clear_cache
from treeform.render.lighting import MAX_LIGHTS, Lighting
from treeform.render.result import RenderResult, _unpremultiply, to_uint8_rgb
from treeform.render.shaders import _ALPHA_MODES
from treeform.structures.camera import Camera
from treeform.structures.mesh import Mesh, MeshPart

__all__ = ["Lighting", "RenderResult", "Renderer", "render_views", "view_camera", "to_uint8_rgb", "clear_cache"]


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
    def render(self, mesh: Mesh, instances=None, *, passes=(), stats: dict | None = None) -> RenderResult:
        """Render ``mesh`` (or a single :class:`MeshPart`) from :attr:`camera`.

        Parameters
        ----------
        mesh : Mesh or MeshPart
        instances : array_like, shape (N, 6), optional
            Draw the mesh once per row (:func:`~treeform.render.instances.check_instances`):
            a forest of one tree in one draw call per part.
        passes, stats :
            As :meth:`render_scene`.

        Returns
        -------
        RenderResult
            ``color`` (H, W, 4) uint8, ``mask`` (H, W) bool, ``depth`` (H, W) float32.
        """
        return self.render_scene([(mesh, instances)], passes=passes, stats=stats)

    def render_scene(self, items, *, passes=(), stats: dict | None = None) -> RenderResult:
        """Render several meshes, each drawn once or once per instance, into one image.

        Parameters
        ----------
        items : sequence of (Mesh or MeshPart, instances or None)
            ``instances``: (N, 6) rows ``(x, y, z, scale, yaw, count)``
            (:func:`~treeform.render.instances.check_instances`); parts are numbered over all
            items in order (:attr:`RenderResult.part`). Instanced items cast no shadows: the
            key light's shadow map is drawn only when no item is instanced.
        passes : sequence of callables, optional
            ``draw(ctx, camera)`` each, called after the opaque and alpha-tested parts, into
            the same framebuffer with the depth test on (e.g. relief impostors and billboard
            clouds, e.g. ``treeform forest``). A pass writes location 0 = premultiplied
            colour and location 1 = (view depth, id, 0, 1). Only with ``samples <= 1``.
        stats : dict, optional
            Filled with milliseconds per step, measured with ``glFinish`` between steps:
            ``meshes`` (opaque and alpha-tested parts), one entry per pass (its ``name``
            attribute, else ``pass<k>``), ``blend``, ``draw`` (all of these) and ``read``.

        Returns
        -------
        RenderResult
        """
        import time

        import moderngl

        from treeform.render.instances import check_instances

        if passes and self.samples > 1:
            raise InputError("passes: only with samples <= 1 (they draw into the single-sample framebuffer)")
        scene = []
        for k, item in enumerate(items):
            try:
                m, inst = item
            except (TypeError, ValueError):
                raise InputError(f"items[{k}]: expected a (mesh, instances or None) pair") from None
            scene.append((_as_mesh(m), None if inst is None else check_instances(inst, f"items[{k}] instances")))
        mesh = Mesh([p for m, _ in scene for p in m.parts])
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

        parts, i = [], 0
        for m, inst in scene:
            for p in m.parts:
                if p.n_triangles and (inst is None or len(inst)):
                    parts.append((i, p, inst))
                i += 1
        for _i, p, _inst in parts:
            p.validate()
        parts.sort(key=lambda ip: ip[1].material.alpha_mode == "BLEND")  # stable: opaque first
        inst_bufs: dict = {}  # one GPU buffer per instance array
        temp = []  # vertex arrays and buffers of this call
        try:
            for _i, _p, inst in parts:
                if inst is not None and id(inst) not in inst_bufs:
                    inst_bufs[id(inst)] = ctx.buffer(inst.tobytes())
                    temp.append(inst_bufs[id(inst)])
        except moderngl.Error as exc:
            for obj in temp:
                obj.release()
            raise RenderError(f"OpenGL render failed: {exc}") from None
        gpu = [(i, p, _part_gpu(state, p), _texture_gpu(state, p.material.texture),
                _texture_gpu(state, p.material.normal_texture) if p.material.normal_texture is not None else None,
                inst)
               for i, p, inst in parts]

        lt = self.lighting
        dirs, cols = lt.world_lights(cam)
        shadows = (lt.shadow > 0 and lt.key != (0.0, 0.0, 0.0) and bool(gpu)
                   and all(inst is None for _m, inst in scene))
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
            for i, p, g, tex, ntex, inst in gpu:
                m = p.material
                mode = _ALPHA_MODES[m.alpha_mode]
                if only is not None and (mode == 2) != (only == "blend"):
                    continue
                key, program = state.program(pass_, mode, m.texture is not None, g.flat, ntex is not None,
                                             shadows, prepassed, inst is not None)
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
                    _set(program, "u_unlit", int(bool(m.unlit)))
                    if ntex is not None:
                        ntex.use(1)
                tex.use(0)
                if inst is None:
                    g.vao(ctx, key, program).render(moderngl.TRIANGLES)
                else:
                    vao = g.vao(ctx, key, program, inst_bufs[id(inst)])
                    temp.append(vao)
                    vao.render(moderngl.TRIANGLES, instances=len(inst))

        clock = [time.perf_counter()]

        def lap(name: str) -> None:
            if stats is not None:
                ctx.finish()
                now = time.perf_counter()
                stats[name] = stats.get(name, 0.0) + 1e3 * (now - clock[0])
                clock[0] = now

        if stats is not None:
            stats.clear()
            ctx.finish()
            clock[0] = time.perf_counter()
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
            lap("meshes")
            fbo.use()
            for k, pass_draw in enumerate(passes):
                ctx.enable_only(moderngl.DEPTH_TEST)
                ctx.depth_func = "<"
                pass_draw(ctx, cam)
                lap(getattr(pass_draw, "name", f"pass{k}"))
            fbo.use()
            draw("shade", True, only="blend")
            lap("blend")
            if stats is not None:
                stats["draw"] = sum(v for k, v in stats.items() if k not in ("draw", "read"))
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
            lap("read")
        except moderngl.Error as exc:
            raise RenderError(f"OpenGL render failed: {exc}") from None
        finally:
            ctx.enable_only(moderngl.NOTHING)
            ctx.depth_func = "<"
            for obj in reversed(temp):
                obj.release()

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
