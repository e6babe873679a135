"""The shared headless OpenGL context (moderngl over EGL; Mesa llvmpipe on CPU, a GPU when present).

One context per process is created lazily and cached; every renderer in :mod:`treeform.render`
draws through it. moderngl contexts are bound to the thread that made them, so render from one
thread (use processes for parallelism).
"""

from __future__ import annotations

import logging
import threading

from treeform._shared.errors import RenderError

__all__ = ["get_context", "release_context", "on_release", "NO_CONTEXT_MESSAGE"]

log = logging.getLogger(__name__)

NO_CONTEXT_MESSAGE = (
    "no OpenGL context: install Mesa EGL (apt-get install libegl1 libgl1 libegl-mesa0 libgl1-mesa-dri)"
)

_REQUIRED_VERSION = 330  # OpenGL 3.3 core
_lock = threading.Lock()
_ctx = None
_release_hooks: list = []  # what caches GL objects in the context frees them before it goes


def _create():
    try:
        import moderngl
    except ImportError:  # pragma: no cover - moderngl is a hard dependency
        raise RenderError(NO_CONTEXT_MESSAGE) from None
    errors = []
    for kwargs in ({"backend": "egl"}, {}):
        try:
            ctx = moderngl.create_standalone_context(require=_REQUIRED_VERSION, **kwargs)
        except Exception as exc:  # moderngl raises plain Exception / moderngl.Error
            errors.append(f"{kwargs.get('backend', 'default')}: {exc}")
            continue
        if ctx.version_code < _REQUIRED_VERSION:
            errors.append(f"{kwargs.get('backend', 'default')}: OpenGL {ctx.version_code} < 3.3")
            ctx.release()
            continue
        # free GL objects when their Python wrappers die (render code also releases explicitly)
        ctx.gc_mode = "auto"
        log.debug("OpenGL context: %s, %s", ctx.info.get("GL_RENDERER"), ctx.info.get("GL_VERSION"))
        return ctx
    log.debug("OpenGL context creation failed: %s", "; ".join(errors))
    raise RenderError(NO_CONTEXT_MESSAGE)


def get_context():
    """Return the cached moderngl standalone context, creating it on first use.

    Tries the EGL backend first (headless), then moderngl's default backend.

    Returns
    -------
    moderngl.Context
        An OpenGL >= 3.3 core context.

    Raises
    ------
    RenderError
        If no OpenGL 3.3 context can be created (e.g. Mesa EGL is not installed).
    """
    global _ctx
    if _ctx is not None:
        return _ctx
    with _lock:
        if _ctx is None:
            _ctx = _create()
    return _ctx


def on_release(hook) -> None:
    """Call ``hook()`` before the context is released (:func:`release_context`).

    Modules that cache GL objects in the context (:mod:`treeform.render.gpu`) register here,
    so the context needs to know none of them: imports flow one way, into this module.
    """
    if hook not in _release_hooks:
        _release_hooks.append(hook)


def release_context() -> None:
    """Release the cached context and every GPU resource cached in it (the :func:`on_release` hooks first)."""
    global _ctx
    with _lock:
        if _ctx is None:
            return
        try:
            for hook in _release_hooks:
                hook()
            _ctx.release()
        finally:
            _ctx = None
