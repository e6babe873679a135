"""Headless OpenGL rendering (moderngl over EGL; Mesa llvmpipe on CPU, a GPU when present).

* :func:`get_context` – the shared, cached OpenGL 3.3 context (raises ``RenderError`` if none).
* :class:`Renderer` – ``Renderer(camera, samples=, background=, lighting=).render(mesh)`` gives a
  :class:`RenderResult` with ``color`` (H, W, 4) uint8, ``mask`` (H, W) bool and ``depth``
  (H, W) float32 metres along the view axis, row 0 at the top (Camera.project's pixel grid).
* :func:`render_views` – front / side / back / top renders around one camera.
* :func:`render_radial_cubemap` – the radial distance map of a closed mesh (seed 001 §3.5);
  :func:`bake_color_cubemap` – a mesh's own colours on that map's surface.
* :func:`render_rdm_impostor` – a radial distance map drawn by relief mapping (seed 001 §4.1).
* :func:`to_uint8_rgb` – RGBA composited over a background colour, for previews.

Modules, imports flowing one way (each only from those above it): ``context`` (the GL
context; others register :func:`~treeform.render.context.on_release` hooks), ``shaders``
(GLSL sources), ``gpu`` (programs, vertex buffers and textures cached in the context),
``lighting`` (:class:`Lighting`), ``result`` (:class:`RenderResult`, readback conversions),
``renderer`` (the mesh passes of :class:`Renderer`, :func:`render_views`), ``cubemap`` (the
radial distance map pass), ``impostor`` (the relief-mapped RDM).
"""

from treeform.render.context import get_context, release_context
from treeform.render.cubemap import bake_color_cubemap, render_radial_cubemap
from treeform.render.gpu import clear_cache
from treeform.render.impostor import render_rdm_impostor
from treeform.render.lighting import Lighting
from treeform.render.renderer import Renderer, render_views, view_camera
from treeform.render.result import RenderResult, to_uint8_rgb

__all__ = [
    "Lighting",
    "RenderResult",
    "Renderer",
    "clear_cache",
    "get_context",
    "release_context",
    "render_radial_cubemap",
    "bake_color_cubemap",
    "render_rdm_impostor",
    "render_views",
    "to_uint8_rgb",
    "view_camera",
]
