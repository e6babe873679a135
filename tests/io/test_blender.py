"""A reconstructed tree opened in a real client: Blender's glTF importer and Cycles (the `bpy` module).

Blender's module pins its own numpy, so it lives in its own environment (`make blender`
makes `.venv-blender`; `TREEFORM_BLENDER_PYTHON` may name another interpreter). Without one
the test is skipped.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


def _blender_python() -> str | None:
    cand = os.environ.get("TREEFORM_BLENDER_PYTHON") or str(ROOT / ".venv-blender" / "bin" / "python")
    if not Path(cand).exists():
        return None
    ok = subprocess.run([cand, "-c", "import bpy"], capture_output=True, timeout=120)
    return cand if ok.returncode == 0 else None


@pytest.fixture(scope="module")
def blender_facts(tmp_path_factory):
    py = _blender_python()
    if py is None:
        pytest.skip("no Python with Blender's bpy module (make blender)")
    from treeform.methods.envelope.pipeline import reconstruct

    out = tmp_path_factory.mktemp("blender")
    photo = ROOT / "src" / "treeform" / "data" / "Celtis_occidentalis_1.jpg"
    reconstruct(photo, out=out / "tree", seed=0, leaves=2000, lod="low", max_size=320)
    facts = out / "facts.json"
    subprocess.run([py, str(ROOT / "scripts" / "blender_view.py"), str(out / "tree" / "tree.glb"), "--json",
                    str(facts), "--render", str(out / "render"), "--views", "front,side", "--size", "96",
                    "--samples", "4"], check=True, capture_output=True, timeout=600)
    return json.loads(facts.read_text())


def test_blender_imports_at_scale_and_upright(blender_facts):
    lo, hi = blender_facts["bbox_min"], blender_facts["bbox_max"]
    # Blender is Z-up: treeform's Y-up metres arrive standing on the ground, 10 m tall
    assert abs(lo[2]) < 0.1
    assert 9.5 < hi[2] - lo[2] < 10.6
    assert hi[2] - lo[2] > max(hi[0] - lo[0], hi[1] - lo[1])


def test_blender_materials_textured_alpha_cut_and_normal_mapped(blender_facts):
    mats = {m["name"]: m for m in blender_facts["materials"]}
    assert set(mats) == {"bark", "leaves"}
    assert mats["leaves"]["base_color_image"] and min(mats["leaves"]["base_color_image"]) >= 64
    assert mats["leaves"]["alpha_linked"], "leaf cards must be alpha-cut"
    assert mats["bark"]["base_color_image"] and mats["bark"]["normal_map"]


def test_blender_no_inside_out_faces(blender_facts):
    for obj in blender_facts["objects"]:
        assert obj["faces"] > 0
        assert obj["inside_out"] < 0.001, obj


@pytest.mark.parametrize("view", ["front", "side"])
def test_blender_cycles_render_is_a_lit_green_tree(blender_facts, view):
    r = blender_facts["renders"][view]
    assert r["tree_pixels"] > 500
    assert r["black_share"] < 0.05
    red, green, blue = r["mean_rgb"]
    assert green > red and green > blue  # the photo's summer crown, not grey cards


def test_blender_plays_the_wind_animation(tmp_path):
    """`treeform animate`'s GLB in Blender: an armature, one action, the skinned mesh sways and loops."""
    py = _blender_python()
    if py is None:
        pytest.skip("no Python with Blender's bpy module (make blender)")
    from treeform.animate import animate_tree
    from treeform.methods.learned.grow import grow_tree

    grow_tree("oak", seed=3, out=tmp_path / "oak", lod="low", leaves=1500)
    res = animate_tree(tmp_path / "oak", wind=12.0, seconds=2.0, fps=12)
    facts = tmp_path / "facts.json"
    subprocess.run([py, str(ROOT / "scripts" / "blender_view.py"), res["path"], "--json", str(facts)],
                   check=True, capture_output=True, timeout=600)
    anim = json.loads(facts.read_text())["animation"]
    assert anim["armatures"] == 1 and len(anim["actions"]) >= 1
    assert anim["moved"] > 0.01                       # metres: the crown sways
    assert anim["loop_gap"] < 0.2 * anim["moved"]     # the clip's end is its start


if __name__ == "__main__":  # pragma: no cover
    sys.exit(pytest.main([__file__, "-v"]))
