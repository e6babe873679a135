"""`treeform impostor`: a grown tree's colour cubemap and RDM written all at once; bad inputs fail cleanly."""

import json

import numpy as np
import pytest
from cli_helpers import assert_clean_failure, cli
from PIL import Image


@pytest.fixture(scope="module")
def grown(tmp_path_factory):
    out = tmp_path_factory.mktemp("impostor") / "oak"
    proc = cli("grow", "--species", "oak", "--seed", "2", "--lod", "low", "--out", out)
    assert proc.returncode == 0, proc.stderr
    return out


def test_impostor_of_a_grown_tree(grown, gl):
    from treeform.io.gltf import read_glb_geometry
    from treeform.structures import RadialDistanceMap

    proc = cli("impostor", grown, "--face", "64", "--rdm-resolution", "32", "--seed", "1")
    assert proc.returncode == 0, proc.stderr
    imp = grown / "impostor"
    names = sorted(p.name for p in imp.iterdir())
    assert names == sorted([f"color_{n}.png" for n in ("px", "nx", "py", "ny", "pz", "nz")]
                           + ["cloud.npz", "color_cross.png", "front.png", "impostor.json", "leaflets", "opacity.npz",
                              "rdm.npz", "wood.glb"])
    assert {p.name for p in (imp / "leaflets").iterdir()} >= {"rgba.png", "normal.png", "centroid.png", "ao.png",
                                                              "depth.png", "type.png", "leaflets.json"}
    faces = [np.asarray(Image.open(imp / f"color_{n}.png")) for n in ("px", "nx", "py", "ny", "pz", "nz")]
    assert all(f.shape == (64, 64, 3) for f in faces)
    assert all(f.reshape(-1, 3).mean(0)[1] > f.reshape(-1, 3).mean(0)[2] for f in faces)  # leafy, every side
    manifest = json.loads((imp / "impostor.json").read_text())
    assert manifest["color"]["face_size"] == 64 and manifest["rdm"]["resolution"] == 32
    # the front view's mapping for the planar colours: the crown centre lands inside the front view's tree
    front = np.asarray(Image.open(imp / "front.png"))
    u, v = (int(x) for x in manifest["front"]["center_px"])
    assert manifest["front"]["pixels_per_metre"] > 0 and 0 <= u < front.shape[1] and 0 <= v < front.shape[0]
    # the RDM holds the tree (all but the single-texel spikes of twigs and leaves its median drops; the thin
    # bare trunk below the crown whole) and is no bigger
    rdm = RadialDistanceMap.load(imp / "rdm.npz")
    verts, leaves = read_glb_geometry(grown / "tree.glb")
    d = verts - rdm.center
    r = np.linalg.norm(d, axis=1)
    inside = r <= rdm.lookup(d) * (1 + 1e-6) + 1e-5
    below = verts[:, 1] < leaves.reshape(-1, 3)[:, 1].min()
    assert below.sum() > 10 and inside[below].all() and inside.mean() > 0.85
    assert rdm.radii.max() <= r.max() * (1 + 1e-5)
    assert np.median(rdm.radii[rdm.radii > 0]) < np.percentile(np.linalg.norm(leaves.reshape(-1, 3) - rdm.center,
                                                                              axis=1), 99)
    # the billboard cloud: 144 centres inside the crown, on the tree's branches; the wood under a small budget
    from treeform.methods.envelope.impostor import WOOD_TRIANGLES, read_impostor

    back = read_impostor(grown)
    assert back.cloud_points.shape == (144, 3) and back.cloud_size > 0 and manifest["cloud"]["from"] == "skeleton"
    assert rdm.contains(back.cloud_points).all()
    assert 0 < back.wood.n_triangles <= WOOD_TRIANGLES
    assert back.leaflets.depth.dtype == np.uint16 and back.leaflets.rgba.shape == (256, 256, 4)
    # the billboard centres sit among the leaves, not along the bare trunk below the crown
    leaf_lo = leaves.reshape(-1, 3).min(0)
    assert (back.cloud_points[:, 1] >= leaf_lo[1] - 1e-4).all()
    # the opacity grid read back: the default resolution, a cube around the whole tree, opaque where the leaves are
    from treeform.methods.envelope.impostor import OPACITY_RESOLUTION

    og = back.opacity
    assert og.resolution == OPACITY_RESOLUTION == manifest["opacity"]["resolution"]
    lo, hi = og.bounds()
    assert (verts.min(0) >= lo).all() and (verts.max(0) <= hi).all()
    at_leaves = og.sample(leaves.reshape(-1, 3)[::7])
    assert np.median(at_leaves) > 20 * og.sample(np.array([lo + 0.01 * (hi - lo)]))[0] + 1e-9 and np.median(at_leaves) > 0
    # same seed, same files
    proc = cli("impostor", grown, "--face", "64", "--rdm-resolution", "32", "--seed", "1", "--out", grown / "again")
    assert proc.returncode == 0, proc.stderr
    assert (grown / "again" / "color_nz.png").read_bytes() == (imp / "color_nz.png").read_bytes()
    # written again over itself (its leaflets/ sub-folder too): the same files, nothing left beside them
    proc = cli("impostor", grown, "--face", "64", "--rdm-resolution", "32", "--seed", "1")
    assert proc.returncode == 0, proc.stderr
    assert sorted(p.name for p in imp.iterdir()) == names


