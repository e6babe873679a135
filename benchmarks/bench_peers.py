"""Side-by-side peer benchmark: treeform's procedural trees against ez-tree (issue 17 item 1).

Run: `python benchmarks/bench_peers.py [--repeat 15] [--presets "Oak Large" ...] [--write]`.

ez-tree (npm ``@dgreenheck/ez-tree``, a three.js procedural tree generator) runs under node in
``benchmarks/peers/ez_tree.mjs``, a line server started once: each request times one
``tree.generate()`` of a preset (branch tubes + leaf cards, CPU geometry). Versions are pinned
in ``benchmarks/peers/package.json`` / ``package-lock.json``; ``node_modules`` is installed with
``npm ci`` on first use and never committed.

Per preset: the ez-tree triangle count (branches + leaves) is the treeform triangle budget;
both sides are warmed up (3 runs each), then one ez-tree run and one treeform run alternate
``--repeat`` times (so both see the same machine load) and the medians are reported. The
treeform side is :func:`treeform_tree`: grow + leaves + mesh of the nearest species preset,
geometry only (no texture synthesis, no rendering, no export) — the same work ez-tree's
``generate()`` does. The ez-tree timing is in-process (``performance.now()`` in node), the
pipe round trip is not counted.

Without node (or npm when ``node_modules`` is missing), or when the server fails, it prints one
line and exits 0: a benchmark, not a test. ``--write`` puts the result into BENCHMARKS.md
between ``<!-- peers:begin -->`` and ``<!-- peers:end -->`` (appended the first time).
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import queue
import shutil
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from _common import machine, write_section  # benchmarks/ is on sys.path when a script runs

ROOT = Path(__file__).resolve().parents[1]
PEERS = ROOT / "benchmarks" / "peers"
BENCHMARKS_MD = ROOT / "BENCHMARKS.md"

DEFAULT_PRESETS = ("Oak Large", "Pine Large", "Ash Large", "Aspen Large")
# ez-tree preset family -> nearest treeform species preset (treeform has no ash or aspen)
NEAREST = {"oak": "oak", "pine": "pine", "ash": "maple", "aspen": "birch"}
WARMUP = 3
MIN_REPEAT = 9
TIMEOUT_S = 60.0  # one ez-tree request (the first one also imports three + ez-tree)


class PeerError(RuntimeError):
    """The ez-tree side could not run; reported as one line, never a crash."""


# --------------------------------------------------------------------------------------------
# treeform side: keep it ONE function so a budget-aware pipeline is a one-place change


def treeform_tree(species: str, budget: int, seed: int = 0) -> tuple[dict[str, float], int]:
    """Grow + leaves + mesh of one ``species`` tree within ``budget`` triangles.

    Returns the wall seconds of each stage (``{"grow", "leaves", "mesh"}``) and the mesh's
    triangle count. Geometry only: no texture synthesis, no rendering. As ``treeform grow``
    does under a budget, only the leaf clusters the budget keeps are generated, enlarged as
    the LOD would enlarge a thinned crown (:func:`treeform.geometry.foliage_budget`).
    """
    from treeform.geometry import foliage_budget, tree_mesh
    from treeform.growth.leaves import twig_foliage, twig_nodes
    from treeform.growth.phenomenological import grow
    from treeform.growth.species import load_species, load_species_appearance

    p, look = load_species(species), load_species_appearance(species)
    t0 = time.perf_counter()
    sk = grow(p, seed=seed)
    t1 = time.perf_counter()
    n, factor = foliage_budget(sk, int(round(3.0 * len(twig_nodes(sk, 4)))), max_triangles=budget, radial_segments=8)
    fol = twig_foliage(sk, leaf_color=look.leaf_color, size=look.leaf_size * factor, leaves=n, twig_tips=4,
                       seed=seed)
    t2 = time.perf_counter()
    m = tree_mesh(sk, fol, max_triangles=budget, radial_segments=8, seed=seed)
    t3 = time.perf_counter()
    return {"grow": t1 - t0, "leaves": t2 - t1, "mesh": t3 - t2}, int(m.n_triangles)


# --------------------------------------------------------------------------------------------
# ez-tree side: node line server


def _installed() -> bool:
    nm = PEERS / "node_modules"
    return (nm / "@dgreenheck" / "ez-tree" / "package.json").is_file() and (nm / "three" / "package.json").is_file()


def _pkg_version(name: str) -> str:
    try:
        return json.loads((PEERS / "node_modules" / name / "package.json").read_text())["version"]
    except (OSError, ValueError, KeyError):
        return "?"


def ensure_node() -> str | None:
    """None when ez-tree can run, else the one line saying why not (npm ci on first use)."""
    node = shutil.which("node")
    if node is None:
        return "peers: node not found — skipped"
    if _installed():
        return None
    npm = shutil.which("npm")
    if npm is None:
        return "peers: npm not found (needed once for benchmarks/peers/node_modules) — skipped"
    print("peers: installing ez-tree into benchmarks/peers/node_modules (npm ci) ...", flush=True)
    try:
        r = subprocess.run([npm, "ci", "--no-audit", "--no-fund", "--loglevel=error"], cwd=PEERS,
                           capture_output=True, text=True, timeout=600)
    except (OSError, subprocess.TimeoutExpired) as e:
        return f"peers: npm ci failed ({e}) — skipped"
    if r.returncode != 0 or not _installed():
        tail = (r.stderr or r.stdout).strip().splitlines()[-1:] or [f"exit {r.returncode}"]
        return f"peers: npm ci failed ({tail[0]}) — skipped"
    return None


class EzTreeServer:
    """``node benchmarks/peers/ez_tree.mjs``, one JSON line per request."""

    def __init__(self):
        self._err = tempfile.TemporaryFile(mode="w+t")
        try:
            self.proc = subprocess.Popen([shutil.which("node") or "node", "ez_tree.mjs"], cwd=PEERS,
                                         stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self._err,
                                         text=True, bufsize=1)
        except OSError as e:
            self._err.close()
            raise PeerError(f"cannot start node ({e})") from e
        self._lines: queue.Queue = queue.Queue()
        threading.Thread(target=self._pump, daemon=True).start()

    def _pump(self):
        for line in self.proc.stdout:
            self._lines.put(line)
        self._lines.put(None)  # EOF

    def _stderr_tail(self) -> str:
        try:
            self._err.seek(0)
            lines = [ln.strip() for ln in self._err.read().splitlines() if ln.strip()]
        except (OSError, ValueError):
            return ""
        return f": {lines[-1][:200]}" if lines else ""

    def request(self, cmd: str) -> dict:
        if self.proc.poll() is not None:
            raise PeerError(f"ez-tree server exited with {self.proc.returncode}{self._stderr_tail()}")
        try:
            self.proc.stdin.write(cmd + "\n")
            self.proc.stdin.flush()
        except (BrokenPipeError, OSError) as e:
            raise PeerError(f"ez-tree server pipe closed ({e}){self._stderr_tail()}") from e
        deadline = time.monotonic() + TIMEOUT_S
        while True:
            try:
                line = self._lines.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                raise PeerError(f"ez-tree server did not answer {cmd!r} within {TIMEOUT_S:.0f} s") from None
            if line is None:
                time.sleep(0.1)
                raise PeerError(f"ez-tree server exited{self._stderr_tail()}")
            try:
                msg = json.loads(line)
            except ValueError:
                continue  # stray console output from three / ez-tree
            if not isinstance(msg, dict):
                continue
            if "error" in msg:
                raise PeerError(f"ez-tree: {str(msg['error']).splitlines()[0]}")
            return msg

    def generate(self, preset: str) -> tuple[float, int]:
        """Wall milliseconds of one ``generate()`` of ``preset`` and its triangle count."""
        msg = self.request(preset)
        return float(msg["ms"]), int(msg["triangles"])

    def close(self):
        try:
            if self.proc.poll() is None:
                try:
                    self.proc.stdin.write("quit\n")
                    self.proc.stdin.flush()
                    self.proc.wait(timeout=5)
                except (OSError, ValueError, subprocess.TimeoutExpired):
                    pass
            if self.proc.poll() is None:
                self.proc.kill()
                self.proc.wait(timeout=5)
        finally:
            self._err.close()


# --------------------------------------------------------------------------------------------


def nearest_species(preset: str) -> str | None:
    """``"Oak Large"`` -> ``"oak"``; ``"Name=species"`` names the species explicitly."""
    if "=" in preset:
        return preset.split("=", 1)[1].strip()
    return NEAREST.get(preset.split()[0].lower()) if preset.split() else None


def bench_preset(server: EzTreeServer, preset: str, species: str, repeat: int, seed: int) -> dict:
    _, budget = server.generate(preset)
    for _ in range(WARMUP):
        server.generate(preset)
        treeform_tree(species, budget, seed)
    ez_ms, tf_total, tf_stage, ez_tris, tf_tris = [], [], {"grow": [], "leaves": [], "mesh": []}, set(), set()
    for _ in range(repeat):
        ms, n = server.generate(preset)
        ez_ms.append(ms)
        ez_tris.add(n)
        stages, n_tf = treeform_tree(species, budget, seed)
        for k in tf_stage:
            tf_stage[k].append(stages[k] * 1e3)
        tf_total.append(sum(stages.values()) * 1e3)
        tf_tris.add(n_tf)
    med = statistics.median
    return {"preset": preset, "species": species, "budget": budget,
            "ez_ms": med(ez_ms), "ez_tris": max(ez_tris),
            "tf_ms": med(tf_total), "tf_stage": {k: med(v) for k, v in tf_stage.items()},
            "tf_tris": max(tf_tris), "ratio": med(tf_total) / med(ez_ms)}


def table(rows: list[dict]) -> str:
    out = ["| ez-tree preset | ez-tree median (ms) | ez-tree triangles | treeform species (nearest) "
           "| treeform median (ms) (grow / leaves / mesh) | treeform triangles | ratio (treeform / ez-tree) |",
           "|---|---|---|---|---|---|---|"]
    for r in rows:
        s = r["tf_stage"]
        out.append(f"| {r['preset']} | {r['ez_ms']:.1f} | {r['ez_tris']:,} | {r['species']} "
                   f"| {r['tf_ms']:.1f} ({s['grow']:.1f} / {s['leaves']:.1f} / {s['mesh']:.1f}) "
                   f"| {r['tf_tris']:,} | {r['ratio']:.2f}× |")
    return "\n".join(out)


def load_line() -> str:
    try:
        l1, l5, _ = os.getloadavg()
        return f"load average {l1:.1f} (1 min) / {l5:.1f} (5 min) on {os.cpu_count()} cores"
    except OSError:
        return "load average unknown"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=15,
                    help=f"alternating timed runs per side and preset (default 15, at least {MIN_REPEAT})")
    ap.add_argument("--presets", nargs="+", default=list(DEFAULT_PRESETS),
                    help='ez-tree presets (e.g. "Oak Large"); "Name=species" picks the treeform species')
    ap.add_argument("--seed", type=int, default=0, help="treeform seed (ez-tree presets carry their own)")
    ap.add_argument("--write", action="store_true", help="put the result into BENCHMARKS.md")
    args = ap.parse_args(argv)
    repeat = max(args.repeat, MIN_REPEAT)
    if repeat != args.repeat:
        print(f"peers: --repeat {args.repeat} raised to {repeat} (at least {MIN_REPEAT} for a median)")

    why = ensure_node()
    if why:
        print(why)
        return 0
    jobs = []
    for name in args.presets:
        sp = nearest_species(name)
        preset = name.split("=", 1)[0].strip()
        if not sp:
            print(f"peers: no treeform species for ez-tree preset {preset!r} (use \"{preset}=oak\") — skipped")
            continue
        jobs.append((preset, sp))
    if not jobs:
        return 0

    node_v = subprocess.run([shutil.which("node"), "--version"], capture_output=True, text=True).stdout.strip()
    versions = (f"ez-tree {_pkg_version('@dgreenheck/ez-tree')} + three {_pkg_version('three')} on node {node_v}")
    load_before = load_line()
    rows = []
    try:
        server = EzTreeServer()
    except PeerError as e:
        print(f"peers: {e} — skipped")
        return 0
    try:
        for preset, sp in jobs:
            try:
                rows.append(bench_preset(server, preset, sp, repeat, args.seed))
            except PeerError as e:
                print(f"peers: {preset}: {e} — skipped")
                if server.proc.poll() is not None:
                    break
            except (KeyError, ValueError, TypeError) as e:
                print(f"peers: {preset}: bad answer from the ez-tree server ({e!r}) — skipped")
    finally:
        server.close()
    if not rows:
        return 0

    cmd = "python benchmarks/bench_peers.py" + ("" if repeat == 15 else f" --repeat {repeat}")
    if [p for p, _ in jobs] != list(DEFAULT_PRESETS):
        cmd += " --presets " + " ".join(f'"{p}"' for p in args.presets)
    head = (f"Machine: {machine()}; {load_before} at the start, {load_line()} at the end.\n"
            f"Peer: {versions}. Date: {_dt.date.today().isoformat()}.\n"
            f"Medians of {repeat} alternating runs per side after {WARMUP} warm-up runs each; "
            f"treeform budget = the ez-tree triangle count; treeform seed {args.seed}.")
    tab = table(rows)
    print(head)
    print()
    print(tab)

    if args.write:
        section = (
            f"## Peers: ez-tree side by side — `{cmd}`\n\n"
            "ez-tree ([`@dgreenheck/ez-tree`](https://www.npmjs.com/package/@dgreenheck/ez-tree), a three.js\n"
            "procedural tree generator) runs under node (`benchmarks/peers/ez_tree.mjs`, versions pinned in\n"
            "`benchmarks/peers/package-lock.json`, installed by `npm ci` on first use). Its time is one\n"
            "`Tree.generate()` of the preset (branch tubes + leaf cards as three.js BufferGeometry, CPU only),\n"
            "timed in node. The treeform time is grow + leaves + mesh (`grow`; `twig_foliage` of only the\n"
            "clusters the budget keeps, `foliage_budget`, as `treeform grow` does; `tree_mesh(max_triangles=budget,\n"
            "radial_segments=8)`) of the nearest species preset — treeform has\n"
            "no ash or aspen, so Ash → maple and Aspen → birch — geometry only: no texture synthesis, no\n"
            "rendering, no export. The two trees are not the same tree; the budget makes the triangle counts\n"
            "comparable. Skipped with one line when node is missing.\n\n"
            f"{head}\n\n{tab}\n")
        write_section(BENCHMARKS_MD, "peers", section)
        print(f"\nwrote the peers section of {BENCHMARKS_MD.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
