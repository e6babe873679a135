"""Vendor three.js (npm) into the package as classic-script modules for the report's 3D viewer.

    python scripts/vendor_three.py [NODE_MODULES]   # default: benchmarks/peers/node_modules

Why not the ES modules as they are: a page opened from the file system (file://) may not
load module scripts or fetch files (Chromium refuses both for an opaque origin), and the
reports must work offline from a folder. So the few modules the viewer needs (three core,
GLTFLoader, OrbitControls and their helpers) are rewritten into one classic script: each
module becomes a function that fills an exports object, ``import {A as B} from 'x'``
becomes ``const {A: B} = __tf_require('x')`` and ``export {A as B}`` an assignment. The
rewrite refuses any import/export form it does not know, so a new three.js release cannot
slip through half-converted. Output: ``src/treeform/report/assets/three-modules.js`` and
``THREE_LICENSE`` (MIT).
"""

from __future__ import annotations

import json
import posixpath
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "src" / "treeform" / "report" / "assets"

# module name -> file inside the three package (order: dependencies first, for readability)
MODULES = {
    "three/core": "build/three.core.js",
    "three": "build/three.module.js",
    "three/addons/utils/BufferGeometryUtils.js": "examples/jsm/utils/BufferGeometryUtils.js",
    "three/addons/utils/SkeletonUtils.js": "examples/jsm/utils/SkeletonUtils.js",
    "three/addons/loaders/GLTFLoader.js": "examples/jsm/loaders/GLTFLoader.js",
    "three/addons/controls/OrbitControls.js": "examples/jsm/controls/OrbitControls.js",
}
FILE_TO_NAME = {v: k for k, v in MODULES.items()}

IMPORT_NAMED = re.compile(r"^import\s*\{([^}]*)\}\s*from\s*['\"]([^'\"]+)['\"]\s*;?", re.M)
IMPORT_STAR = re.compile(r"^import\s+\*\s+as\s+(\w+)\s+from\s*['\"]([^'\"]+)['\"]\s*;?", re.M)
EXPORT_FROM = re.compile(r"^export\s*\{([^}]*)\}\s*from\s*['\"]([^'\"]+)['\"]\s*;?", re.M)
EXPORT_LIST = re.compile(r"^export\s*\{([^}]*)\}\s*;?", re.M)


def _resolve(spec: str, here: str) -> str:
    if not spec.startswith("."):
        if spec not in MODULES:
            raise SystemExit(f"vendor_three: unknown bare import {spec!r} in {here}")
        return spec
    path = posixpath.normpath(posixpath.join(posixpath.dirname(here), spec))
    if path not in FILE_TO_NAME:
        raise SystemExit(f"vendor_three: {here} imports {path}, which is not vendored (add it to MODULES)")
    return FILE_TO_NAME[path]


def _pairs(spec: str) -> list:
    out = []
    for item in spec.split(","):
        item = item.strip()
        if not item:
            continue
        a, _, b = item.partition(" as ")
        out.append((a.strip(), (b or a).strip()))
    return out


def convert(source: str, here: str) -> str:
    """One ES module -> the body of a classic function(__tf_exports, __tf_require)."""
    src = IMPORT_STAR.sub(lambda m: f"const {m.group(1)} = __tf_require({json.dumps(_resolve(m.group(2), here))});",
                          source)
    src = IMPORT_NAMED.sub(lambda m: "const { " + ", ".join(a if a == b else f"{a}: {b}" for a, b in _pairs(m.group(1)))
                           + f" }} = __tf_require({json.dumps(_resolve(m.group(2), here))});", src)

    def export_from(m):
        mod = json.dumps(_resolve(m.group(2), here))
        return "{ const __m = __tf_require(" + mod + "); " + " ".join(
            f"__tf_exports.{b} = __m.{a};" for a, b in _pairs(m.group(1))) + " }"

    src = EXPORT_FROM.sub(export_from, src)
    src = EXPORT_LIST.sub(lambda m: " ".join(f"__tf_exports.{b} = {a};" for a, b in _pairs(m.group(1))), src)
    left = re.findall(r"^(?:import|export)\b.*$", src, re.M)
    if left:
        raise SystemExit(f"vendor_three: {here}: unconverted statement {left[0][:80]!r}")
    return src


def main(argv) -> int:
    nm = Path(argv[1]) if len(argv) > 1 else ROOT / "benchmarks" / "peers" / "node_modules"
    three = nm / "three"
    if not (three / "package.json").exists():
        raise SystemExit(f"vendor_three: no three.js in {nm} (npm install three there first)")
    version = json.loads((three / "package.json").read_text())["version"]
    parts = [f"/* three.js {version} (MIT License, see THREE_LICENSE), rewritten by scripts/vendor_three.py into\n"
             "   classic-script modules so that treeform's reports open from the file system. */\n"
             "(function () {\n"
             "  const defs = (window.__tf_defs = window.__tf_defs || {}), cache = {};\n"
             "  window.__tf_require = function (name) {\n"
             "    if (name in cache) return cache[name];\n"
             "    const f = defs[name];\n"
             "    if (!f) throw new Error('treeform viewer: no module ' + name);\n"
             "    const exports = (cache[name] = {});\n"
             "    f(exports, window.__tf_require);\n"
             "    return exports;\n"
             "  };\n"
             "})();\n"]
    for name, rel in MODULES.items():
        body = convert((three / rel).read_text(encoding="utf-8"), rel)
        parts.append(f"window.__tf_defs[{json.dumps(name)}] = function (__tf_exports, __tf_require) {{\n"
                     f"'use strict';\n{body}\n}};\n")
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "three-modules.js").write_text("".join(parts), encoding="utf-8")
    (OUT / "THREE_LICENSE").write_text((three / "LICENSE").read_text(encoding="utf-8"), encoding="utf-8")
    (OUT / "THREE_VERSION").write_text(version + "\n")
    print(f"three.js {version}: {len(MODULES)} modules -> {OUT / 'three-modules.js'} "
          f"({(OUT / 'three-modules.js').stat().st_size / 1e6:.2f} MB)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