def test_baked_colours_of_a_grown_tree(grown, gl, tmp_path):
    """--colors baked: the mesh's own colours all round (same RDM), deterministic, leafy on every side."""
    out = tmp_path / "baked"
    proc = cli("impostor", grown, "--face", "32", "--rdm-resolution", "32", "--colors", "baked", "--out", out)
    assert proc.returncode == 0, proc.stderr
    manifest = json.loads((out / "impostor.json").read_text())
    assert manifest["color"]["made_by"] == "baked"
    faces = [np.asarray(Image.open(out / f"color_{n}.png")).reshape(-1, 3).mean(0) for n in ("px", "nx", "pz", "nz")]
    assert all(f[1] > f[2] for f in faces)  # the leaves' green on the four sides
    proc = cli("impostor", grown, "--face", "32", "--rdm-resolution", "32", "--colors", "baked", "--out", tmp_path / "b2",
               "--opacity", "0")
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "b2" / "color_px.png").read_bytes() == (out / "color_px.png").read_bytes()
    assert not (tmp_path / "b2" / "opacity.npz").exists() and "opacity" not in json.loads(
        (tmp_path / "b2" / "impostor.json").read_text())  # --opacity 0: the RDM's solid relief, as published
    proc = cli("impostor", grown, "--colors", "painted", "--out", tmp_path / "bad")
    assert_clean_failure(proc, tmp_path / "bad")
    assert "colors" in proc.stderr


def test_impostor_bad_inputs(tmp_path, grown):
    proc = cli("impostor", tmp_path / "missing")
    assert_clean_failure(proc)
    empty = tmp_path / "empty"
    empty.mkdir()
    proc = cli("impostor", empty)
    assert_clean_failure(proc, empty)
    assert "tree.glb" in proc.stderr
    (empty / "tree.glb").write_bytes(b"not a glb")
    proc = cli("impostor", empty, "--out", tmp_path / "x")
    assert_clean_failure(proc, tmp_path / "x")
    proc = cli("impostor", grown, "--face", "8", "--out", tmp_path / "y")
    assert_clean_failure(proc, tmp_path / "y")
    proc = cli("impostor", grown, "--opacity", "3", "--out", tmp_path / "y")
    assert_clean_failure(proc, tmp_path / "y")
    assert "opacity" in proc.stderr
    for bad in ("200,40", "40", "a,b"):
        proc = cli("impostor", grown, "--engine", bad, "--out", tmp_path / "z")
        assert_clean_failure(proc, tmp_path / "z")
        assert "engine" in proc.stderr


