"""The seven species presets of seed 003 Table 2: loading, sizes, speed and characters."""

import json
import time

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.growth.phenomenological import GrowthParameters, grow
from treeform.growth.species import SPECIES, load_species, load_species_appearance, species_path
from treeform.methods.learned.grow import shape_metrics

SEEDS = range(5)  # the acceptance uses 30 seeds: benchmarks/bench_growth.py


@pytest.fixture(scope="module")
def shapes():
    """species -> list of shape metrics over SEEDS (and node counts under 'nodes')."""
    out = {}
    for sp in ("acacia", "maple", "oak", "pine", "willow"):
        p = load_species(sp)
        out[sp] = []
        for s in SEEDS:
            sk = grow(p, seed=s)
            out[sp].append({**shape_metrics(sk), "nodes": sk.n_nodes})
    return out


def _mean(rows, key):
    return float(np.mean([r[key] for r in rows]))


def test_table2_values_are_the_presets():
    pine = load_species("pine")
    assert (pine.lateral_buds, pine.branching_angle_mean, pine.apical_control_base, pine.age) == (3, 80.0, 6.2, 15)
    acacia = load_species("acacia")
    assert acacia.apical_bud_kill_probability == 0.9 and acacia.low_branch_pruning_factor == 0.64
    maple = load_species("maple")
    assert maple.apical_control_level_factor == 0.92 and maple.apical_dominance_distance_factor == 0.98


def test_presets_are_package_data_in_json():
    for sp in SPECIES:
        path = species_path(sp)
        assert path.suffix == ".json" and path.is_file()
        d = json.loads(path.read_text())
        assert d["species"] == sp and set(d["parameters"]) == set(GrowthParameters().to_dict())
        look = load_species_appearance(sp)
        assert len(look.leaf_color) == 3 and look.leaf_size > 0


def test_unknown_species_lists_the_known_ones():
    with pytest.raises(InputError) as err:
        load_species("baobab")
    for sp in SPECIES:
        assert sp in str(err.value)


def test_user_file_copy_and_edit(tmp_path):
    d = json.loads(species_path("oak").read_text())
    d["parameters"]["age"] = 4
    path = tmp_path / "my_oak.json"
    path.write_text(json.dumps(d))
    assert load_species(path).age == 4
    assert load_species(str(path)).age == 4
    # a partial file on top of a preset
    partial = tmp_path / "tall_pine.json"
    partial.write_text(json.dumps({"base": "pine", "parameters": {"growth_rate": 4.0}}))
    p = load_species(partial)
    assert p.growth_rate == 4.0 and p.branching_angle_mean == 80.0
    assert load_species_appearance(partial) == load_species_appearance("pine")


@pytest.mark.parametrize("content, match", [
    ({"parameters": {"age": 3}, "colour": "red"}, "unknown key"),
    ({"base": "oak", "parameters": {"leaf_count": 3}}, "unknown name"),
    ({"parameters": {"age": 3}}, "missing"),
    ({"base": "oak", "parameters": {"age": -2}}, "age"),
    ({"base": "oak"}, "parameters"),
])
def test_bad_user_files(tmp_path, content, match):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(content))
    with pytest.raises(InputError, match=match):
        load_species(path)


def test_unreadable_user_files(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        load_species(tmp_path / "missing.json")
    (tmp_path / "x.json").write_text("{not json")
    with pytest.raises(InputError, match="not valid JSON"):
        load_species(tmp_path / "x.json")


def test_every_species_grows_a_plausible_tree_quickly():
    for sp in SPECIES:
        p = load_species(sp)
        t0 = time.perf_counter()
        sk = grow(p, seed=0)
        dt = time.perf_counter() - t0
        # paper 003: 2k-10k branches per tree (the 30-seed ranges are in BENCHMARKS / bench_growth.py)
        assert 1500 <= sk.n_nodes <= 13000, (sp, sk.n_nodes)
        assert 8 < sk.positions[:, 1].max() < 40, sp
        assert dt < 5.0  # generous: the benchmark reports the medians (well under 0.5 s)


def test_pine_is_slender_with_a_strong_leader(shapes):
    assert _mean(shapes["pine"], "slenderness") > 1.5 * _mean(shapes["oak"], "slenderness")
    assert all(r["slenderness"] > 1.8 for r in shapes["pine"])


def test_willow_twigs_hang(shapes):
    assert _mean(shapes["willow"], "tip_direction_y") < -0.3
    assert all(r["tip_direction_y"] < 0 for r in shapes["willow"])


def test_acacia_crown_is_flatter_than_maple(shapes):
    assert _mean(shapes["acacia"], "crown_flatness") < 0.7 * _mean(shapes["maple"], "crown_flatness")


def test_oak_is_broad(shapes):
    assert _mean(shapes["oak"], "slenderness") < 1.4
    assert _mean(shapes["oak"], "crown_width") > 10
