"""Phenomenological bud-based growth (seed 003 §4.3, Tables 2-3): contract, determinism, parameter effects."""

from dataclasses import fields, replace

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.growth.phenomenological import PARAMETER_SYMBOLS, GrowthParameters, apical_control, grow
from treeform.growth.species import load_species
from treeform.methods.learned.grow import shape_metrics
from treeform.structures import TreeSkeleton

OAK = load_species("oak")


class Sphere:
    """The envelope contract: anything with contains(points (N, 3)) -> (N,) bool."""

    def __init__(self, center, radius):
        self.center, self.radius = np.asarray(center, float), float(radius)

    def contains(self, points):
        return np.linalg.norm(np.asarray(points) - self.center, axis=1) < self.radius


def _mean_shape(params, seeds=range(8)):  # compiled growth: 8 trees cost what 3 did, and the means hold
    ms = [shape_metrics(grow(params, seed=s)) for s in seeds]
    return {k: float(np.mean([m[k] for m in ms])) for k in ms[0]}


def test_every_table3_parameter_is_a_documented_field():
    names = [f.name for f in fields(GrowthParameters)]
    assert len(names) == 29 and set(names) == set(PARAMETER_SYMBOLS)
    assert len(set(PARAMETER_SYMBOLS.values())) == 29
    import inspect

    src = inspect.getsource(GrowthParameters)
    for name in names:  # every field carries a docstring naming its Table-3 symbol
        assert f'{name}:' in src and PARAMETER_SYMBOLS[name] in src.split(f"{name}:")[1].split('"""')[1]


def test_grow_returns_a_valid_skeleton():
    sk = grow(OAK, seed=0)
    assert isinstance(sk, TreeSkeleton)
    n = sk.n_nodes
    assert 1000 < n < 15000
    np.testing.assert_array_equal(sk.positions[0], 0.0)
    assert np.all(sk.parent[1:] < np.arange(1, n)) and sk.parent[0] == -1
    assert np.all(sk.positions[:, 1] >= 0)  # nothing below the ground
    # trunk along +Y, tree a few metres tall, radii by the pipe model (thickest at the base)
    assert sk.positions[:, 1].max() > 5
    assert sk.radius[0] == sk.radius.max() and np.all(sk.radius > 0)
    assert sk.order[0] == 0 and sk.order.max() >= 2
    # age = the growth cycle (year) that created each node, never older than its parent
    assert sk.age.min() == 0 and sk.age.max() == OAK.age - 1
    assert np.all(sk.age[1:] >= sk.age[sk.parent[1:]])
    assert sk.meta["method"] == "phenomenological" and sk.meta["parameters"]["age"] == OAK.age


