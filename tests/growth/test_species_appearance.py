"""Species appearance: leaf colour, size and leaf type (broadleaf, needles, scales)."""

from __future__ import annotations

import json

import pytest

from treeform._shared.errors import InputError
from treeform.growth.species import SPECIES, load_species_appearance


def test_pine_has_needles_the_others_broadleaves():
    kinds = {name: load_species_appearance(name).leaf_type for name in SPECIES}
    assert kinds.pop("pine") == "needles"
    assert set(kinds.values()) == {"broadleaf"}


def test_a_variant_keeps_its_base_leaf_type_and_can_change_it(tmp_path):
    variant = tmp_path / "blue_pine.json"
    variant.write_text(json.dumps({"base": "pine", "parameters": {}, "appearance": {"leaf_color": [0.2, 0.3, 0.4]}}))
    look = load_species_appearance(variant)
    assert look.leaf_type == "needles" and look.leaf_color == (0.2, 0.3, 0.4)
    assert look.leaf_size == load_species_appearance("pine").leaf_size  # the base's, not the default
    thuja = tmp_path / "thuja.json"
    thuja.write_text(json.dumps({"base": "pine", "parameters": {}, "appearance": {"leaf_type": "scales"}}))
    assert load_species_appearance(thuja).leaf_type == "scales"


def test_bad_leaf_type(tmp_path):
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"base": "oak", "parameters": {}, "appearance": {"leaf_type": "needle"}}))
    with pytest.raises(InputError, match="leaf_type"):
        load_species_appearance(bad)


def test_perception_angle_presets_inheritance_and_bad_values(tmp_path):
    from treeform.growth.species import load_perception_angle

    angles = {name: load_perception_angle(name) for name in SPECIES}
    assert all(10 <= a <= 90 for a in angles.values())
    assert angles["acacia"] < angles["apple"]  # narrow vase vs spreading crown
    variant = tmp_path / "v.json"
    variant.write_text(json.dumps({"base": "acacia", "parameters": {}}))
    assert load_perception_angle(variant) == angles["acacia"]  # the base's
    for bad in (0, 120, "wide"):
        f = tmp_path / "bad.json"
        f.write_text(json.dumps({"base": "oak", "parameters": {}, "perception_angle": bad}))
        with pytest.raises(InputError, match="perception_angle"):
            load_perception_angle(f)


def test_marker_density_presets_and_bad_values(tmp_path):
    from treeform.growth.species import load_marker_density

    d = {name: load_marker_density(name) for name in SPECIES}
    assert all(0 < v < 20 for v in d.values())
    assert d["pine"] > 3 * d["oak"]  # a small dense conifer crown against a large open one
    f = tmp_path / "bad.json"
    f.write_text(json.dumps({"base": "oak", "parameters": {}, "marker_density": -1}))
    with pytest.raises(InputError, match="marker_density"):
        load_marker_density(f)
