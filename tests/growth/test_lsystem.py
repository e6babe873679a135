"""The L-system of seed 004 §4: grammar, derivation, turtle, presets, dressing a skeleton."""

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.growth.lsystem import (dress_skeleton, interpret, load_preset, lsystem_tree, parse_lsystem,
                                     preset_names)

SPECIES = ("acacia", "apple", "birch", "maple", "oak", "pine", "willow")


def test_parametric_rewriting_with_conditions():
    ls = parse_lsystem("define k = 0.5\naxiom: A(8)\nderivations: 10\nA(x) : x > 1 -> F(x) A(x*k)\nA(x) -> L(x)")
    out = ls.derive()
    assert [m[0] for m in out] == ["F", "F", "F", "L"]
    assert [m[1][0] for m in out] == [8, 4, 2, 1]


def test_first_matching_rule_applies_and_unmatched_modules_are_copied():
    ls = parse_lsystem("axiom: A(1) B X(2)\nderivations: 1\nA(x) : x > 0 -> C\nA(x) -> D\nB -> E E")
    assert [m[0] for m in ls.derive()] == ["C", "E", "E", "X"]


def test_stochastic_rules_follow_their_weights_and_the_seed():
    ls = parse_lsystem("axiom: " + "A " * 2000 + "\nderivations: 1\nA -> 0.8 : B ; 0.2 : C")
    out = ls.derive(seed=3)
    frac = sum(m[0] == "B" for m in out) / len(out)
    assert 0.76 < frac < 0.84
    assert out == ls.derive(seed=3)
    assert out != ls.derive(seed=4)


def test_random_functions_are_seeded():
    ls = parse_lsystem("axiom: A\nderivations: 1\nA -> F(uniform(1, 2)) F(normal(0, 1))")
    a, b = ls.derive(seed=1), ls.derive(seed=1)
    assert a == b and 1 <= a[0][1][0] <= 2


@pytest.mark.parametrize("bad", [
    "axiom: A\nA -> F(__import__('os'))",
    "axiom: A\nA -> F(open)",
    "axiom: A\nA -> F((1).real)",
    "axiom: A\nA -> F(x)",  # unknown name
    "axiom: A(\n",
    "nonsense line",
    "derivations: 3",  # no axiom
    "axiom: A\nA -> 0.5 : B ; C",  # an alternative without its probability
])
def test_bad_grammars_raise_one_clear_error(bad):
    with pytest.raises(InputError):
        parse_lsystem(bad)


def test_defines_can_be_overridden_but_not_invented():
    ls = load_preset("generic", defines={"density": 2.0})
    assert ls.defines["density"] == 2.0
    with pytest.raises(InputError, match="unknown define"):
        load_preset("generic", defines={"nonsense": 1})
    with pytest.raises(InputError):
        load_preset("no-such-species")


def test_string_explosion_is_stopped():
    ls = parse_lsystem("axiom: A\nderivations: 40\nA -> A A")
    with pytest.raises(InputError, match="grew past"):
        ls.derive()


def test_turtle_geometry():
    F = ("F", (1.0,))
    sk, fol = interpret([F, ("&", (90.0,)), F, ("+", (90.0,)), F, ("/", (90.0,)), ("[", ()), ("&", (90.0,)),
                         F, ("]", ()), ("|", ()), F])
    seg = np.diff(sk.positions[[0, 1, 2, 3]], axis=0)
    assert np.allclose(np.linalg.norm(seg, axis=1), 1)
    assert abs(seg[0] @ seg[1]) < 1e-9 and abs(seg[1] @ seg[2]) < 1e-9  # right angles
    assert sk.parent.tolist()[4] == 3 and sk.order[4] == 1  # the bracket opened a branch on node 3
    assert sk.parent[5] == 3 and np.allclose(sk.positions[5], sk.positions[2])  # turned around: back on node 2
    assert len(fol) == 0


