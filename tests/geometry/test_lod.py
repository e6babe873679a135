"""tree_mesh and the triangle budget."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_foliage, y_tree

from treeform._shared.errors import InputError
from treeform.geometry import LOD_PRESETS, branch_mesh, leaf_cards, plan_lod, tree_mesh
from treeform.geometry.tubes import _chain_measure
from treeform.structures import Foliage


def test_presets():
    assert LOD_PRESETS == {"low": 20_000, "medium": 60_000, "high": 200_000, "full": None}


def test_full_detail_is_the_two_parts(big_tree):
    s, f = big_tree
    m = tree_mesh(s, f)
    assert [p.name for p in m.parts] == ["bark", "leaves"]
    assert m.parts[0].n_triangles == branch_mesh(s).n_triangles
    assert m.parts[1].n_triangles == 2 * len(f)
    assert np.array_equal(m.parts[1].positions, leaf_cards(f).positions)
    assert m.n_triangles == tree_mesh(s, f, max_triangles=LOD_PRESETS["full"]).n_triangles


@pytest.mark.parametrize("budget", [1_000, 5_000, 50_000, 20_000, 100_000, 0, 7, 333])
def test_budget_respected(big_tree, budget):
    s, f = big_tree
    m = tree_mesh(s, f, max_triangles=budget)
    assert m.n_triangles <= budget
    if budget >= 1_000:
        assert m.n_triangles >= 0.9 * budget  # the budget is used, not wasted
        assert [p.name for p in m.parts] == ["bark", "leaves"]
    for p in m.parts:
        p.validate()
        assert np.all(np.isfinite(p.normals)) and np.all(np.isfinite(p.uvs))


def test_reduction_order(big_tree):
    s, f = big_tree
    chains = s.chains()
    lens = np.array([len(c) for c in chains])
    rad = _chain_measure(s, chains)
    full = plan_lod(lens, rad, len(f), radial_segments=8)
    assert full["radial_segments"] == 8 and full["keep_chains"].all() and full["keep_leaves"].all()
    total = full["branch_triangles"] + full["leaf_triangles"]
    # slightly over budget: fewer segments only
    p = plan_lod(lens, rad, len(f), max_triangles=total - 1, radial_segments=8)
    assert 3 <= p["radial_segments"] < 8 and p["keep_chains"].all() and p["keep_leaves"].all()
    # 50k: segments at 3, thinnest chains dropped, then leaves thinned
    p = plan_lod(lens, rad, len(f), max_triangles=50_000, radial_segments=8)
    assert p["radial_segments"] == 3
    if not p["keep_chains"].all():
        assert rad[~p["keep_chains"]].max() <= rad[p["keep_chains"]].min() + 1e-12
        assert p["keep_chains"][0]  # the trunk goes last
    kept = p["keep_leaves"].sum()
    assert 0 < kept < len(f)
    assert p["leaf_scale"] == pytest.approx(np.sqrt(len(f) / kept))


def test_subsampled_leaves_are_enlarged(big_tree):
    s, f = big_tree
    m = tree_mesh(s, f, max_triangles=5_000)
    leaves = m.parts[1]
    kept = leaves.n_triangles // 2
    q = leaves.positions.reshape(-1, 4, 3).astype(np.float64)
    size = np.linalg.norm(q[:, 1] - q[:, 0], axis=1)
    centre = q.mean(axis=1)
    idx = np.array([np.flatnonzero(np.all(np.isclose(f.positions, c, atol=1e-5), axis=1))[0] for c in centre[:20]])
    assert np.allclose(size[:20], f.size[idx] * np.sqrt(len(f) / kept), rtol=1e-4)
    # the area of the crown's cards stays about the same
    assert np.sum(size**2) == pytest.approx(np.sum(f.size**2), rel=0.1)


def test_deterministic(big_tree):
    s, f = big_tree
    a = tree_mesh(s, f, max_triangles=5_000, seed=3)
    b = tree_mesh(s, f, max_triangles=5_000, seed=3)
    c = tree_mesh(s, f, max_triangles=5_000, seed=4)
    for pa, pb in zip(a.parts, b.parts):
        for k in ("positions", "normals", "uvs", "colors", "indices"):
            assert np.array_equal(getattr(pa, k), getattr(pb, k))
        assert np.array_equal(pa.material.texture, pb.material.texture)
    assert not np.array_equal(a.parts[1].positions, c.parts[1].positions)


def test_small_trees_and_bad_input():
    s = y_tree()
    m = tree_mesh(s, None)
    assert [p.name for p in m.parts] == ["bark"]
    m = tree_mesh(s, Foliage.empty(), max_triangles=10)
    assert m.n_triangles <= 10
    f = random_foliage(s, 5)
    assert tree_mesh(s, f, max_triangles=4).n_triangles <= 4
    tex = np.zeros((8, 8, 4), np.uint8)
    assert tree_mesh(s, f, leaf_texture=tex).parts[1].material.texture is not None
    with pytest.raises(InputError, match="max_triangles"):
        tree_mesh(s, f, max_triangles=-1)
    with pytest.raises(InputError, match="max_triangles"):
        tree_mesh(s, f, max_triangles=1.5)
    with pytest.raises(InputError, match="radial_segments"):
        tree_mesh(s, f, radial_segments=1)
    with pytest.raises(InputError, match="foliage"):
        tree_mesh(s, "leaves")
