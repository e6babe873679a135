"""Every option of every command, given values a user may mistype (issue 16 item 4).

:mod:`option_sweep` walks the command tree and gives each option a word where a number goes,
negative, zero, huge, nan and inf numbers, an unknown name, an unwritable output or a missing
input (less the values an option accepts by design, each listed with its reason). Each case
must end with exactly one ``error:`` line on stderr, a non-zero exit, no traceback, nothing
written, and quickly: the options are checked before any work starts.
"""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from cli_helpers import cli
import option_sweep

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = ROOT / "src" / "treeform" / "data" / "Celtis_occidentalis_1.jpg"
LIMIT = 20.0  # seconds a case may take: an option checked first fails in well under one

# the valid rest of each command line; {out} is the case's own (not yet existing) output path
BASE = {
    "reconstruct": ["{photo}", "--out", "{out}"],
    "demo": ["--out", "{out}"],
    "sample-data": ["--out", "{out}"],
    "animate": ["{tree}", "--out", "{out}.glb"],
    "batch": ["{photos}", "--out", "{out}", "--workers", "0"],
    "billboard": ["{photo}", "--out", "{out}.png"],
    "cloud": ["{photo}", "--out", "{out}.glb"],
    "eval": ["--cases", "synthetic:1", "--methods", "envelope", "--out", "{out}", "--workers", "0"],
    "forest": ["--species-dir", "{trees}", "--out", "{out}", "--trees", "20", "--frames", "1", "--size", "64x64"],
    "grow": ["--out", "{out}"],
    "impostor": ["{tree}", "--out", "{out}"],
    "leaflets": ["--out", "{out}"],
    "multiview": ["{photos}", "--out", "{out}"],
    "rbv": ["{tree}", "--out", "{out}.npz"],
    "segment": ["{photo}", "--out", "{out}.png"],
    "species": ["{photo}"],
    "skeleton2d": ["{photo}", "--out", "{out}.png"],
    "vary": ["{library}", "-n", "2", "--out", "{out}"],
    "morph": ["{tree_a}", "{tree_b}", "--out", "{out}.png"],
    "dataset generate": ["--n", "2", "--out", "{out}", "--workers", "1"],
    "dataset show": ["{dataset}", "--out", "{out}.png"],
    "dataset capture": ["{out}"],
    "train seg": ["--data", "{dataset}", "--out", "{out}", "--steps", "1"],
    "train feet": ["--cutouts", "{library}", "--out", "{out}", "--steps", "1"],
    "train species": ["--data", "{dataset}", "--out", "{out}", "--epochs", "1"],
    "train rbv": ["--data", "{dataset}", "--out", "{out}", "--epochs", "1"],
    "library process": ["{library}", "--cache", "{out}"],
}


@pytest.fixture(scope="module")
def fixtures(tmp_path_factory):
    root = tmp_path_factory.mktemp("sweep")
    trees = root / "trees"
    tree = trees / "oak"
    assert cli("grow", "--leaves", "300", "--lod", "low", "--out", tree).returncode == 0
    assert cli("impostor", tree, "--rdm-resolution", "16").returncode == 0
    assert cli("dataset", "generate", "--n", "2", "--size", "64", "--workers", "1", "--out", root / "ds").returncode == 0
    assert cli("sample-data", "--out", root / "samples").returncode == 0
    photos = root / "photos"
    photos.mkdir()
    for i in range(3):
        (photos / f"p{i}.jpg").write_bytes(SAMPLE.read_bytes())
    lib = sorted((root / "samples" / "library").glob("*.png"))
    return {"photo": str(SAMPLE), "tree": str(tree), "trees": str(trees), "photos": str(photos),
            "library": str(root / "samples" / "library"), "tree_a": str(lib[0]), "tree_b": str(lib[1]),
            "dataset": str(root / "ds"), "unwritable": "/proc/treeform-sweep/out",
            "missing": str(root / "missing" / "nothing.png"), "work": str(root / "work"), "limit": LIMIT}


def test_every_command_with_options_has_a_base_line():
    """A new command must join the sweep: its valid command line is in BASE."""
    names = {" ".join(p) for p, cmd in option_sweep.commands()
             if any(o.opts and o.opts[0].startswith("-") and not getattr(o, "is_flag", False) for o in cmd.params)}
    assert names - set(BASE) <= {"metrics"}, sorted(names - set(BASE))


def test_the_sweep_covers_every_kind_of_wrong_value():
    found = option_sweep.cases(BASE)
    assert len(found) > 300
    values = {c["value"] for c in found}
    assert {"abc", "-5", "0", "1000000000000", "nan", "inf", "nope", "{unwritable}", "{missing}"} <= values
    assert any(c["command"] == "grow" and c["option"] == "--seed" and c["value"] == "-5" for c in found)


def test_every_wrong_option_value_is_one_clear_line(tmp_path, fixtures):
    work = Path(fixtures["work"])
    work.mkdir(parents=True, exist_ok=True)
    todo = option_sweep.cases(BASE)
    fx, cs, rs = tmp_path / "fixtures.json", tmp_path / "cases.json", tmp_path / "results.json"
    fx.write_text(json.dumps(fixtures))
    cs.write_text(json.dumps(todo))
    proc = subprocess.run([sys.executable, option_sweep.__file__, fx, cs, rs], capture_output=True, text=True,
                          timeout=1800, cwd=work)
    assert proc.returncode == 0, proc.stderr[-3000:]
    bad = []
    for r in json.loads(rs.read_text()):
        lines = [l for l in r["stderr"].splitlines() if l.strip()]
        errors = [l for l in lines if l.startswith("error:")]
        problem = None
        if r["code"] in ("timeout", "exception") or r["code"] == 0:
            problem = f"ended with {r['code']!r}"
        elif "Traceback" in r["stderr"] or len(errors) != 1 or lines[-1] != errors[0]:
            problem = f"stderr {lines[-3:]}"
        elif r["left"]:
            problem = f"left {r['left'][:3]}"
        if problem:
            bad.append(f"{' '.join(r['args'])}: {problem}")
    assert not bad, f"{len(bad)} of {len(todo)} cases:\n" + "\n".join(bad)
