"""treeform eval: cases, scores against ground truth, failure isolation, resume."""

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

from treeform._shared.errors import InputError

DEMO = Path(__file__).resolve().parents[2] / "src" / "treeform" / "data" / "Celtis_occidentalis_1.jpg"


def test_case_specs_are_parsed_and_bad_ones_named(tmp_path):
    from treeform.evaluation import case_names

    assert case_names("synthetic:2", seed=7) == ["synthetic-7-0", "synthetic-7-1"]
    assert case_names("captures:2", seed=7) == ["capture-7-0", "capture-7-1"]
    for bad in ("synthetic:0", "synthetic:x", "captures:0", "forest:3", f"photos:{tmp_path / 'missing'}"):
        with pytest.raises(InputError, match="--cases"):
            case_names(bad)
    with pytest.raises(InputError, match="no photos"):
        case_names(f"photos:{tmp_path}")


def test_unknown_or_non_photo_methods_are_refused():
    from treeform.evaluation.run import parse_methods

    assert parse_methods("envelope, learned,envelope") == ["envelope", "learned"]
    with pytest.raises(InputError, match="not a tree-reconstruction method"):
        parse_methods("variations")
    assert parse_methods("envelope,multiview", cases="captures:2") == ["envelope", "multiview"]
    with pytest.raises(InputError, match="captures:N"):  # the multi-view route needs photos all around
        parse_methods("multiview", cases="synthetic:3")
    with pytest.raises(InputError, match="at least one"):
        parse_methods(" , ")


def _box(center, half, name="leaves"):
    from treeform.structures import MeshPart

    c = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], np.float32) * half + center
    faces = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1), (2, 3, 7), (2, 7, 6),
             (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)]
    return MeshPart(c, np.zeros_like(c), np.zeros((8, 2)), None, np.array(faces), name=name)


def test_novel_views_score_one_for_the_same_tree_and_see_a_wrong_depth(gl):
    from treeform.evaluation import novel_view_ious
    from treeform.structures import Mesh

    tree = Mesh([_box((0.0, 3.0, 0.0), np.array([1.0, 3.0, 1.0], np.float32))])
    same = novel_view_ious(tree, tree, size=64)
    assert set(same) == {"iou_front", "iou_side", "iou_back", "iou_top", "gap_err_side", "gap_err_back", "gap_err_top"}
    assert all(same[k] == pytest.approx(1.0) for k in same if k.startswith("iou"))
    assert all(same[k] == 0.0 for k in same if k.startswith("gap"))
    flat = Mesh([_box((0.0, 3.0, 0.0), np.array([1.0, 3.0, 0.25], np.float32))])  # right from the front, thin in depth
    s = novel_view_ious(tree, flat, size=64)
    assert s["iou_front"] > 0.95 and s["iou_back"] > 0.95
    assert s["iou_side"] < 0.4 and s["iou_top"] < 0.4


def test_novel_views_tell_a_solid_crown_from_one_of_clumps(gl):
    """IoU alone cannot: a solid crown and one of eight clumps in its place overlap much; the gap error sees the
    sky between the clumps from every side."""
    from treeform.evaluation import novel_view_ious
    from treeform.structures import Mesh

    solid = Mesh([_box((0.0, 3.0, 0.0), np.array([1.0, 1.0, 1.0], np.float32))])
    clumps = Mesh([_box((x, 3.0 + y, z), np.full(3, 0.4, np.float32), name=f"leaves{i}")
                   for i, (x, y, z) in enumerate((x, y, z) for x in (-0.5, 0.5) for y in (-0.5, 0.5)
                                                  for z in (-0.5, 0.5))])
    s = novel_view_ious(solid, clumps, size=64)
    assert s["iou_side"] > 0.6 and s["iou_top"] > 0.6, s  # the clumps cover 0.64 of the solid's outline
    assert min(s["gap_err_side"], s["gap_err_back"], s["gap_err_top"]) > 0.15, s


