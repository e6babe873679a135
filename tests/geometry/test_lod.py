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


def _card_area(part) -> float:
    q = part.positions.reshape(-1, 4, 3).astype(np.float64)
    return float(np.sum(np.linalg.norm(q[:, 1] - q[:, 0], axis=1) ** 2))


@pytest.mark.parametrize("species", ["oak", "pine"])
def test_foliage_budget_generates_only_what_the_lod_keeps(species):
    """Clusters generated to the budget's count and size: tree_mesh keeps them all, the crown area stays."""
    from treeform.geometry import foliage_budget
    from treeform.growth.leaves import twig_foliage, twig_nodes
    from treeform.growth.phenomenological import grow
    from treeform.growth.species import load_species, load_species_appearance

    s, look = grow(load_species(species), seed=1), load_species_appearance(species)
    n = int(round(3.0 * len(twig_nodes(s))))
    full = twig_foliage(s, leaf_color=look.leaf_color, size=look.leaf_size, leaves=n, seed=0)
    for budget in (2_000, 8_000, 20_000, 60_000, None):
        m, factor = foliage_budget(s, n, max_triangles=budget, radial_segments=8)
        thinned = tree_mesh(s, full, max_triangles=budget, seed=0)
        assert m == thinned.parts[-1].n_triangles // 2  # as many as plan_lod keeps of the full foliage
        assert factor == pytest.approx(np.sqrt(n / m) if m < n else 1.0)
        f = twig_foliage(s, leaf_color=look.leaf_color, size=look.leaf_size * factor, leaves=m, seed=0)
        mesh = tree_mesh(s, f, max_triangles=budget, seed=0)
        assert budget is None or mesh.n_triangles <= budget
        assert mesh.parts[-1].name == "leaves" and mesh.parts[-1].n_triangles == 2 * m == 2 * len(f)  # all kept
        assert mesh.parts[0].n_triangles == thinned.parts[0].n_triangles  # the same branches
        assert _card_area(mesh.parts[-1]) == pytest.approx(_card_area(thinned.parts[-1]), rel=0.03)


def test_foliage_budget_always_fits_and_bad_input(big_tree):
    from treeform.geometry import foliage_budget
    from treeform.geometry.tubes import _chain_arrays, _chain_measure_flat

    s, f = big_tree
    nodes, lens = _chain_arrays(s)
    rad = _chain_measure_flat(s, nodes, lens)
    for budget in list(range(0, 3_000, 97)) + list(range(3_000, 80_000, 1_013)):
        for n in (0, 1, 500, len(f)):
            m, factor = foliage_budget(s, n, max_triangles=budget, radial_segments=8)
            p = plan_lod(lens, rad, m, max_triangles=budget, radial_segments=8)
            assert p["keep_leaves"].all() and p["branch_triangles"] + 2 * m <= budget  # the mesh keeps every one
            assert m <= plan_lod(lens, rad, n, max_triangles=budget)["keep_leaves"].sum()
            assert factor == (np.sqrt(n / m) if 0 < m < n else 1.0)
    assert foliage_budget(s, 123, max_triangles=None) == (123, 1.0)
    assert foliage_budget(y_tree(), 10, max_triangles=0) == (0, 1.0)
    with pytest.raises(InputError, match="max_triangles"):
        foliage_budget(s, 10, max_triangles=-1)
    with pytest.raises(InputError, match="n_leaves"):
        foliage_budget(s, -1, max_triangles=10)
    with pytest.raises(InputError, match="n_leaves"):
        foliage_budget(s, 2.5, max_triangles=10)
    with pytest.raises(InputError, match="radial_segments"):
        foliage_budget(s, 10, max_triangles=10, radial_segments=2)
    with pytest.raises(InputError, match="skeleton"):
        foliage_budget("tree", 10, max_triangles=10)
