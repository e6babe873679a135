"""Several trees in one photo: instances, their placement on the ground, `reconstruct --all-trees` (issue 16 item 2)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.methods.scene.placement import place_on_ground
from treeform.segment.instances import split_at_trunks, trunk_feet

from treeform.data import GROUP_TREES

EXE = Path(sys.executable).parent / "treeform"
FEET = np.array([(x, z) for _, x, z, _ in GROUP_TREES])  # x right, z ahead (m); at least 5 m apart
HEIGHTS = np.array([h for *_, h in GROUP_TREES])


@pytest.fixture(scope="module")
def group():
    """The sample group photo (three library trees 15-19 m ahead of a level camera 1.6 m up) and its truth."""
    from treeform.data import data_path, group_photo
    from treeform.dataset.scenes import group_scene, load_cutouts

    sprites = {s.name: s for s in load_cutouts(data_path("library"))}
    truth = group_scene([sprites[n] for n, *_ in GROUP_TREES], FEET, HEIGHTS, np.random.default_rng(0))
    assert np.array_equal(truth["image"], group_photo())
    return truth


def test_feet_are_where_trunks_meet_the_ground_not_where_a_crown_hangs():
    m = np.zeros((80, 100), bool)
    m[5:40, 10:90] = True       # one wide crown over two trunks
    m[40:70, 28:32] = True      # trunk 1
    m[40:66, 68:72] = True      # trunk 2
    m[38:50, 76:92] = True      # a hanging lobe at the crown's edge: wide at once above its lowest point
    m[40:52, 44:56] = True      # a low bulge of the crown between the trunks
    feet = trunk_feet(m)
    assert [f for _, f in feet] == [(29.5, 69.0), (69.5, 65.0)]
    left, right = split_at_trunks(m, feet)
    assert left[20, 12] and right[20, 88] and not (left & right).any() and ((left | right) == m).all()
    wood = np.zeros_like(m)
    wood[20:50, 82:86] = True   # ... unless wood rises from the lobe: a trunk in front of the crown
    assert len(trunk_feet(m, wood)) == 3


def test_two_trunks_close_together_are_two_feet_but_a_root_flare_is_one():
    """Two lowest points a trunk's width apart are one foot only where the mask joins them just above
    (a flare at the base); a near tree and one just behind it stand apart up to their crowns."""
    m = np.zeros((120, 100), bool)
    m[5:50, 10:90] = True       # the crowns, one piece
    m[50:110, 40:43] = True     # a trunk to the ground
    m[50:104, 50:53] = True     # a second one 10 px beside it, standing a little farther back
    feet = [f for _, f in trunk_feet(m)]
    assert feet == [(41.0, 109.0), (51.0, 103.0)]
    one = np.zeros_like(m)
    one[5:50, 10:90] = True
    one[50:105, 42:48] = True   # one trunk whose foot flares into two lowest points, 7 px apart
    one[104:110, 40:43] = True
    one[104:108, 47:50] = True
    assert [f for _, f in trunk_feet(one)] == [(41.0, 109.0)]


def test_a_learned_foot_on_a_rule_foots_trunk_is_that_foot_and_the_rules_stays():
    """``--feet both``: the detector's foot a little aside on one wide, flared trunk is the rules'
    foot (it split single trees into strips: Ulmus americana 1 four instances, now two), while a
    learned foot under a trunk of its own still makes a tree."""
    from treeform.segment.instances import merge_joined_feet
    from treeform.segment.learned_feet import union_feet

    m = np.zeros((120, 100), bool)
    m[5:50, 10:90] = True       # the crowns, one piece
    m[50:108, 38:46] = True     # a wide trunk, flaring at its foot
    m[104:110, 36:48] = True
    m[50:104, 70:73] = True     # a second trunk, standing apart
    rules = trunk_feet(m)
    assert [f for _, f in rules] == [(41.5, 109.0), (71.0, 103.0)]
    m[60:100, 20:23] = True     # a third, thin one, hanging: the rules see no foot at its end
    mark = lambda u, v: np.pad(np.ones((3, 3), bool), ((v - 2, 119 - v), (u - 1, 98 - u)))  # noqa: E731
    learned = [(mark(47, 109), (47.0, 109.0), 0.6), (mark(21, 99), (21.0, 99.0), 0.5)]
    both = union_feet(rules, learned, 2.0, 2.0)
    assert len(both) == 4  # 5.5 px aside: the plain tolerance keeps the flare's foot as another tree
    feet = [f for _, f in merge_joined_feet(m, both, fixed=len(rules))]
    assert feet == [(21.0, 99.0), (41.5, 109.0), (71.0, 103.0)]  # the flare's learned foot joins the rules'
    # among feet of one kind, the lower of two joined ones stays
    assert [f for _, f in merge_joined_feet(m, [(rules[0][0], (41.5, 108.0)), both[2]])] == [(47.0, 109.0)]


def test_a_thin_trunk_the_mask_cut_keeps_its_crown_and_its_learned_foot():
    """A thin trunk over a lawn that the mask lost twice: its lowest stretch (the detector saw the
    trunk go on down: its foot, far below the rules', stays) and a few rows under the crown (the
    split still hands that crown to this trunk, not to the neighbour whose crown it touches)."""
    from treeform.segment.instances import merge_joined_feet

    m = np.zeros((120, 120), bool)
    m[10:40, 10:50] = True      # the thin trunk's crown ...
    m[15:50, 45:110] = True     # ... touching a big neighbour's crown
    m[43:80, 29:31] = True      # the thin trunk: a gap of 3 rows under its crown, its lowest 30 rows lost
    m[50:110, 76:80] = True     # the neighbour's trunk
    rules = trunk_feet(m)
    assert [f for _, f in rules] == [(29.5, 79.0), (77.5, 109.0)]
    learned = (np.pad(np.ones((3, 3), bool), ((107, 10), (28, 89))), (29.0, 109.0))
    feet = merge_joined_feet(m, [*rules, learned], fixed=len(rules))
    assert [f for _, f in feet] == [(29.0, 109.0), (77.5, 109.0)]
    import scipy.ndimage as ndi

    thin, big = split_at_trunks(m, feet, within=ndi.binary_dilation(m, iterations=4))  # the clustering's reach
    assert thin[20, 15] and thin[25, 40] and big[25, 100] and ((thin | big) == m).all() and not (thin & big).any()
    inside_only = split_at_trunks(m, feet)[0]
    assert not inside_only[20, 15]  # grown inside the mask only, the crown went to the neighbour


def test_the_ground_placement_puts_every_foot_back_on_its_pixel():
    rng = np.random.default_rng(3)
    feet = np.c_[rng.uniform(50, 590, 6), rng.uniform(250, 470, 6)]
    tops = feet[:, 1] - rng.uniform(60, 200, 6)
    p = place_on_ground(feet, tops, 640, 480, camera_height=1.7)
    uv = p.camera.project(p.positions)[:, :2]
    assert np.abs(uv - feet).max() < 1e-3 and np.allclose(p.positions[:, 1], 0)
    assert abs(p.camera.position[1] - 1.7) < 1e-9 and np.allclose(p.positions[p.reference], 0)
    tops_uv = p.camera.project(p.positions + np.c_[np.zeros(6), p.heights, np.zeros(6)])[:, 1]
    assert np.abs(tops_uv - (tops - 1)).max() < 1.0  # each top row, from the tree's height
    # a given tree height sets the scale instead: everything scales with it
    q = place_on_ground(feet, tops, 640, 480, main_height=2 * p.heights[p.reference])
    assert np.allclose(q.positions, 2 * p.positions) and abs(q.camera_height - 3.4) < 1e-9
    with pytest.raises(InputError, match="top"):
        place_on_ground([[10, 100]], [120], 640, 480)


def test_one_foot_above_the_horizon_does_not_move_the_other_trees():
    # a level camera (horizon at the middle row, 240): three feet on the lawn and a false one in a
    # crown above the horizon. It used to lift the horizon over itself and push every tree away.
    feet = np.array([[100.0, 400.0], [320.0, 330.0], [520.0, 360.0]])
    tops = feet[:, 1] - 150.0
    p = place_on_ground(feet, tops, 640, 480, camera_height=1.6, reference=0)
    q = place_on_ground(np.vstack([feet, [[600.0, 200.0]]]), np.r_[tops, 120.0], 640, 480,
                        camera_height=1.6, reference=0)
    assert p.horizon_row == q.horizon_row == 240.0
    assert np.allclose(q.positions[:3], p.positions) and np.allclose(q.distances[:3], p.distances)
    assert q.distances[3] >= p.distances.max() and np.isfinite(q.positions).all()   # placed far, not behind the camera
    # with the camera tilted up the feet are high: the horizon rises above all but the highest, the
    # nearer feet stand nearer
    up = place_on_ground(feet - [0, 150], tops - 150, 640, 480, camera_height=1.6, reference=0)
    assert up.horizon_row < 210 and up.distances[0] < up.distances[2] <= up.distances[1]


def test_every_tree_of_a_group_is_found_and_placed_within_a_tenth_of_their_spacing(group):
    from treeform.segment.instances import find_tree_instances

    inst = find_tree_instances(group["image"])
    assert len(inst) == 3
    feet = np.array([t.base for t in inst])
    order = np.argsort(group["feet_px"][:, 0])
    assert np.abs(feet - group["feet_px"][order]).max() < 0.02 * 960
    overlap = [(t.mask & (group["instances"] == k + 1)).sum() / t.mask.sum() for t, k in zip(inst, order)]
    assert min(overlap) > 0.7  # each instance is mostly its own tree (crowns that touch split halfway)
    p = place_on_ground(feet, [t.top for t in inst], 960, 720, camera_height=1.6)
    ref = order[p.reference]
    truth = np.c_[FEET[:, 0] - FEET[ref, 0], np.zeros(3), FEET[ref, 1] - FEET[:, 1]][order]
    spacing = min(np.linalg.norm(FEET[i] - FEET[j]) for i in range(3) for j in range(i))
    assert np.linalg.norm(p.positions - truth, axis=1).max() < 0.1 * spacing
    assert np.abs(p.heights - HEIGHTS[order]).max() < 0.1 * HEIGHTS.min()


@pytest.fixture(scope="module")
def scene_run(group, tmp_path_factory):
    from PIL import Image

    tmp = tmp_path_factory.mktemp("scene")
    Image.fromarray(group["image"]).save(tmp / "group.png")
    proc = subprocess.run([str(EXE), "reconstruct", str(tmp / "group.png"), "--all-trees", "--leaves", "1500",
                           "--lod", "low", "--out", str(tmp / "out")], capture_output=True, text=True, timeout=600)
    return proc, tmp / "out"


def test_reconstruct_all_trees_writes_a_placed_scene(scene_run):
    import trimesh

    proc, out = scene_run
    assert proc.returncode == 0, proc.stderr
    meta = json.loads((out / "scene.json").read_text())
    assert meta["trees_found"] == meta["trees_reconstructed"] == 3
    for row in meta["trees"]:
        assert (out / row["folder"] / "tree.glb").is_file() and (out / row["folder"] / "preview.png").is_file()
    assert (out / "preview.png").is_file()
    gltf = json.loads(_glb_json(out / "scene.glb"))
    nodes = {n["name"]: n for n in gltf["nodes"]}
    for row in meta["trees"]:  # each tree's node stands where scene.json says, turned to the camera
        node = nodes[f"tree_{row['tree']}"]
        assert np.allclose(node.get("translation", [0, 0, 0]), row["position_m"], atol=1e-3)
        yaw = 2 * np.degrees(np.arctan2(node.get("rotation", [0, 0, 0, 1])[1], node.get("rotation", [0, 0, 0, 1])[3]))
        assert abs(yaw - row["yaw_deg"]) < 0.01
    scene = trimesh.load(out / "scene.glb")
    assert len(scene.geometry) >= 3
    lo, hi = scene.bounds
    assert lo[1] > -0.5 and hi[1] > 5.0  # on the ground, trees several metres tall


def test_the_scene_glb_passes_the_khronos_validator(scene_run, khronos_report):
    report = khronos_report(scene_run[1] / "scene.glb")
    assert report["numErrors"] == 0 and report["numWarnings"] == 0, report["messages"][:5]


def test_all_trees_refuses_a_mask_and_finds_nothing_in_a_wall(tmp_path):
    from PIL import Image

    wall = np.full((240, 320, 3), (150, 120, 100), np.uint8)
    wall[::12] = 90  # mortar lines
    Image.fromarray(wall).save(tmp_path / "wall.png")
    proc = subprocess.run([str(EXE), "reconstruct", str(tmp_path / "wall.png"), "--all-trees", "--mask",
                           str(tmp_path / "wall.png"), "--out", str(tmp_path / "a")], capture_output=True, text=True)
    assert proc.returncode == 2 and proc.stderr.strip().startswith("error: --mask") and len(proc.stderr.splitlines()) == 1
    proc = subprocess.run([str(EXE), "reconstruct", str(tmp_path / "wall.png"), "--all-trees", "--out",
                           str(tmp_path / "b")], capture_output=True, text=True)
    assert proc.returncode != 0 and "no tree found" in proc.stderr.splitlines()[-1]
    assert "Traceback" not in proc.stderr and not (tmp_path / "b").exists()
    proc = subprocess.run([str(EXE), "reconstruct", str(tmp_path / "wall.png"), "--camera-height", "2",
                           "--out", str(tmp_path / "c")], capture_output=True, text=True)
    assert proc.returncode == 2 and proc.stderr.strip() == "error: --camera-height works with --all-trees"


def _glb_json(path: Path) -> str:
    import struct

    data = path.read_bytes()
    n = struct.unpack_from("<I", data, 12)[0]
    return data[20:20 + n].decode()


if shutil.which(str(EXE)) is None and not EXE.exists():  # pragma: no cover - the console script is installed
    pytest.skip("treeform console script missing", allow_module_level=True)


def test_a_trunk_foot_goes_down_to_where_the_bark_meets_the_lawn():
    from treeform.segment.instances import trunk_end

    img = np.zeros((40, 40, 3), np.uint8)
    img[:] = (60, 140, 50)                       # lawn
    img[5:30, 19:21] = (110, 95, 80)             # a trunk 2 px wide, its foot at row 29
    m = np.zeros((40, 40), bool)
    m[5:26, 19:21] = True                        # the mask stops 4 rows short
    assert trunk_end(img, m, (19.5, 25.0), max_rows=8) == (19.5, 29.0)
    assert trunk_end(img, m, (19.5, 25.0), max_rows=3)[1] == 28.0          # no farther than asked
    # a trunk leaning a pixel per row is followed; a lawn the trunk's colour gives nothing to follow
    lean = img.copy()
    lean[26:30, 19:21] = (60, 140, 50)
    for r in range(26, 30):
        lean[r, 19 + (r - 25):21 + (r - 25)] = (110, 95, 80)
    assert trunk_end(lean, m, (19.5, 25.0), max_rows=8) == (22.5, 29.0)   # along its left edge
    same = np.full_like(img, (110, 95, 80))
    assert trunk_end(same, m, (19.5, 25.0), max_rows=8) == (19.5, 25.0)