def test_a_multiview_tree_is_scored_where_its_cameras_place_it(gl):
    """Its trunk run under the true ground neither shrinks nor lowers its crown in the views (the crown
    in place is what the photos all around measured). The height error, the route's own estimate's, is
    checked on a real run in tests/methods/multiview/test_multiview_pipeline.py."""
    from types import SimpleNamespace

    from treeform.evaluation import novel_view_ious
    from treeform.evaluation.scores import AlignedTree, aligned_view_mesh, canonical_mesh
    from treeform.structures import Mesh

    crown = _box((0.0, 7.0, 0.0), np.array([2.0, 3.0, 2.0], np.float32))
    trunk = _box((0.0, 2.0, 0.0), np.array([0.2, 2.0, 0.2], np.float32), name="bark")
    sunk = _box((0.0, 0.5, 0.0), np.array([0.2, 3.5, 0.2], np.float32), name="bark")  # 3 m under the ground
    truth = Mesh([crown, trunk])
    case = SimpleNamespace(gt_mesh=truth, gt_skeleton=SimpleNamespace(positions=np.zeros((1, 3))), azimuth_deg=0.0)
    rec = AlignedTree(Mesh([crown, sunk]), SimpleNamespace(positions=np.array([[0.0, -3.0, 0.0]])))
    s = novel_view_ious(canonical_mesh(truth, (0.0, 0.0, 0.0)), aligned_view_mesh(rec, case), size=64)
    assert s["iou_side"] > 0.9 and s["iou_top"] > 0.95, s  # scaled to the true height about its base: 0.39


def test_canonical_mesh_turns_the_camera_onto_plus_z():
    from treeform.evaluation.scores import canonical_mesh
    from treeform.structures import Mesh

    m = Mesh([_box((5.0, 0.0, 0.0), np.array([0.1, 0.1, 0.1], np.float32))])  # seen from azimuth 90 = from +X
    c = canonical_mesh(m, (0.0, 0.0, 0.0), azimuth_deg=90.0, scale=2.0)
    centre = c.parts[0].positions.mean(0)
    assert np.allclose(centre, (0.0, 0.0, 10.0), atol=1e-4)
    assert np.allclose(m.parts[0].positions.mean(0), (5.0, 0.0, 0.0))  # input unchanged


def test_lai_and_mrt_errors_are_zero_for_the_same_tree_at_any_scale_and_see_a_wider_crown():
    from types import SimpleNamespace

    from treeform.evaluation.cases import Case
    from treeform.evaluation.scores import _form_errors
    from treeform.structures import Material, Mesh, MeshPart, TreeSkeleton

    # a trunk 0 -> 1 -> 2 (m, leaning) with two laterals, and a leaf layer of two cards
    pos = np.array([[0, 0, 0], [0.2, 2, 0], [0.4, 4, 0], [1.6, 2.8, 0.5], [-1.2, 3.6, -0.4]], float)
    skel = TreeSkeleton(pos, np.array([-1, 0, 1, 1, 2]), radius=np.array([0.2, 0.15, 0.1, 0.05, 0.05]))
    cards = np.array([[-1, 3, -1], [1, 3, -1], [1, 3, 1], [-1, 3, 1]], np.float32)
    leaves = MeshPart(cards, np.zeros((4, 3)), np.zeros((4, 2)), None, np.array([0, 1, 2, 0, 2, 3]),
                      Material("leaves"), name="leaves")

    def tree(scale=1.0, wide=1.0):
        p = pos * scale
        p[3:, [0, 2]] = p[2, [0, 2]] + (p[3:, [0, 2]] - p[2, [0, 2]]) * wide  # laterals farther from the trunk
        lv = MeshPart(cards * scale * wide, leaves.normals, leaves.uvs, None, leaves.indices, leaves.material)
        return TreeSkeleton(p, skel.parent, radius=skel.radius * scale), Mesh([lv])

    case = Case(name="t", image=np.zeros((4, 4, 3), np.uint8), gt_skeleton=skel, gt_mesh=Mesh([leaves]))
    s, m = tree(scale=2.0)
    same = _form_errors(SimpleNamespace(skeleton=s, mesh=m), case)
    assert same["rel_err_height"] == pytest.approx(1.0)  # twice as tall ...
    assert same["rel_err_lai"] == pytest.approx(0.0, abs=0.02)  # ... same leaf area per ground area
    assert same["mrt_err_pct"] == pytest.approx(0.0, abs=1e-6)  # ... and the same crown shape
    s, m = tree(wide=1.5)
    wider = _form_errors(SimpleNamespace(skeleton=s, mesh=m), case)
    assert wider["mrt_err_pct"] > 5.0
    bare = _form_errors(SimpleNamespace(skeleton=skel, mesh=Mesh([])), case)
    assert "rel_err_lai" not in bare and bare["mrt_err_pct"] == 0.0  # no leaves: no LAI score, not a fake one


