"""texture_sizes and tree_textures: a tree's texture set, sized from the tree."""

from __future__ import annotations

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.geometry import FOLIAGE_KINDS, bark_texture, leaf_texture, texture_sizes, tree_textures
from treeform.geometry.textures import BARK_TEXTURE_SIZE, LEAF_TEXTURE_SIZE, foliage_texture_kind
from treeform.structures import Foliage, TreeSkeleton


def _stick(r: float) -> TreeSkeleton:
    return TreeSkeleton(np.array([[0, 0, 0], [0, 2, 0.]]), np.array([-1, 0]), np.array([r, 0.6 * r]))


def _cards(size: float, m: int = 5) -> Foliage:
    return Foliage([[0, 1, 0]] * m, [[0, 0, 1]] * m, [[0, 1, 0]] * m, [size] * m, [[0.2, 0.5, 0.1]] * m)


def test_defaults_are_at_least_512_bark_and_256_leaves():
    assert (BARK_TEXTURE_SIZE, LEAF_TEXTURE_SIZE) == (512, 256)
    assert texture_sizes(_stick(0.05)) == (512, 256)  # a thin trunk and no leaves: the defaults
    assert texture_sizes(_stick(0.05), _cards(0.3)) == (512, 256)
    assert texture_sizes(_stick(0.05), Foliage.empty()) == (512, 256)
    # the default textures themselves
    assert bark_texture().shape == (512, 512, 4) and leaf_texture().shape == (256, 256, 4)


def test_sizes_grow_with_the_tree():
    # bark: ~512 texels per metre of trunk circumference (2π·0.35 m = 2.2 m -> 1024)
    assert texture_sizes(_stick(0.35))[0] == 1024
    # leaves: ~512 texels per metre of card (1 m cards -> 512)
    assert texture_sizes(_stick(0.05), _cards(1.0))[1] == 512
    # monotone in the tree's size, capped at 1024 unless asked for more
    sizes = [texture_sizes(_stick(r), _cards(2 * r)) for r in (0.02, 0.1, 0.3, 0.6, 3.0)]
    assert sizes == sorted(sizes) and sizes[-1] == (1024, 1024)
    for b, lf in sizes:
        assert b & (b - 1) == 0 and lf & (lf - 1) == 0  # powers of two


def test_texture_size_option():
    assert texture_sizes(_stick(0.35), _cards(1.0), texture_size=128) == (128, 64)
    assert texture_sizes(_stick(0.05), texture_size=2048) == (2048, 1024)
    bark, leaves = tree_textures(_stick(0.05), _cards(0.3), texture_size=64, seed=2)
    assert bark.shape == (64, 64, 4) and leaves.shape == (32, 32, 4)
    for bad in (8, 10_000, 300.0, True, "512"):
        with pytest.raises(InputError, match="texture_size"):
            texture_sizes(_stick(0.05), texture_size=bad)


@pytest.mark.parametrize("kind", FOLIAGE_KINDS)
def test_tree_textures_draw_the_foliage_kind(kind):
    bark, leaves = tree_textures(_stick(0.05), _cards(0.3), foliage_kind=kind, seed=3)
    np.testing.assert_array_equal(leaves, leaf_texture(256, seed=3, kind=foliage_texture_kind(kind)))
    np.testing.assert_array_equal(bark, bark_texture(512, seed=3))
    b2, l2 = tree_textures(_stick(0.05), _cards(0.3), foliage_kind=kind, seed=3)
    assert np.array_equal(bark, b2) and np.array_equal(leaves, l2)
    leaves[:] = 0  # a copy: the cached texture is not touched
    assert not np.array_equal(leaves, tree_textures(_stick(0.05), _cards(0.3), foliage_kind=kind, seed=3)[1])


def test_bad_inputs():
    with pytest.raises(InputError, match="foliage"):
        tree_textures(_stick(0.05), foliage_kind="ferns")
    with pytest.raises(InputError, match="skeleton"):
        texture_sizes("tree")
    with pytest.raises(InputError, match="seed"):
        tree_textures(_stick(0.05), seed=1.5)


def test_bark_normal_map_tiles_matches_the_texture_and_faces_out():
    from treeform.geometry.textures import bark_normals
    from treeform.geometry.tubes import bark_normal_map

    tex = bark_texture(128, seed=3)
    n = bark_normal_map(tex)
    assert n.shape == (128, 128, 4) and n.dtype == np.uint8
    v = n[..., :3].astype(float) / 127.5 - 1.0
    assert np.allclose(np.linalg.norm(v, axis=-1), 1.0, atol=0.02) and (v[..., 2] > 0.2).all()
    # relief, not a flat map; and it tiles: the jump across the wrap is no larger than inside
    assert v[..., :2].std() > 0.05
    inner = np.abs(np.diff(v[..., 0], axis=1)).mean()
    wrap = np.abs(v[:, 0, 0] - v[:, -1, 0]).mean()
    assert wrap < 2.0 * inner
    # the texture set's bark gets the map of its own texture
    s = TreeSkeleton(np.array([[0, 0, 0], [0, 1, 0.]]), np.array([-1, 0]), np.array([0.1, 0.05]))
    bark, _ = tree_textures(s, seed=3)
    np.testing.assert_array_equal(bark_normals(bark, seed=3), bark_normal_map(bark))
    with pytest.raises(InputError):
        bark_normals(np.zeros((4, 8, 4), np.uint8))


def test_tree_mesh_bark_carries_its_normal_map():
    from treeform.geometry import tree_mesh
    from treeform.geometry.textures import bark_normals

    s = TreeSkeleton(np.array([[0, 0, 0], [0, 1, 0.]]), np.array([-1, 0]), np.array([0.1, 0.05]))
    bark, leaves = tree_textures(s)
    mesh = tree_mesh(s, None, bark_texture=bark, bark_normal=bark_normals(bark))
    assert mesh.parts[0].material.normal_texture.shape == bark.shape
    assert tree_mesh(s, None).parts[0].material.normal_texture is not None  # the default bark has one too
