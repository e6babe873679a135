"""PyMatting's one-time numba compile: detected beforehand from numba's cache, announced, never silent."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = ROOT / "src" / "treeform" / "data" / "Celtis_occidentalis_1.jpg"
TREEFORM = Path(sys.executable).parent / "treeform"

_LOCATE = """
import json
from numba.core.registry import cpu_target
from treeform.segment import matting as m
from treeform._shared.jit import numba_kernels
from importlib.util import find_spec
import os
from numba.core.caching import CompileResultCacheImpl
out = []
for path, name, line in numba_kernels(os.path.dirname(find_spec("pymatting").origin)):
    ns = {}
    exec(compile("\\n" * (line - 1) + "def _f():\\n    pass\\n", path, "exec"), ns)
    f = ns["_f"]; f.__qualname__ = name; f.__name__ = name.rsplit(".", 1)[-1]
    impl = CompileResultCacheImpl(f)
    out.append([name, impl.locator.get_cache_path(), impl.filename_base])
import sys
print(json.dumps({"kernels": out, "count": m.kernels_to_compile(), "imported": "pymatting" in sys.modules}))
"""


def _py(code: str, **env) -> dict:
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600,
                         env={**os.environ, **env})
    assert run.returncode == 0, run.stderr
    return json.loads(run.stdout.strip().splitlines()[-1])


def _env_without_numba_cache_dir():
    return {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}


def test_a_cold_numba_cache_is_seen_without_compiling(tmp_path):
    t0 = time.perf_counter()
    info = _py(_LOCATE, NUMBA_CACHE_DIR=str(tmp_path))
    cold, total = info["count"]
    assert total >= 20 and cold == total  # every kernel PyMatting declares with cache=True
    assert not info["imported"] and not list(tmp_path.rglob("*.nbc"))  # nothing compiled by the check
    assert time.perf_counter() - t0 < 30


@pytest.fixture(scope="module")
def warm_default_cache():
    """Numba's default cache (PyMatting's __pycache__ or the user cache) holding every kernel."""
    env = _env_without_numba_cache_dir()
    subprocess.run([sys.executable, "-c", "import pymatting"], check=True, env=env, timeout=600)  # ~50 s if cold
    return subprocess.run([sys.executable, "-c", _LOCATE], capture_output=True, text=True, check=True, env=env,
                          timeout=120).stdout


def test_a_warm_cache_is_seen_and_an_unwritable_cache_folder_is_harmless(warm_default_cache, tmp_path):
    info = json.loads(warm_default_cache.strip().splitlines()[-1])
    assert info["count"][0] == 0 and info["count"][1] >= 20
    blocker = tmp_path / "file"
    blocker.write_text("x")
    code = ("import logging, json, sys\n"
            "logging.basicConfig(level=logging.INFO, stream=sys.stdout, format='%(message)s')\n"
            "from treeform.segment import matting as m\n"
            "m._import_pymatting()\n"
            "print(json.dumps(m.kernels_to_compile()))")
    env = {**_env_without_numba_cache_dir(), "XDG_CACHE_HOME": str(blocker / "cache")}  # cannot be created
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert run.returncode == 0, run.stderr
    assert "first run" not in run.stdout and run.stdout.strip().splitlines()[-1] == "[0, 0]"


def test_billboard_announces_exactly_the_kernels_numba_will_compile(warm_default_cache, tmp_path):
    """A cache missing one kernel: the CLI says so, numba compiles it, and the next run is quiet."""
    warm = json.loads(warm_default_cache.strip().splitlines()[-1])["kernels"]
    cache = tmp_path / "numba"
    target = {base: folder for _, folder, base in _py(_LOCATE, NUMBA_CACHE_DIR=str(cache))["kernels"]}
    names = [k[0] for k in warm]
    skip = "_propagate_1d_first_pass" if "_propagate_1d_first_pass" in names else names[0]  # a quick one
    for name, src_dir, base in warm:  # copy the warm cache into NUMBA_CACHE_DIR's layout, but one kernel
        if name == skip:
            continue
        dst = Path(target[base])
        dst.mkdir(parents=True, exist_ok=True)
        for f in Path(src_dir).glob(base + ".*"):
            if f.suffix in (".nbi", ".nbc"):
                shutil.copy2(f, dst / f.name)
    assert _py(_LOCATE, NUMBA_CACHE_DIR=str(cache))["count"] == [1, len(warm)]

    env = {**os.environ, "NUMBA_CACHE_DIR": str(cache)}
    cmd = [str(TREEFORM), "billboard", str(SAMPLE), "-o", str(tmp_path / "b.png")]
    first = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=600)
    assert first.returncode == 0, first.stderr
    notes = [l for l in first.stderr.splitlines() if l.startswith("note:")]
    assert notes == [f"note: first run: compiling 1 of {len(warm)} matting kernels with numba, once (~5 s); "
                     "later runs load them from the cache"], first.stderr
    assert first.stderr.index("note:") < first.stderr.index("  matting ")  # said before the wait, not after
    assert _py(_LOCATE, NUMBA_CACHE_DIR=str(cache))["count"] == [0, len(warm)]  # numba did compile it
    again = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=600)
    assert again.returncode == 0 and "note:" not in again.stderr