def test_a_method_failing_on_one_case_costs_only_that_case_and_a_rerun_retries_it(tmp_path, gl, monkeypatch):
    import treeform.evaluation.run as run
    from treeform.evaluation import evaluate

    real = run._entry
    calls = []

    def flaky(method):
        f = real(method)

        def wrapped(image, **kw):
            calls.append(method)
            if len(calls) == 2:
                raise RuntimeError("boom\non two lines")
            return f(image, **kw)
        return wrapped

    monkeypatch.setattr(run, "_entry", flaky)
    r = evaluate("synthetic:2", "envelope", tmp_path / "ev", workers=0, size=128)
    a, b = r["cases"]
    s = a["methods"]["envelope"]
    assert b["methods"]["envelope"] == {"error": "RuntimeError: boom on two lines"}
    assert r["aggregate"]["envelope"]["cases"] == 2 and r["aggregate"]["envelope"]["failed"] == 1
    # every score against the truth is there and in range
    for k in ("front_iou", "front_iou_own", "segmentation_iou", "iou_side", "iou_back", "iou_top"):
        assert 0.0 <= s[k] <= 1.0, k
    assert s["front_iou"] > 0.5 and s["iou_front"] > 0.3
    assert len([k for k in s if k.startswith("rbv_err_l")]) == 5 and s["stages"]["segment"] > 0
    saved = json.loads((tmp_path / "ev" / "results.json").read_text())
    assert saved["aggregate"]["envelope"]["scores"]["iou_side"]["n"] == 1
    # rerun: the finished case is kept, the failed one retried (and now succeeds)
    r2 = evaluate("synthetic:2", "envelope", tmp_path / "ev", workers=0, size=128)
    assert r2["resumed"] == 1 and r2["evaluated"] == 1 and r2["aggregate"]["envelope"]["failed"] == 0
    assert r2["cases"][0]["methods"]["envelope"] == {k: v for k, v in s.items()}
    # another photo size is another evaluation: nothing is resumed from this one
    assert evaluate("synthetic:1", "envelope", tmp_path / "ev", workers=0, size=96)["resumed"] == 0


def test_photo_cases_score_against_a_mask_file_and_a_corrupt_photo_costs_only_itself(tmp_path, gl):
    from PIL import Image

    from treeform.evaluation import evaluate
    from treeform.segment import segment

    d = tmp_path / "photos"
    d.mkdir()
    im = Image.open(DEMO).convert("RGB")
    im.thumbnail((256, 256))
    im.save(d / "a.jpg")
    shutil.copy(d / "a.jpg", d / "b.jpg")
    Image.fromarray(((segment(np.asarray(im)).labels > 0) * 255).astype(np.uint8)).save(d / "a_mask.png")
    (d / "c.jpg").write_bytes(b"not a jpeg")
    r = evaluate(f"photos:{d}", "envelope", tmp_path / "ev", workers=0)
    by = {c["case"]: c for c in r["cases"]}
    assert set(by) == {"photo-a.jpg", "photo-b.jpg", "photo-c.jpg"}
    a, b, c = by["photo-a.jpg"], by["photo-b.jpg"], by["photo-c.jpg"]
    assert a["mask_source"] == "mask file" and "front_iou" in a["methods"]["envelope"]
    assert b["mask_source"] == "none" and "front_iou" not in b["methods"]["envelope"]
    assert "front_iou_own" in b["methods"]["envelope"]
    assert "error" in c and "\n" not in c["error"]
    assert "iou_side" not in a["methods"]["envelope"]  # no 3D truth for a photo


def test_cli_eval_on_dask_writes_results_and_a_summary(tmp_path, gl):
    from typer.testing import CliRunner

    from treeform.cli.app import app

    res = CliRunner().invoke(app, ["eval", "--cases", "synthetic:1", "--methods", "envelope", "--workers", "1",
                                   "--out", str(tmp_path / "ev")])
    assert res.exit_code == 0, res.output
    assert "envelope: 1/1 ok" in res.output and "side IoU" in res.output
    r = json.loads((tmp_path / "ev" / "results.json").read_text())
    assert r["cases"][0]["methods"]["envelope"]["iou_side"] > 0.0
    bad = CliRunner().invoke(app, ["eval", "--cases", "synthetic:1", "--methods", "nope", "--out", str(tmp_path / "x")])
    assert bad.exit_code != 0 and "nope" in bad.output