def test_tropism_bends_toward_its_vector():
    mods = [("+", (90.0,))] + [("F", (0.2,))] * 30
    straight, _ = interpret(mods)
    droop, _ = interpret(mods, tropism=(0, -1, 0, 0.2))
    assert abs(straight.positions[-1, 1]) < 1e-9
    assert droop.positions[-1, 1] < -1.0


def test_cut_symbol_drops_the_rest_of_the_branch():
    sk, _ = interpret([("F", ()), ("[", ()), ("F", ()), ("%", ()), ("F", ()), ("[", ()), ("F", ()), ("]", ()),
                       ("]", ()), ("F", ())])
    assert sk.n_nodes == 4


def test_a_cut_skips_its_points_and_the_next_point_is_the_right_one():
    """``@T`` points inside a cut branch are skipped with it; the next ``@T`` still draws to its own."""
    sk, _ = interpret([("[", ()), ("F", ()), ("%", ()), ("@T", (5.0, 5.0, 5.0)), ("]", ()), ("@T", (0.0, 3.0, 0.0)),
                       ("@T", (1.0, 3.0, 0.0))])
    assert np.allclose(sk.positions, [[0, 0, 0], [0, 1, 0], [0, 3, 0], [1, 3, 0]])
    assert sk.parent.tolist() == [-1, 0, 0, 2]
    with pytest.raises(InputError, match="without a matching"):
        interpret([("F", ()), ("]", ())])
    with pytest.raises(InputError, match="3 parameters"):
        interpret([("@T", (1.0, 2.0))])


def _plain_derive(ls, seed):
    """Reference: every step rewrites a copy of the whole string (what derive() did before it kept
    the runs no rule rewrites)."""
    import random

    rng = random.Random(seed)
    ls._globals.update(uniform=rng.uniform, normal=rng.gauss, random=rng.random)
    string = list(ls.axiom)
    for _ in range(ls.derivations):
        out, changed = [], False
        for mod in string:
            for rule in ls.rules.get((mod[0], len(mod[1])), ()):
                if rule.cond is not None and not rule.cond(*mod[1]):
                    continue
                k = 0
                if len(rule.choices) > 1:
                    w = [max(float(c[0](*mod[1])), 0.0) for c in rule.choices]
                    r = rng.random() * sum(w) if sum(w) > 0 else 0.0
                    while k < len(w) - 1 and r >= w[k]:
                        r -= w[k]
                        k += 1
                out.extend(rule.choices[k][1](*mod[1]))
                changed = True
                break
            else:
                out.append(mod)
        string = out
        if not changed:
            break
    return string


@pytest.mark.parametrize("name", ("generic", "pine", "willow"))
def test_derive_equals_a_rewrite_of_the_whole_string(name):
    ls = load_preset(name, defines={"density": 2.0})
    for seed in (0, 5):
        assert ls.derive(seed=seed) == _plain_derive(ls, seed)
    stoch = parse_lsystem("axiom: A B A\nderivations: 6\nA -> 0.5 : F A ; 0.5 : [ + F ] B\nB : uniform(0, 1) > 0.3 -> F(1) B")
    assert stoch.derive(seed=2) == _plain_derive(stoch, 2)


def test_at_t_draws_to_points_and_leaves_face_the_turtle():
    sk, fol = interpret([("@T", (1.0, 1.0, 0.0)), ("@T", (1.0, 3.0, 0.0)), ("L", (0.5,))])
    assert np.allclose(sk.positions, [[0, 0, 0], [1, 1, 0], [1, 3, 0]])
    assert np.allclose(fol.positions[0], [1, 3.25, 0])
    assert abs(fol.normals[0] @ fol.up[0]) < 1e-9 and np.allclose(fol.up[0], [0, 1, 0])


@pytest.mark.parametrize("name", SPECIES + ("generic",))
def test_presets_grow_trees_of_their_height(name):
    t = lsystem_tree(name, seed=0)
    sk = t.skeleton
    h = load_preset(name).defines["height"]
    top = sk.positions[:, 1].max()
    assert 0.7 * h < top < 1.15 * h
    assert len(t.foliage) > 200 and sk.n_nodes > 200
    assert sk.radius[0] == sk.radius.max() and sk.radius.min() > 0
    # a crown, not a pole: wider than a tenth of the height
    assert np.ptp(sk.positions[:, 0]) > 0.1 * h
    assert np.all(np.isin(t.foliage.node, np.arange(sk.n_nodes)))


