"""The compiled growth kernels against plain NumPy references (exactness, not speed)."""

import numpy as np
import pytest

from treeform.growth import _kernels as K


def _random_tree(n=400, seed=0):
    rng = np.random.default_rng(seed)
    parent = np.full(n, -1, np.int64)
    for i in range(1, n):
        parent[i] = rng.integers(max(0, i - 30), i)  # parents first
    pos = np.zeros((n, 3))
    for i in range(1, n):
        pos[i] = pos[parent[i]] + rng.normal(0, 0.5, 3) + [0, 0.6, 0]
    return parent, pos, rng


def test_random_stream_is_seeded_uniform_and_normal():
    a = K.seed_state(np.random.default_rng(3))
    b = K.seed_state(np.random.default_rng(3))
    u = np.array([K.uniform(a) for _ in range(20000)])
    assert np.array_equal(u, [K.uniform(b) for _ in range(20000)])  # same seed, same stream
    assert u.min() >= 0 and u.max() < 1 and abs(u.mean() - 0.5) < 0.01
    assert abs(np.histogram(u, 10, (0, 1))[0] / len(u) - 0.1).max() < 0.01
    z = np.array([K.normal(a) for _ in range(20000)])
    assert abs(z.mean()) < 0.03 and abs(z.std() - 1) < 0.03
    c = K.seed_state(np.random.default_rng(4))
    assert K.uniform(c) != K.uniform(K.seed_state(np.random.default_rng(3)))


def test_tree_sweeps_match_references():
    parent, pos, rng = _random_tree()
    n = len(parent)
    alive = rng.random(n) < 0.9
    alive[0] = True
    for i in range(1, n):  # a dead node's subtree is dead
        alive[i] &= alive[parent[i]]
    order = np.flatnonzero(alive)
    vals = rng.random(n)

    ref = vals.copy()
    for i in order[::-1]:
        if parent[i] >= 0:
            ref[parent[i]] += 0.7 * ref[i]
    assert np.allclose(K.accumulate(order, parent, vals, 0.7), ref)

    ref = vals.copy()
    for i in order[::-1]:
        if parent[i] >= 0:
            ref[parent[i]] += 0.8 ** np.linalg.norm(pos[i] - pos[parent[i]]) * ref[i]
    assert np.allclose(K.accumulate_decay(order, parent, vals, 0.8, pos), ref)

    ref = vals.copy()
    for i in order[::-1]:
        if parent[i] >= 0:
            ref[parent[i]] = max(ref[parent[i]], ref[i])
    assert np.array_equal(K.subtree_max(order, parent, vals), ref)

    flags = rng.random(n) < 0.05
    got = K.spread(order, parent, flags)
    for i in order:
        anc, hit = i, False
        while anc >= 0:
            hit |= flags[anc]
            anc = parent[anc]
        assert got[i] == hit

    level, starts = K.branch_levels(order, parent, vals, n)
    for i in order[1:]:
        sibs = [c for c in order if parent[c] == parent[i]]
        main = max(sibs, key=lambda c: (vals[c], -c))
        assert starts[i] == (i != main)
        assert level[i] == level[parent[i]] + starts[i]


def test_pipe_radii_and_orders_match_the_rule():
    from treeform.growth.radii import branch_orders, pipe_model_radii

    parent, _, _ = _random_tree(200, seed=1)
    r = pipe_model_radii(parent, tip_radius=0.01, exponent=2.0)
    kids = [np.flatnonzero(parent == i) for i in range(len(parent))]
    for i, k in enumerate(kids):
        want = 0.01 if len(k) == 0 else np.sqrt(np.sum(r[k] ** 2))
        assert r[i] == pytest.approx(want)
    order = branch_orders(parent, r)
    for i, k in enumerate(kids):
        if len(k):
            main = max(k, key=lambda c: (r[c], -c))
            assert all(order[c] == order[i] + (c != main) for c in k)


def test_shadow_grid_equals_the_splatted_pyramids():
    rng = np.random.default_rng(2)
    pts = rng.uniform([-2, 0, -2], [2, 5, 2], (150, 3))
    voxel, a, depth, decay = 0.5, 0.5, 5, 2.0
    shadow, lo = K.shadow_grid(pts, np.arange(len(pts)), voxel, a, depth, decay)
    ref = np.zeros_like(shadow)
    ijk = np.floor((pts - lo) / voxel).astype(int)
    nx, ny, nz = shadow.shape
    for x, y, z in ijk:  # each internode shades the (2q+1)^2 voxels q layers below it
        for q in range(depth + 1):
            if y - q < 0:
                break
            ref[max(x - q, 0):min(x + q, nx - 1) + 1, y - q, max(z - q, 0):min(z + q, nz - 1) + 1] += a * decay ** -q
    assert np.allclose(shadow, ref)
    # light direction: up minus the numpy gradient, normalised
    g = np.stack(np.gradient(shadow), -1)
    for p in pts[:20]:
        i, j, k = np.floor((p - lo) / voxel).astype(int)
        want = np.array([0, 0.5, 0]) - g[i, j, k]
        assert np.allclose(K.light_direction(shadow, lo, voxel, 0.5, *p), want / np.linalg.norm(want))
        e = K.exposure(shadow, lo, voxel, a, 10.0, *p)
        assert e == pytest.approx(np.clip(1 - (shadow[i, j, k] - a) / 10.0, 0, 1))


def test_a_cold_cache_is_announced_once_and_a_warm_one_not(tmp_path):
    import os
    import subprocess
    import sys

    code = (
        "import logging, json\n"
        "from treeform._shared import jit\n"
        "from treeform.growth import _kernels\n"
        "from treeform.growth.phenomenological import _ENTRY_KERNELS, COMPILE_SECONDS, GrowthParameters, grow\n"
        "seen = []\n"
        "class H(logging.Handler):\n"
        "    def emit(self, r): seen.append(r.getMessage())\n"
        "log = logging.getLogger('treeform'); log.addHandler(H()); log.setLevel(logging.INFO)\n"
        "before = jit.cold_kernels(_kernels.__file__, names=_ENTRY_KERNELS)\n"
        "grow(GrowthParameters(age=2), seed=0); grow(GrowthParameters(age=2), seed=1)\n"
        "after = jit.cold_kernels(_kernels.__file__, names=_ENTRY_KERNELS)\n"
        "print(json.dumps([before, after, seen]))\n")
    env = {**os.environ, "NUMBA_CACHE_DIR": str(tmp_path)}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    import json

    before, after, seen = json.loads(out.stdout.strip().splitlines()[-1])
    assert before[0] == before[1] == 7 and after == [0, 7]  # every entry kernel compiled and cached
    notes = [m for m in seen if "compiling the growth kernels" in m]
    assert len(notes) == 1  # once per process
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=300)
    before, after, seen = json.loads(out.stdout.strip().splitlines()[-1])
    assert before == [0, 7] and not [m for m in seen if "compiling" in m]  # warm: silent