def test_same_seed_same_tree_different_seed_different_tree(tmp_path):
    a, b, c = grow(OAK, seed=5), grow(OAK, seed=5), grow(OAK, seed=6)
    for name in ("positions", "parent", "radius", "order", "age"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    a.save(tmp_path / "a.json")
    b.save(tmp_path / "b.json")
    assert (tmp_path / "a.json").read_bytes() == (tmp_path / "b.json").read_bytes()
    assert a.n_nodes != c.n_nodes or not np.allclose(a.positions, c.positions)


def test_progress_callback_reports_stages():
    events = []
    grow(replace(OAK, age=3), seed=0, progress=lambda s, e, t: events.append((s, e)))
    assert events == [("grow", "start"), ("grow", "end"), ("structure", "start"), ("structure", "end")]


def test_gravitropism_sign_turns_the_twigs():
    # Table 3: the weight of the direction of gravity -> positive turns shoots down
    down = _mean_shape(replace(OAK, gravitropism_base=0.5, gravitropism_level_factor=0.0))
    up = _mean_shape(replace(OAK, gravitropism_base=-0.5, gravitropism_level_factor=0.0))
    assert down["tip_direction_y"] < 0 < up["tip_direction_y"]
    assert up["slenderness"] > down["slenderness"]


def test_apical_dominance_suppresses_lateral_shoots():
    base = replace(OAK, apical_control_base=1.5, apical_control_age_factor=1.0, apical_dominance_age_factor=1.0,
                   apical_dominance_distance_factor=0.5)
    counts, shapes = [], []
    for adb in (0.0, 8.0):
        p = replace(base, apical_dominance_base=adb)
        counts.append(np.mean([grow(p, seed=s).n_nodes for s in range(8)]))
        shapes.append(_mean_shape(p))
    assert counts[1] < 0.7 * counts[0]
    # fewer laterals shade less, so fewer low branches are shed: the crown reaches lower
    # (over 4 blocks of 8 seeds the crown base falls to 0.38-0.57 of the free-growing tree's)
    assert shapes[1]["crown_base"] < 0.75 * shapes[0]["crown_base"]


def test_apical_control_makes_an_excurrent_tree():
    weak = _mean_shape(replace(OAK, apical_control_base=1.0, apical_control_age_factor=1.0))
    strong = _mean_shape(replace(OAK, apical_control_base=4.0, apical_control_age_factor=1.0))
    assert strong["slenderness"] > 1.5 * weak["slenderness"]
    assert strong["crown_width"] < weak["crown_width"]


def test_apical_control_formula():
    p = GrowthParameters(apical_control_base=3.0, apical_control_age_factor=0.5, apical_control_level_factor=1.0)
    np.testing.assert_allclose(apical_control(p, [0, 1, 2], 0), [1, 1 / 3, 1 / 9])
    np.testing.assert_allclose(apical_control(p, [1], 1), [1 / 1.5])  # C(1) = 3 * 0.5
    # C < 1: decurrent, the outermost shoots grow fastest
    m = apical_control(p, [0, 1, 2, 3], 3, top_level=[2, 2, 2, 2])  # C = 0.375
    assert m[3] == 1.0 and np.all(np.diff(m) > 0)


def test_low_branch_pruning_clears_the_bole():
    bare = grow(replace(OAK, low_branch_pruning_factor=6.0), seed=0)
    free = grow(replace(OAK, low_branch_pruning_factor=0.0), seed=0)

    def forks_below(sk, h):
        return int(np.sum((sk.child_counts() > 1) & (sk.positions[:, 1] < h)))

    assert forks_below(free, 5.0) > 0
    assert forks_below(bare, 5.0) == 0


def test_shade_pruning_sheds_branches():
    keep = np.mean([grow(replace(OAK, pruning_factor=0.0), seed=s).n_nodes for s in range(2)])
    shed = np.mean([grow(replace(OAK, pruning_factor=0.9), seed=s).n_nodes for s in range(2)])
    assert shed < keep


def test_envelope_contract_every_node_inside_a_sphere():
    env = Sphere([0.0, 4.0, 0.0], 5.0)
    for species in ("oak", "willow", "pine"):
        p = load_species(species)
        free = grow(p, seed=0)
        sk = grow(p, seed=0, envelope=env)
        assert sk.n_nodes > 10
        assert env.contains(sk.positions).all(), species
        assert not env.contains(free.positions).all()  # the envelope did constrain growth


def test_envelope_bad_input():
    with pytest.raises(InputError, match="envelope"):
        grow(OAK, envelope=object())
    with pytest.raises(InputError, match="origin"):
        grow(OAK, envelope=Sphere([0, 10, 0], 1))


def test_parameter_validation():
    with pytest.raises(InputError, match="params"):
        grow({"age": 3})
    with pytest.raises(InputError, match="apical_bud_kill_probability"):
        grow(replace(OAK, apical_bud_kill_probability=1.5))
    with pytest.raises(InputError, match="age"):
        grow(replace(OAK, age=0))
    with pytest.raises(InputError, match="growth_rate"):
        GrowthParameters.from_dict({"growth_rate": -1.0}, base=OAK)
    with pytest.raises(InputError, match="unknown name.*colour"):
        GrowthParameters.from_dict({"colour": 1}, base=OAK)
    with pytest.raises(InputError, match="missing"):
        GrowthParameters.from_dict({"age": 3})


def test_edge_cases_young_tree_and_no_lateral_buds():
    sk = grow(replace(OAK, age=1), seed=0)
    assert 2 <= sk.n_nodes <= 10 and np.all(sk.child_counts() <= 1)  # one shoot, no branches yet
    stick = grow(replace(OAK, lateral_buds=0), seed=0)
    assert np.all(stick.child_counts() <= 1)
    # every bud dying at once leaves the tree as it is
    dead = grow(replace(OAK, apical_bud_kill_probability=1.0, lateral_bud_kill_probability=1.0), seed=0)
    assert dead.n_nodes >= 2
