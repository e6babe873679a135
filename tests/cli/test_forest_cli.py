"""`treeform forest`: a small forest of two species with the LoD switch and its full-mesh baseline; bad inputs fail cleanly."""

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import assert_clean_failure, cli
from PIL import Image

SKY = np.array([184, 209, 237])


@pytest.fixture(scope="module")
def species(tmp_path_factory):
    root = tmp_path_factory.mktemp("forest") / "species"
    for name, seed in (("oak", 2), ("pine", 3)):
        proc = cli("grow", "--species", name, "--seed", str(seed), "--lod", "low", "--out", root / name)
        assert proc.returncode == 0, proc.stderr
        proc = cli("impostor", root / name, "--face", "64", "--rdm-resolution", "32")
        assert proc.returncode == 0, proc.stderr
    return root


def _trees(img):
    """Pixels that are neither sky nor bare ground."""
    img = img[..., :3].astype(int)
    return (np.abs(img - SKY).sum(2) > 30) & (np.abs(img - [84, 97, 56]).sum(2) > 40)


def test_forest_with_baseline(species, gl, tmp_path):
    out = tmp_path / "f"
    args = ("forest", "--species-dir", species, "--out", out, "--trees", "600", "--area", "240x240",
            "--size", "192x108", "--frames", "2", "--switch-distance", "60", "--seed", "3")
    proc = cli(*args, "--baseline", "--glb")
    assert proc.returncode == 0, proc.stderr
    assert "600 trees" in proc.stdout
    names = {p.name for p in (out / "frames").iterdir()}
    assert names == {"frame_000.png", "frame_001.png", "baseline_000.png", "baseline_001.png"}
    assert {p.name for p in out.iterdir()} == {"frames", "contact_sheet.png", "timing.json", "instances.npy",
                                               "config.json", "forest.glb"}
    t = json.loads((out / "timing.json").read_text())
    for f in t["per_frame"]:
        # crowns under 32 px on screen (most far trees in a 192 x 108 frame) are impostor cards
        assert f["near"] + f["far"] + f["cards"] == f["visible"] and 0 < f["near"] < f["visible"] <= 600
        assert f["cards"] > f["far"]
        assert 16 * f["near"] <= f["billboards"] <= 144 * f["near"]
        assert f["ms"] > 0 and f["baseline_ms"] > 0
    assert t["speedup"] == pytest.approx(t["baseline_ms_per_frame"] / t["ms_per_frame"], rel=0.02)
    assert set(t["memory_per_species_bytes"]) == {"oak", "pine"}
    assert all(m["total"] < 10 * 2**20 for m in t["memory_per_species_bytes"].values())
    inst = np.load(out / "instances.npy")
    assert inst.shape == (600, 7) and set(np.unique(inst[:, 6])) == {0.0, 1.0}
    assert np.abs(inst[:, [0, 2]]).max() <= 120
    for k in range(2):
        lod = np.asarray(Image.open(out / "frames" / f"frame_{k:03d}.png"))
        full = np.asarray(Image.open(out / "frames" / f"baseline_{k:03d}.png"))
        a, b = _trees(lod), _trees(full)
        assert a.mean() > 0.2  # a forest, not a blank frame
        assert (a & b).sum() / (a | b).sum() > 0.8  # the LoD frame shows the trees the full meshes show
        # ... in about their colours (the levels are lit alike)
        ratio = lod[..., :3][a & b].astype(float).mean(0) / full[..., :3][a & b].astype(float).mean(0)
        print("LoD / full mean colour", ratio)
        assert np.all(np.abs(ratio - 1) < 0.2), ratio
    # the forest for engines: the ground plus one instanced node per species, every tree placed as scattered
    from treeform.io.gltf import accessor_array, read_glb

    gltf, bin_chunk = read_glb(out / "forest.glb")
    assert gltf["extensionsRequired"] == ["EXT_mesh_gpu_instancing"]
    assert "KHR_materials_unlit" in gltf["extensionsUsed"]
    placed = []
    for node in gltf["nodes"][1:]:
        attrs = node["extensions"]["EXT_mesh_gpu_instancing"]["attributes"]
        t, r, s = (accessor_array(gltf, bin_chunk, attrs[k]) for k in ("TRANSLATION", "ROTATION", "SCALE"))
        assert np.allclose(np.linalg.norm(r, axis=1), 1, atol=1e-5) and np.allclose(r[:, [0, 2]], 0)
        placed.append(np.column_stack([t, s[:, 0], 2 * np.arctan2(r[:, 1], r[:, 3])]))
    placed = np.concatenate(placed)
    want = np.concatenate([inst[inst[:, 6] == k, :5] for k in (0, 1)]).astype(np.float64)
    assert np.allclose(placed[:, :4], want[:, :4], atol=1e-4)
    assert np.allclose(np.angle(np.exp(1j * (placed[:, 4] - want[:, 4]))), 0, atol=1e-4)  # the same turn
    validator = Path(__file__).resolve().parents[2] / "tools" / "gltf_validate.mjs"
    if shutil.which("node") and (validator.parent / "node_modules" / "gltf-validator").is_dir():
        rep = json.loads(subprocess.run(["node", str(validator), str(out / "forest.glb")], capture_output=True,
                                        text=True, timeout=120).stdout)
        assert rep["numErrors"] == 0 and rep["numWarnings"] == 0, rep["messages"]
    # Blender's glTF importer turns the instanced nodes into one object per tree
    blender = Path(__file__).resolve().parents[2] / ".venv-blender" / "bin" / "python"
    if blender.exists():
        script = ("import bpy, sys\nbpy.ops.wm.read_factory_settings(use_empty=True)\n"
                  "bpy.ops.import_scene.gltf(filepath=sys.argv[-1])\n"
                  "print('TREES', sum(o.type == 'MESH' and o.data.name in ('oak', 'pine') for o in bpy.context.scene.objects))")
        proc = subprocess.run([str(blender), "-c", script, str(out / "forest.glb")], capture_output=True, text=True,
                              timeout=300)
        assert "TREES 600" in proc.stdout, proc.stdout[-2000:] + proc.stderr[-2000:]
    # same seed, same scatter and frames
    proc = cli(*args[:4], tmp_path / "again", *args[5:])
    assert proc.returncode == 0, proc.stderr
    assert np.array_equal(np.load(tmp_path / "again" / "instances.npy"), inst)
    assert (tmp_path / "again" / "frames" / "frame_001.png").read_bytes() == (out / "frames" / "frame_001.png").read_bytes()
    # without the card tier every far tree is marched; the cards stand in for those crowns closely
    proc = cli(*args[:4], tmp_path / "relief", *args[5:], "--card-px", "0")
    assert proc.returncode == 0, proc.stderr
    t0 = json.loads((tmp_path / "relief" / "timing.json").read_text())
    assert all(f["cards"] == 0 and f["near"] + f["far"] == f["visible"] for f in t0["per_frame"])
    mem = json.loads((out / "timing.json").read_text())["memory_per_species_bytes"]
    assert "impostor_cards" in mem["oak"]
    assert "impostor_cards" not in t0["memory_per_species_bytes"]["oak"]
    for k in range(2):
        cards = np.asarray(Image.open(out / "frames" / f"frame_{k:03d}.png"))
        relief = np.asarray(Image.open(tmp_path / "relief" / "frames" / f"frame_{k:03d}.png"))
        a, b = _trees(cards), _trees(relief)
        assert (a & b).sum() / (a | b).sum() > 0.85
        ratio = cards[..., :3][a & b].astype(float).mean(0) / relief[..., :3][a & b].astype(float).mean(0)
        assert np.all(np.abs(ratio - 1) < 0.12), ratio


