"""Wind sway: rod dynamics per branch, a looping skinned GLB that validates and plays in three.js."""

import base64
import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from treeform._shared.errors import InputError
from treeform.animate import animate_tree, tree_joints, wind_sway
from treeform.structures.rig import Rig

REPO = Path(__file__).resolve().parents[2]
VALIDATOR = REPO / "tools" / "node_modules" / "gltf-validator"


@pytest.fixture(scope="module")
def tree(tmp_path_factory):
    from treeform.methods.learned.grow import grow_tree

    out = tmp_path_factory.mktemp("oak") / "tree"
    grow_tree("oak", seed=3, out=out, lod="low", leaves=1500)
    return out


@pytest.fixture(scope="module")
def animated(tree):
    return animate_tree(tree, wind=10.0, seconds=2.0, fps=15, seed=1)


def test_the_sway_keeps_branches_attached_and_loops(animated, tree):
    res = animated
    assert Path(res["path"]) == tree / "tree_animated.glb" and Path(res["path"]).stat().st_size > 1000
    assert res["frames"] == 30 and res["period"] == pytest.approx(2.0) and res["joints"] > 10
    assert res["skeleton_stretch"] < 1e-9  # every branch turns about the node it grows from
    assert res["mesh_stretch"] < 0.05      # tubes bend smoothly through their joints (blended weights)
    assert res["loop_gap"] == 0.0          # the last pose is the first: no jump when the clip loops
    assert 0.0 < res["trunk_motion"] < res["tip_motion"] < 2.0  # the twigs move more than the trunk


def test_stiffer_trunk_bends_less_and_wind_scales_the_sway(tree):
    from treeform.structures.skeleton import TreeSkeleton

    sk = TreeSkeleton.load(tree / "skeleton.json")
    j = tree_joints(sk, max_joints=48)
    assert j.parent[0] == -1 and np.all(j.parent[1:] < np.arange(1, j.n_joints))
    assert set(np.unique(j.node_joint)) == set(range(j.n_joints))
    slow = wind_sway(sk, j, wind=4.0, seconds=2.0, fps=10, seed=0)
    fast = wind_sway(sk, j, wind=12.0, seconds=2.0, fps=10, seed=0)
    angle = lambda r: 2 * np.arccos(np.clip(np.abs(r.rotations[..., 3]), 0, 1))  # noqa: E731
    assert angle(fast).max() > 3 * angle(slow).max()
    again = wind_sway(sk, j, wind=12.0, seconds=2.0, fps=10, seed=0)
    assert np.array_equal(again.rotations, fast.rotations)  # same seed, same sway
    other = wind_sway(sk, j, wind=12.0, seconds=2.0, fps=10, seed=1)
    assert not np.array_equal(other.rotations, fast.rotations)
    # the wind turns branches about the horizontal axis across it: with the wind along +X the
    # rotation axes lie in the Y-Z plane... mostly about Z
    q = fast.rotations[..., :3]
    assert np.abs(q[..., 2]).sum() > 3 * np.abs(q[..., 0]).sum()


def test_rig_and_options_are_checked(tree):
    with pytest.raises(InputError, match="wind"):
        animate_tree(tree, wind=0)
    with pytest.raises(InputError, match="fps"):
        animate_tree(tree, fps=0)
    with pytest.raises(InputError, match="not a folder"):
        animate_tree(tree / "skeleton.json")
    with pytest.raises(InputError, match="no tree.glb"):
        animate_tree(tree.parent)
    with pytest.raises(InputError, match=".glb"):
        animate_tree(tree, out=tree / "x.obj")
    with pytest.raises(InputError, match="unit quaternions"):
        Rig(np.zeros((1, 3)), [-1], [0.0, 1.0], np.zeros((2, 1, 4)))


def test_cli_one_line_on_bad_input(tmp_path):
    import sys
    sys.path.insert(0, str(REPO / "tests" / "cli"))
    from cli_helpers import assert_clean_failure, cli

    assert_clean_failure(cli("animate", tmp_path / "none"))
    assert_clean_failure(cli("animate", tmp_path, "--wind", "-2"))


@pytest.mark.skipif(not (VALIDATOR / "package.json").exists() or shutil.which("node") is None,
                    reason="Khronos glTF validator not installed (make validator)")