def test_engine_levels(grown, gl, tmp_path):
    """--engine: lod0 (the tree), lod1 (billboard cloud + wood), lod2 (six-view impostor cards) and lods.json;
    each level much lighter than the one before; the cards show the tree from its sides; valid glTF."""
    import shutil
    import subprocess
    from pathlib import Path

    from treeform.io.gltf import read_glb, read_glb_counts, read_glb_mesh
    from treeform.render import Renderer
    from treeform.structures.camera import box_camera

    out = tmp_path / "imp"
    proc = cli("impostor", grown, "--face", "64", "--rdm-resolution", "32", "--engine", "40,200", "--out", out)
    assert proc.returncode == 0, proc.stderr
    eng = out / "engine"
    assert sorted(p.name for p in eng.iterdir()) == ["lod0.glb", "lod1.glb", "lod2.glb", "lods.json"]
    assert (eng / "lod0.glb").read_bytes() == (grown / "tree.glb").read_bytes()
    levels = json.loads((eng / "lods.json").read_text())["levels"]
    assert [(lv["from_m"], lv["to_m"]) for lv in levels] == [(0.0, 40.0), (40.0, 200.0), (200.0, None)]
    tris = [read_glb_counts(eng / lv["file"])[1] for lv in levels]
    assert tris == [lv["triangles"] for lv in levels]
    assert tris[0] > 4 * tris[1] and tris[2] == 12
    gltf, _ = read_glb(eng / "lod1.glb")
    assert gltf["extensionsUsed"] == ["KHR_materials_unlit"]
    assert [n["name"] for n in gltf["nodes"]][1] == "wood"
    # the cards and the cloud cover about what the full tree covers, from two sides
    full = read_glb_mesh(eng / "lod0.glb")
    pts = np.concatenate([p.positions for p in full.parts])
    for az in (0, 90):
        cam = box_camera(pts.min(0), pts.max(0), az, 5, 96)
        r = Renderer(cam, samples=1)
        masks = [r.render(read_glb_mesh(eng / f"lod{k}.glb")).mask for k in range(3)]
        for m in masks[1:]:
            assert (m & masks[0]).sum() / (m | masks[0]).sum() > 0.5
        # the cloud's leaves outside the crown are cut out of their quads (0.20-0.23 of the tree's
        # pixels drawn outside it, IoU 0.76-0.79; unclipped quads: 0.45-0.47 and 0.67)
        one, full_mask = masks[1], masks[0]
        assert (one & full_mask).sum() / (one | full_mask).sum() > 0.72
        assert (one & ~full_mask).sum() / full_mask.sum() < 0.3
    validator = Path(__file__).resolve().parents[2] / "tools" / "gltf_validate.mjs"
    if shutil.which("node") and (validator.parent / "node_modules" / "gltf-validator").is_dir():
        for name in ("lod1.glb", "lod2.glb"):
            rep = json.loads(subprocess.run(["node", str(validator), str(eng / name)], capture_output=True,
                                            text=True, timeout=120).stdout)
            assert rep["numErrors"] == 0 and rep["numWarnings"] == 0, rep["messages"]


def test_reconstruct_writes_the_impostor_beside_the_tree(tmp_path, gl):
    from pathlib import Path

    sample = Path(__file__).resolve().parents[2] / "src" / "treeform" / "data" / "Celtis_occidentalis_1.jpg"
    out = tmp_path / "tree"
    proc = cli("reconstruct", sample, "--out", out, "--leaves", "2000", "--lod", "low", "--impostor")
    assert proc.returncode == 0, proc.stderr
    assert (out / "tree.glb").is_file() and (out / "impostor" / "rdm.npz").is_file()
    manifest = json.loads((out / "impostor" / "impostor.json").read_text())
    assert manifest["source"].endswith("tree.glb") and manifest["leaflets"]["leaves"] > 0
