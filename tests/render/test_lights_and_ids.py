"""Several lights, key-light shadows, normal maps, specular highlights and per-pixel part / triangle ids."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import cube_part, quad_part

from treeform._shared.errors import InputError
from treeform.geometry import normal_map_from_height
from treeform.render import Lighting, Renderer
from treeform.structures import Camera, Material, Mesh

CAM = Camera(64, 64, 40.0, (0.0, 0.0, 5.0), (0.0, 0.0, 0.0))
OFF = dict(sky=(0.0, 0.0, 0.0), ground=(0.0, 0.0, 0.0))


def _lum(res, mask=None):
    m = res.mask if mask is None else mask
    return float(res.color[..., :3][m].astype(float).mean())


def test_part_and_triangle_ids(gl):
    back = quad_part(z=-1.0, half=1.0)
    front = quad_part(z=0.0, half=0.4)
    res = Renderer(CAM, samples=1).render(Mesh([back, front]))
    assert res.part.dtype == np.int16 and res.triangle.dtype == np.int32
    assert res.part[32, 32] == 1 and res.part[2, 32] in (-1, 0)
    assert (res.part[~res.mask] == -1).all() and (res.part[res.mask] >= 0).all()
    assert set(np.unique(res.triangle[res.mask])) <= {0, 1}
    # MSAA path (separate id pass) gives the same ids
    res4 = Renderer(CAM, samples=4).render(Mesh([back, front]))
    assert (res4.part == res.part).all() and (res4.triangle == res.triangle).all()


def test_aux_normals_and_uvs(gl):
    res = Renderer(CAM, samples=1, aux=True).render(quad_part(z=0.0, half=1.0))
    assert res.normal.shape == (64, 64, 3) and res.uv.shape == (64, 64, 2)
    assert np.allclose(res.normal[res.mask], [0, 0, 1], atol=1e-5)
    # glTF UVs: u grows to the right, v downwards
    assert res.uv[32, 40, 0] > res.uv[32, 24, 0] and res.uv[40, 32, 1] > res.uv[24, 32, 1]
    assert Renderer(CAM, samples=1).render(quad_part()).normal is None


def test_extra_lights_add_up(gl):
    mesh = cube_part(half=(0.6, 0.6, 0.6))
    cam = Camera(64, 64, 40.0, (2.5, 2.5, 4.0), (0.0, 0.0, 0.0))
    one = Renderer(cam, samples=1, lighting=Lighting(direction=(0, 0, 1), key=(0.4, 0.4, 0.4), **OFF)).render(mesh)
    two = Renderer(cam, samples=1, lighting=Lighting(direction=(0, 0, 1), key=(0.4, 0.4, 0.4), **OFF,
                                                     lights=(((1, 0, 0), (0.4, 0.4, 0.4)),))).render(mesh)
    assert _lum(two) > _lum(one) + 20
    with pytest.raises(InputError, match="at most 7"):
        Lighting(lights=[((0, 1, 0), (1, 1, 1))] * 8)
    with pytest.raises(InputError, match="shadow"):
        Lighting(shadow=1.5)


def test_key_light_shadow(gl):
    """A small quad between the light and a large one darkens it where the shadow falls."""
    floor = quad_part(z=-1.0, half=1.5)
    blocker = quad_part(z=0.5, half=0.4)
    blocker.positions[:, 0] += 1.2  # to the side: the camera sees the floor's shadowed centre
    mesh = Mesh([floor, blocker])
    lit = Lighting(direction=(0.8, 0.0, 1.0), key=(0.8, 0.8, 0.8), sky=(0.1, 0.1, 0.1), ground=(0.1, 0.1, 0.1))
    from dataclasses import replace

    none = Renderer(CAM, samples=1, lighting=lit).render(mesh)
    full = Renderer(CAM, samples=1, lighting=replace(lit, shadow=1.0)).render(mesh)
    half = Renderer(CAM, samples=1, lighting=replace(lit, shadow=0.5)).render(mesh)
    floor_px = full.part == 0
    dark = floor_px & (full.color[..., 0] < none.color[..., 0] - 30)
    assert dark.sum() > 30  # a shadow fell on the floor
    assert np.abs(half.color[..., 0][dark].astype(float)
                  - 0.5 * (full.color[..., 0][dark].astype(float) + none.color[..., 0][dark])).max() <= 3
    # lit parts of the floor and the blocker itself are unchanged
    far = floor_px & ~dark
    assert np.abs(full.color[far].astype(int) - none.color[far]).max() <= 2


def test_normal_map_and_specular(gl):
    bumps = normal_map_from_height(np.tile(np.sin(np.linspace(0, 8 * np.pi, 64)), (64, 1)), strength=30.0)
    flat = quad_part(half=1.0)
    bumpy = quad_part(half=1.0, material=Material(normal_texture=bumps))
    lt = Lighting(direction=(1.0, 0.0, 0.6), key=(0.9, 0.9, 0.9), **OFF)
    a = Renderer(CAM, samples=1, lighting=lt).render(flat).color[..., 0][16:48, 16:48].astype(float)
    b = Renderer(CAM, samples=1, lighting=lt).render(bumpy).color[..., 0][16:48, 16:48].astype(float)
    assert a.std() < 1.0 and b.std() > 10.0  # stripes appear across x only
    assert b.std(axis=0).max() < 3.0
    shiny = Material(roughness=0.2)
    head_on = Lighting(direction=(0.0, 0.0, 1.0), key=(0.5, 0.5, 0.5), **OFF)
    matte = Renderer(CAM, samples=1, lighting=head_on).render(quad_part(half=1.0, material=shiny))
    gloss = Renderer(CAM, samples=1, lighting=Lighting(direction=(0.0, 0.0, 1.0), key=(0.5, 0.5, 0.5), **OFF,
                                                       specular=0.3)).render(quad_part(half=1.0, material=shiny))
    assert gloss.color[32, 32, 0] > matte.color[32, 32, 0] + 20


def test_normal_texture_round_trip(tmp_path, gl):
    from treeform.io import read_glb, write_glb

    nrm = normal_map_from_height(np.random.default_rng(0).random((16, 16)))
    mesh = Mesh([quad_part(material=Material(normal_texture=nrm, normal_scale=0.5))])
    gltf, _ = read_glb(write_glb(mesh, tmp_path / "n.glb"))
    mat = gltf["materials"][0]
    assert mat["normalTexture"]["scale"] == 0.5 and len(gltf["images"]) == 1
    loaded = Mesh.load(mesh.save(tmp_path / "m.npz"))
    assert (loaded.parts[0].material.normal_texture == nrm).all()
