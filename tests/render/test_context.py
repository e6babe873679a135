"""get_context: caching, the one-line error when no OpenGL exists, release and re-creation."""

from __future__ import annotations

import gc

import numpy as np
import pytest

from treeform._shared.errors import RenderError
from treeform.render import Renderer, get_context, release_context
from treeform.render import context as context_module
from treeform.structures import Camera


def test_context_is_cached_and_core_33(gl):
    ctx = get_context()
    assert get_context() is ctx
    assert ctx.version_code >= 330


def test_no_context_raises_one_line_render_error(monkeypatch):
    import moderngl

    def fail(*args, **kwargs):
        raise Exception("no display")

    monkeypatch.setattr(context_module, "_ctx", None)
    monkeypatch.setattr(moderngl, "create_standalone_context", fail)
    with pytest.raises(RenderError) as info:
        get_context()
    msg = str(info.value)
    assert "\n" not in msg
    assert msg == ("no OpenGL context: install Mesa EGL "
                   "(apt-get install libegl1 libgl1 libegl-mesa0 libgl1-mesa-dri)")


def test_renderer_survives_context_release(gl, meshes):
    cam = Camera(40, 30, 50.0, (0.0, 0.0, 3.0), (0.0, 0.0, 0.0))
    part = meshes.cube(half=(0.4, 0.4, 0.4))
    r = Renderer(cam)
    before = r.render(part)
    release_context()
    gc.collect()
    after = r.render(part)  # a fresh context, programs, buffers and framebuffers
    assert np.array_equal(before.mask, after.mask)
    assert before.color.tobytes() == after.color.tobytes()