def test_forest_page_in_headless_chromium(species, gl, tmp_path, browser):
    """--html: three.js draws the forest with the renderer's shaders (GLSL ES), relief far and clouds near,
    no console error, not a blank canvas."""
    out = tmp_path / "web"
    proc = cli("forest", "--species-dir", species, "--out", out, "--trees", "300", "--area", "200x200",
               "--size", "64x36", "--frames", "1", "--switch-distance", "60", "--html")
    assert proc.returncode == 0, proc.stderr
    assert {"forest.html", "forest_data.js", "assets"} <= {p.name for p in out.iterdir()}
    page = browser.new_page(viewport={"width": 480, "height": 300})
    errors = []
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.goto((out / "forest.html").as_uri())
    page.wait_for_function("window.treeformViewerState.done || window.treeformViewerState.error", timeout=120_000)
    state = page.evaluate("window.treeformViewerState")
    page.evaluate("() => new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
    page.locator("#tf-viewer").screenshot(path=str(tmp_path / "shot.png"))
    page.close()
    assert errors == [] and state["error"] is None
    print("page state", state)
    assert state["near"] > 0 and state["far"] > 0 and state["billboards"] >= 16 * state["near"]
    # the farthest crowns (under 32 px on the canvas) are impostor cards, as the renderer draws them
    assert state["cards"] > 0
    # frustum culling: every tree is drawn near, far (relief or cards) or left out of the view, some are left out
    assert state["near"] + state["far"] + state["cards"] + state["culled"] == 300 and state["culled"] > 0
    shot = np.asarray(Image.open(tmp_path / "shot.png").convert("RGB")).astype(int)
    assert shot.std() > 8
    assert _trees(shot).mean() > 0.15  # the trees, not only sky and ground


def test_bad_input(species, tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    cases = [(("--species-dir", empty), "no impostor"), (("--species-dir", tmp_path / "nope"), "nope"),
             (("--species-dir", species, "--area", "10xfoo"), "area"), (("--species-dir", species, "--trees", "0"), "trees")]
    for k, (args, word) in enumerate(cases):
        proc = cli("forest", *args, "--out", tmp_path / f"o{k}")
        assert_clean_failure(proc, tmp_path / f"o{k}")
        assert word in proc.stderr, proc.stderr