def test_species_presets_differ_and_pine_is_conical():
    pine = lsystem_tree("pine", seed=0).skeleton.positions
    h = pine[:, 1].max()
    low = np.ptp(pine[(pine[:, 1] > 0.3 * h) & (pine[:, 1] < 0.5 * h), 0])
    high = np.ptp(pine[pine[:, 1] > 0.8 * h, 0])
    assert low > 2 * high
    assert lsystem_tree("oak", seed=0).skeleton.n_nodes != lsystem_tree("birch", seed=0).skeleton.n_nodes
    assert set(SPECIES) <= set(preset_names())


def test_same_seed_same_tree():
    a, b = lsystem_tree("maple", seed=5), lsystem_tree("maple", seed=5)
    assert np.array_equal(a.skeleton.positions, b.skeleton.positions)
    assert np.array_equal(a.foliage.positions, b.foliage.positions)
    assert not np.array_equal(a.skeleton.positions, lsystem_tree("maple", seed=6).skeleton.positions)


def _skeleton():
    trunk = np.array([[0, 0, 0], [0, 2, 0], [0, 4, 0], [0, 6, 0], [0, 8, 0.]])
    left = np.array([[0, 4, 0], [-1.5, 5, 0.5], [-3, 6, 1.]])
    right = np.array([[0, 6, 0], [1.5, 7, -0.5], [2.5, 8, -1.]])
    radius = [np.array([0, 0, 1.0, 1.5, 1.0]), np.array([1.2, 1.5, 1.0]), np.array([1.2, 1.4, 0.9])]
    return [trunk, left, right], radius


def test_dress_keeps_the_given_branches_and_fills_their_foliage():
    polys, radius = _skeleton()
    t = dress_skeleton(polys, radius, preset="oak", seed=1)
    pos = t.skeleton.positions
    for p in polys:  # every given point is a node of the tree
        assert np.linalg.norm(pos[None] - p[:, None], axis=2).min(1).max() < 1e-9
    # leaves only where there is foliage: none on the bare lower trunk, none far beyond the radius
    lf = t.foliage.positions
    assert len(lf) > 100 and lf[:, 1].min() > 2.0
    dist = np.min([np.linalg.norm(lf[:, None] - np.concatenate(polys)[None], axis=2).min(1)], axis=0)
    assert np.percentile(dist, 95) < 1.5 * 1.2 + 0.5
    # the right branch hangs on the trunk's node at y = 6
    i = int(np.argmin(np.linalg.norm(pos - [1.5, 7, -0.5], axis=1)))
    j = t.skeleton.parent[i]
    while np.linalg.norm(pos[j] - [0, 6, 0]) > 1e-9 and j > 0:
        j = t.skeleton.parent[j]
    assert np.allclose(pos[j], [0, 6, 0])


def test_dress_density_scales_the_leaves():
    polys, radius = _skeleton()
    n = [len(dress_skeleton(polys, radius, seed=2, defines={"density": d}).foliage) for d in (0.5, 1.0, 2.0)]
    assert n[0] < n[1] < n[2] and n[2] > 2.5 * n[0]


def test_dress_bad_input():
    polys, radius = _skeleton()
    with pytest.raises(InputError):
        dress_skeleton([], [])
    with pytest.raises(InputError):
        dress_skeleton(polys, radius[:2])
    with pytest.raises(InputError):
        dress_skeleton([np.zeros((1, 3))], [np.zeros(1)])
    with pytest.raises(InputError):
        dress_skeleton(polys, radius, parent=[0, 0, 1])
    with pytest.raises(InputError, match="rewrite N"):
        dress_skeleton(polys, radius, preset=parse_lsystem("define leaf_size = 1\ndefine density = 1\naxiom: A"))
