"""leaf_texture and leaf_cards."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_foliage, random_parent_tree

from treeform._shared.errors import InputError
from treeform.geometry import leaf_cards, leaf_texture, texture_coverage
from treeform.structures import Foliage


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
def test_cluster_texture_coverage_and_alpha(seed):
    t = leaf_texture(128, seed=seed)
    assert t.shape == (128, 128, 4) and t.dtype == np.uint8
    cov = texture_coverage(t)
    assert 0.55 <= cov <= 0.75, cov
    a = t[..., 3]
    assert (a == 0).any() and (a == 255).any()
    assert ((a > 0) & (a < 255)).any()  # antialiased edges
    # light, slightly green texels so the card colour tints them
    opaque = t[a > 127, :3].astype(float)
    assert opaque.mean() > 0.75 * 255
    assert opaque[:, 1].mean() >= opaque[:, 0].mean() and opaque[:, 1].mean() >= opaque[:, 2].mean()
    assert opaque.std(axis=0).max() > 3  # shading variation, not a flat colour
    # transparent texels carry the leaf colour (no dark fringe when filtered)
    assert t[a == 0, :3].mean() > 0.6 * 255


def test_texture_kinds_sizes_and_determinism():
    leaf = leaf_texture(64, kind="leaf")
    assert 0.2 < texture_coverage(leaf) < 0.6
    assert leaf[..., 3][0, 0] == 0 and leaf[32, 32, 3] == 255  # corner empty, middle leaf
    assert np.array_equal(leaf_texture(64, seed=5), leaf_texture(64, seed=5))
    assert not np.array_equal(leaf_texture(64, seed=5), leaf_texture(64, seed=6))
    for size in (16, 256):
        assert 0.55 <= texture_coverage(leaf_texture(size)) <= 0.75
    with pytest.raises(InputError, match="kind"):
        leaf_texture(kind="needle")
    with pytest.raises(InputError, match="size"):
        leaf_texture(2)


def test_cards_counts_and_material():
    f = random_foliage(random_parent_tree(50), 37)
    p = leaf_cards(f)
    assert p.n_vertices == 4 * 37 and p.n_triangles == 2 * 37
    assert p.name == "leaves"
    mat = p.material
    assert mat.name == "leaves" and mat.alpha_mode == "MASK" and mat.alpha_cutoff == 0.5 and mat.double_sided
    assert mat.texture.shape == (256, 256, 4)  # LEAF_TEXTURE_SIZE
    assert np.allclose(p.colors[:, :3], np.repeat(f.color, 4, axis=0))
    assert np.all(p.colors[:, 3] == 1)
    tex = leaf_texture(32, kind="leaf")
    assert np.array_equal(leaf_cards(f, texture=tex).material.texture, tex)


def test_card_geometry():
    f = random_foliage(random_parent_tree(50), 25, seed=4)
    p = leaf_cards(f)
    q = p.positions.reshape(-1, 4, 3).astype(np.float64)
    assert np.allclose(q.mean(axis=1), f.positions, atol=1e-6)
    e1 = q[:, 1] - q[:, 0]
    e2 = q[:, 3] - q[:, 0]
    assert np.allclose(np.linalg.norm(e1, axis=1), f.size, rtol=1e-5)
    assert np.allclose(np.linalg.norm(e2, axis=1), f.size, rtol=1e-5)
    # spanned by up and cross(normal, up); the up edge is along up
    assert np.allclose(e2 / f.size[:, None], f.up, atol=1e-5)
    side = np.cross(f.normals, f.up)
    assert np.allclose(np.abs(np.sum(e1 / f.size[:, None] * side, axis=1)), 1, atol=1e-5)
    # vertex normals and face normals equal the foliage normal
    assert np.allclose(p.normals.reshape(-1, 4, 3), f.normals[:, None, :], atol=1e-6)
    tri = p.positions[p.indices.astype(np.int64)].astype(np.float64)
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    fn /= np.linalg.norm(fn, axis=1, keepdims=True)
    assert np.allclose(fn, np.repeat(f.normals, 2, axis=0), atol=1e-4)
    # UVs: (0,1) bottom-left ... texture's top at +up
    assert np.allclose(p.uvs.reshape(-1, 4, 2)[0], [[0, 1], [1, 1], [1, 0], [0, 0]])


def test_cards_edge_cases():
    empty = leaf_cards(Foliage.empty())
    assert empty.n_vertices == 0 and empty.n_triangles == 0
    # up not orthogonal (or parallel) to the normal is repaired
    f = Foliage([[0, 0, 0], [1, 0, 0]], [[0, 0, 1], [0, 1, 0]], [[0, 1, 0.5], [0, 1, 0]], [1, 1], [[0.1, 0.5, 0.1]] * 2)
    p = leaf_cards(f)
    assert np.all(np.isfinite(p.positions))
    tri = p.positions[p.indices.astype(np.int64)].astype(np.float64)
    fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    assert np.allclose(fn / np.linalg.norm(fn, axis=1, keepdims=True), np.repeat(f.normals, 2, axis=0), atol=1e-6)
    with pytest.raises(InputError, match="foliage"):
        leaf_cards("leaves")
    with pytest.raises(InputError, match="size_scale"):
        leaf_cards(f, size_scale=[1.0])


# --------------------------------------------------------------------------- conifer textures
def _opaque_runs(alpha: np.ndarray) -> np.ndarray:
    """Lengths (texels) of the runs of opaque texels along every row and every column."""
    runs = []
    for m in (alpha > 127, (alpha > 127).T):
        d = np.diff(np.pad(m.astype(np.int8), ((0, 0), (1, 1))), axis=1)
        runs.append(np.flatnonzero(d.ravel() == -1) - np.flatnonzero(d.ravel() == 1))
    return np.concatenate(runs)


def _mip_coverage(alpha: np.ndarray, k: int) -> float:
    """Opaque fraction after a k x k box filter (a mip level), as an alpha test at 0.5 sees it."""
    n = alpha.shape[0] // k
    return float((alpha[: n * k, : n * k].reshape(n, k, n, k).mean(axis=(1, 3)) >= 127.5).mean())


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_needle_texture_is_thin_needles(seed):
    t = leaf_texture(256, seed=seed, kind="needles")
    assert t.shape == (256, 256, 4) and t.dtype == np.uint8
    a = t[..., 3]
    cov = texture_coverage(t)
    assert 0.2 <= cov <= 0.4, cov  # far sparser than a broadleaf cluster (0.65)
    runs = _opaque_runs(a)
    # across a needle an opaque run is a few texels; a broadleaf blade spans tens
    assert np.median(runs) <= 4 and runs.mean() <= 7, (np.median(runs), runs.mean())
    assert _opaque_runs(leaf_texture(256, seed=seed)[..., 3]).mean() > 5 * runs.mean()
    # many separate strands: the alpha changes along a row far more often than a cluster's
    assert len(runs) > 3000
    # the bottle-brush shape survives the mip chain (an alpha test at a distance keeps it)
    for k in (2, 4, 8):
        assert _mip_coverage(a, k) >= 0.6 * cov, k
    # light, green-leaning colours for the card tint, with needle-to-needle shading
    opaque = t[a > 127, :3].astype(float)
    assert opaque.mean() > 0.6 * 255 and opaque[:, 1].mean() >= opaque[:, 0].mean()
    assert opaque.std(axis=0).max() > 10
    # nothing is cut by the card's border: the outermost texels are transparent
    assert a[0].max() < 128 and a[:, 0].max() < 128 and a[:, -1].max() < 128


def test_scale_texture_is_a_spray_of_scales():
    t = leaf_texture(256, seed=0, kind="scales")
    a = t[..., 3]
    cov = texture_coverage(t)
    assert 0.2 <= cov <= 0.45, cov
    runs = _opaque_runs(a)
    assert np.median(runs) <= 12 and runs.mean() < 0.25 * _opaque_runs(leaf_texture(256)[..., 3]).mean()
    # the branchlets are chains of scales: along the main axis (the middle column) the
    # luminance rises and falls once per scale, several times over its length
    col = t[:, 120:136]
    opaque = col[..., 3] > 200
    rows = opaque.any(axis=1)
    lum = col[..., :3].astype(float).mean(-1)
    prof = (lum * opaque).sum(axis=1)[rows] / opaque.sum(axis=1)[rows]
    d = np.diff(prof)
    assert np.count_nonzero((d[:-1] > 0) & (d[1:] <= 0)) >= 8  # local maxima: scale centres
    for k in (2, 4, 8):
        assert _mip_coverage(a, k) >= 0.8 * cov


@pytest.mark.parametrize("kind", ["needles", "scales"])
def test_conifer_textures_deterministic_and_sized(kind):
    assert np.array_equal(leaf_texture(64, seed=5, kind=kind), leaf_texture(64, seed=5, kind=kind))
    assert not np.array_equal(leaf_texture(64, seed=5, kind=kind), leaf_texture(64, seed=6, kind=kind))
    assert leaf_texture(16, seed=1, kind=kind).shape == (16, 16, 4)
    for size in (64, 128, 512):  # strands widen to about a texel on small textures, never vanish
        t = leaf_texture(size, seed=1, kind=kind)
        assert t.shape == (size, size, 4)
        assert 0.2 < texture_coverage(t) < (0.6 if size < 128 else 0.5), (size, texture_coverage(t))


def _reference_cards(f: Foliage, scale):
    """The former NumPy leaf_cards: corner positions and normals, float32."""
    from treeform.geometry.leaves import card_frames

    m = len(f)
    n, up, right = card_frames(f)
    half = (0.5 * f.size * np.asarray(scale, np.float64))[:, None]
    c = f.positions
    pos = np.stack([c - half * right - half * up, c + half * right - half * up,
                    c + half * right + half * up, c - half * right + half * up], axis=1)
    nrm = np.broadcast_to(n[:, None, :], (m, 4, 3))
    return pos.reshape(-1, 3).astype(np.float32), nrm.reshape(-1, 3).astype(np.float32)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_cards_match_the_numpy_reference(seed):
    rng = np.random.default_rng(seed)
    f = random_foliage(random_parent_tree(200, seed), 3000, seed=seed)
    normals = f.normals * rng.uniform(0.01, 10, (len(f), 1))  # not unit length
    up = f.up.copy()
    up[:50] = normals[:50] * 3  # up parallel to the normal: the fallback frame
    normals[:20] = [0, 2.0, 0]  # ... with a normal along y
    up[:10] = [0, -1.0, 0]
    f = Foliage(f.positions, normals, up, f.size, f.color, f.node)
    for scale in (1.0, 1.7, rng.uniform(0.5, 2.0, len(f))):
        part = leaf_cards(f, size_scale=scale)
        pos, nrm = _reference_cards(f, scale)
        assert np.array_equal(part.positions, pos) and np.array_equal(part.normals, nrm)
    uv = np.sort(rng.uniform(0, 1, (len(f), 2, 2)), axis=1).transpose(0, 2, 1).reshape(-1, 4).astype(np.float32)
    part = leaf_cards(f.with_colors(f.color, uv=uv))
    assert np.array_equal(part.uvs.reshape(-1, 4, 2)[:, 0], uv[:, [0, 3]])
    assert np.array_equal(part.uvs.reshape(-1, 4, 2)[:, 2], uv[:, [2, 1]])


def test_bezier_outline_leaves():
    from treeform._shared.errors import InputError
    from treeform.geometry import leaf_texture, texture_coverage

    a = leaf_texture(64, seed=3, outline="bezier")
    assert np.array_equal(a, leaf_texture(64, seed=3, outline="bezier"))
    assert not np.array_equal(a[..., 3], leaf_texture(64, seed=3)[..., 3])  # other margins
    assert 0.6 <= texture_coverage(a) <= 0.7
    one = leaf_texture(64, seed=1, kind="leaf", outline="bezier")[..., 3] > 127
    cols = one.any(0)
    # one blade: symmetric about the midrib column, widest away from base and tip
    assert abs(np.flatnonzero(cols).mean() - 31.5) < 1.5
    widths = one.sum(1)
    assert widths.argmax() not in (0, 63) and widths.max() > 10
    with pytest.raises(InputError):
        leaf_texture(64, outline="spline")


def test_opaque_cards_trim_each_card_to_its_leaves():
    """What ignores alpha (the impostor's radial map) should see the leaves, not the cards' transparent margins."""
    from dataclasses import replace

    from treeform.geometry import opaque_cards

    f = random_foliage(random_parent_tree(50), 30, seed=2)
    tex = np.zeros((64, 64, 4), np.uint8)
    tex[16:48, 8:40, 3] = 255  # the leaf fills rows 16-47, columns 8-39: half the card along u and v
    p = leaf_cards(f, texture=tex)
    q = opaque_cards(p).reshape(-1, 4, 3)
    full = p.positions.reshape(-1, 4, 3).astype(np.float64)
    # each card keeps its plane and is half as wide and tall, its centre moved to the leaf's
    assert np.allclose(np.linalg.norm(q[:, 1] - q[:, 0], axis=1), 0.5 * f.size, rtol=1e-5)
    assert np.allclose(np.linalg.norm(q[:, 3] - q[:, 0], axis=1), 0.5 * f.size, rtol=1e-5)
    assert np.allclose(np.einsum("nkc,nc->nk", q - full[:, :1], f.normals), 0.0, atol=1e-5)
    expect = full[:, 0] + (8 + 16) / 64 * (full[:, 1] - full[:, 0]) + (1 - 32 / 64) * (full[:, 3] - full[:, 0])
    assert np.allclose(q.mean(1), expect, atol=1e-5)  # u from the left edge; v = 1 at the card's bottom corner 0
    # an opaque texture changes nothing; a part that is not cards is left alone
    solid = np.full((8, 8, 4), 255, np.uint8)
    assert np.allclose(opaque_cards(leaf_cards(f, texture=solid)), p.positions, atol=1e-6)
    assert opaque_cards(replace(p, indices=p.indices[:, ::-1])) is None
    assert opaque_cards(replace(p, material=replace(p.material, texture=None))) is None