def test_the_animated_glb_passes_the_khronos_validator(animated):
    script = ("const v=require('gltf-validator');const fs=require('fs');"
              f"v.validateBytes(new Uint8Array(fs.readFileSync({json.dumps(animated['path'])})))"
              ".then(r=>console.log(JSON.stringify(r.issues)))")
    proc = subprocess.run(["node", "-e", script], capture_output=True, text=True, timeout=120,
                          cwd=VALIDATOR.parent.parent)
    issues = json.loads(proc.stdout)
    assert issues["numErrors"] == 0, [m for m in issues["messages"] if m["severity"] == 0][:5]


def test_three_js_plays_the_clip(animated, tmp_path, browser):
    """three.js loads the GLB as a skinned mesh; frames at different times differ, the loop's end equals its start."""
    assets = REPO / "src" / "treeform" / "report" / "assets"
    shutil.copy(assets / "three-modules.js", tmp_path / "three-modules.js")
    glb64 = base64.b64encode(Path(animated["path"]).read_bytes()).decode()
    (tmp_path / "glb.js").write_text(f"window.GLB='{glb64}';")
    (tmp_path / "page.html").write_text("""<!doctype html><html><body style="margin:0">
<canvas id="c" width="256" height="256"></canvas>
<script src="three-modules.js"></script><script src="glb.js"></script><script>
(function () {
  const THREE = __tf_require('three');
  const { GLTFLoader } = __tf_require('three/addons/loaders/GLTFLoader.js');
  const bytes = Uint8Array.from(atob(window.GLB), c => c.charCodeAt(0));
  const renderer = new THREE.WebGLRenderer({ canvas: document.getElementById('c'), preserveDrawingBuffer: true });
  const scene = new THREE.Scene(); scene.background = new THREE.Color(0xffffff);
  scene.add(new THREE.HemisphereLight(0xffffff, 0x444444, 2.0));
  new GLTFLoader().parse(bytes.buffer, '', function (gltf) {
    scene.add(gltf.scene);
    const box = new THREE.Box3().setFromObject(gltf.scene), c = box.getCenter(new THREE.Vector3());
    const h = box.getSize(new THREE.Vector3()).y;
    const camera = new THREE.PerspectiveCamera(30, 1, 0.05, 1000);
    camera.position.set(c.x, c.y, c.z + 2.2 * h); camera.lookAt(c);
    let skinned = 0; gltf.scene.traverse(o => { if (o.isSkinnedMesh) skinned += 1; });
    const clip = gltf.animations[0], mixer = new THREE.AnimationMixer(gltf.scene);
    mixer.clipAction(clip).play();
    const shot = function (t) {
      mixer.setTime(t); renderer.render(scene, camera);
      const gl = renderer.getContext(), px = new Uint8Array(256 * 256 * 4);
      gl.readPixels(0, 0, 256, 256, gl.RGBA, gl.UNSIGNED_BYTE, px);
      return px;
    };
    const diff = function (a, b) {
      let n = 0;
      for (let i = 0; i < a.length; i += 4) if (Math.abs(a[i] - b[i]) + Math.abs(a[i + 1] - b[i + 1]) > 30) n++;
      return n;
    };
    const a = shot(0), b = shot(0.37 * clip.duration), e = shot(clip.duration - 1e-4);
    window.result = { skinned: skinned, duration: clip.duration, tracks: clip.tracks.length,
                      moved: diff(a, b), loop: diff(a, e), drawn: diff(a, new Uint8Array(a.length).fill(255)) };
  }, function (err) { window.result = { error: String(err) }; });
})();
</script></body></html>""")
    page = browser.new_page(viewport={"width": 300, "height": 300})
    errors = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto((tmp_path / "page.html").as_uri())
    page.wait_for_function("window.result", timeout=120_000)
    res = page.evaluate("window.result")
    assert not errors and "error" not in res, (errors, res)
    assert res["skinned"] >= 1 and res["duration"] == pytest.approx(animated["period"], abs=1e-3)
    assert res["tracks"] == animated["joints"]
    assert res["drawn"] > 2000            # the tree is on screen
    assert res["moved"] > 50              # and it moves
    assert res["loop"] < 0.2 * res["moved"]  # the end of the loop is (nearly) its start
