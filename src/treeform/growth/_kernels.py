"""Compiled kernels of the phenomenological growth (numba): random numbers, tree sweeps, light, shoots.

Everything here works on flat arrays of a tree whose parents come first (``parent[i] < i``),
so a reverse index sweep visits every child before its parent and a forward sweep every
parent before its children — the tree sweeps need no depth buckets. The model itself is
documented in :mod:`treeform.growth.phenomenological`; this module only makes it fast (one
growth cycle of a 10k-node tree is a few hundred microseconds instead of tens of
milliseconds of NumPy calls).

Random numbers come from a SplitMix64 stream in a one-element ``uint64`` state array:
deterministic for a seed, independent of NumPy's and numba's own generators, and free of
global state (threads and Dask workers can grow trees side by side).
"""

from __future__ import annotations

import math

import numba as nb
import numpy as np

from treeform._shared.splitmix import next_u64

_S11 = np.uint64(11)
_TWO53 = 1.0 / 9007199254740992.0

# indices into the float parameter vector (see phenomenological._param_vector)
P_AAV, P_BAM, P_BAV, P_RAM, P_RAV, P_AKP, P_LKP, P_ALF, P_LLF = 0, 1, 2, 3, 4, 5, 6, 7, 8
P_ADB, P_ADF, P_AAF, P_GR, P_ILB, P_IAF, P_ACB, P_ACAF, P_ACLF = 9, 10, 11, 12, 13, 14, 15, 16, 17
P_MBA, P_LBF, P_PHO, P_GGB, P_GLF, P_PPF, P_LPF = 18, 19, 20, 21, 22, 23, 24
P_SIZE = 25

_JIT = dict(cache=True, nogil=True, error_model="numpy")  # no division-by-zero checks: the same IEEE results, faster loops


# ------------------------------------------------------------------------------ random numbers
def seed_state(rng: np.random.Generator) -> np.ndarray:
    """A SplitMix64 state (``uint64[1]``) drawn from a NumPy generator."""
    return np.array([rng.integers(0, 2**63, dtype=np.uint64)], np.uint64)


_next = next_u64  # SplitMix64 (treeform._shared.splitmix)


@nb.njit(**_JIT)
def uniform(state):
    """Uniform double in [0, 1)."""
    return float(_next(state) >> _S11) * _TWO53


@nb.njit(**_JIT)
def normal(state):
    """Standard normal (Box–Muller; one sample per two uniforms)."""
    u1 = 1.0 - uniform(state)
    u2 = uniform(state)
    return math.sqrt(-2.0 * math.log(u1)) * math.cos(2.0 * math.pi * u2)


# ------------------------------------------------------------------------------ small vectors
@nb.njit(**_JIT)
def _unit3(x, y, z):
    n = math.sqrt(x * x + y * y + z * z)
    n = max(n, 1e-12)
    return x / n, y / n, z / n


@nb.njit(**_JIT)
def _perp3(dx, dy, dz, vx, vy, vz):
    """Unit component of v perpendicular to unit d (a fixed perpendicular where v ∥ d)."""
    t = vx * dx + vy * dy + vz * dz
    wx, wy, wz = vx - t * dx, vy - t * dy, vz - t * dz
    n = math.sqrt(wx * wx + wy * wy + wz * wz)
    if n < 1e-6:
        if abs(dx) < 0.9:
            ax, ay, az = 1.0, 0.0, 0.0
        else:
            ax, ay, az = 0.0, 0.0, 1.0
        t = ax * dx + ay * dy + az * dz
        wx, wy, wz = ax - t * dx, ay - t * dy, az - t * dz
        n = math.sqrt(wx * wx + wy * wy + wz * wz)
    return wx / n, wy / n, wz / n


@nb.njit(**_JIT)
def _cross3(ax, ay, az, bx, by, bz):
    return ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx


# ------------------------------------------------------------------------------ tree sweeps
@nb.njit(**_JIT)
def accumulate(order, parent, values, factor):
    """``A[i] = values[i] + factor · Σ_children A[c]`` over the nodes ``order`` (ascending)."""
    a = values.copy()
    for t in range(len(order) - 1, -1, -1):
        i = order[t]
        p = parent[i]
        if p >= 0:
            a[p] += factor * a[i]
    return a


@nb.njit(**_JIT)
def accumulate_decay(order, parent, values, factor, pos):
    """``A[i] = values[i] + Σ_children factor^|c - i| · A[c]`` (decay per metre of internode)."""
    a = values.copy()
    for t in range(len(order) - 1, -1, -1):
        i = order[t]
        p = parent[i]
        if p >= 0:
            dx, dy, dz = pos[i, 0] - pos[p, 0], pos[i, 1] - pos[p, 1], pos[i, 2] - pos[p, 2]
            a[p] += factor ** math.sqrt(dx * dx + dy * dy + dz * dz) * a[i]
    return a


@nb.njit(**_JIT)
def subtree_max(order, parent, values):
    """Largest value in each node's subtree (itself included)."""
    a = values.copy()
    for t in range(len(order) - 1, -1, -1):
        i = order[t]
        p = parent[i]
        if p >= 0 and a[i] > a[p]:
            a[p] = a[i]
    return a


@nb.njit(**_JIT)
def spread(order, parent, flags):
    """``flags`` OR-ed down to every descendant."""
    f = flags.copy()
    for i in order:
        p = parent[i]
        if p >= 0 and f[p]:
            f[i] = True
    return f


@nb.njit(**_JIT)
def shed(order, parent, alive, cut):
    """Every node in the subtree of a ``cut`` node dies (``alive`` updated in place)."""
    dead = spread(order, parent, cut)
    for i in order:
        if dead[i]:
            alive[i] = False


@nb.njit(**_JIT)
def branch_levels(order, parent, weight, n):
    """Branch level of every node and which nodes start a lateral branch.

    At each node the child with the largest ``weight`` (lowest index on ties) continues the
    node's level; every other child starts a branch one level higher.
    """
    best = np.full(n, -1, np.int64)
    for i in order:
        p = parent[i]
        if p >= 0 and (best[p] < 0 or weight[i] > weight[best[p]]):
            best[p] = i
    starts = np.zeros(n, np.bool_)
    level = np.zeros(n, np.int64)
    for i in order:
        p = parent[i]
        if p >= 0:
            starts[i] = best[p] != i
            level[i] = level[p] + (1 if starts[i] else 0)
    return level, starts


@nb.njit(**_JIT)
def place(parent, root, segments):
    """Positions from segment vectors: ``p[i] = p[parent[i]] + segments[i]`` (parents first)."""
    n = len(parent)
    p = np.empty((n, 3))
    p[0] = root
    for i in range(1, n):
        q = parent[i]
        for k in range(3):
            p[i, k] = p[q, k] + segments[i, k]
    return p


@nb.njit(**_JIT)
def bend_segments(pos, parent, radius, strength, factor, tip_radius, n_fixed):
    """Internode vectors before and after gravity bending, ``(seg, bent)``, each (N, 3).

    Each internode's direction gets ``w · (0, -1, 0)`` added, ``w = strength ·
    factor^(r / tip_radius - 1)``, and keeps its length; the first ``n_fixed`` stay.
    """
    n = len(parent)
    seg = np.zeros((n, 3))
    bent = np.zeros((n, 3))
    for i in range(1, n):
        p = parent[i]
        dx, dy, dz = pos[i, 0] - pos[p, 0], pos[i, 1] - pos[p, 1], pos[i, 2] - pos[p, 2]
        seg[i, 0], seg[i, 1], seg[i, 2] = dx, dy, dz
        if i < n_fixed:
            bent[i, 0], bent[i, 1], bent[i, 2] = dx, dy, dz
            continue
        length = math.sqrt(dx * dx + dy * dy + dz * dz)
        w = strength * factor ** (radius[i] / tip_radius - 1.0)
        ux, uy, uz = _unit3(dx, dy, dz)
        ux, uy, uz = _unit3(ux, uy - w, uz)
        bent[i, 0], bent[i, 1], bent[i, 2] = ux * length, uy * length, uz * length
    return seg, bent


@nb.njit(**_JIT)
def ancestors_of(parent, flags):
    """Every node with a flagged node in its subtree (itself included)."""
    f = flags.copy()
    for i in range(len(parent) - 1, 0, -1):
        if f[i]:
            f[parent[i]] = True
    return f


@nb.njit(**_JIT)
def pipe_accumulate(parent, tip_value):
    """``acc[i] = tip_value`` at tips, else ``Σ_children acc[c]`` (parents first)."""
    n = len(parent)
    has_child = np.zeros(n, np.bool_)
    for i in range(1, n):
        has_child[parent[i]] = True
    acc = np.zeros(n)
    for i in range(n):
        if not has_child[i]:
            acc[i] = tip_value
    for i in range(n - 1, 0, -1):
        acc[parent[i]] += acc[i]
    return acc


@nb.njit(**_JIT)
def main_child_orders(parent, radius):
    """Branch order: the thickest child (lowest index on ties) continues its parent's order, others add one."""
    n = len(parent)
    best = np.full(n, -1, np.int64)
    for i in range(1, n):
        p = parent[i]
        if best[p] < 0 or radius[i] > radius[best[p]]:
            best[p] = i
    order = np.zeros(n, np.int32)
    for i in range(1, n):
        p = parent[i]
        order[i] = order[p] + (0 if best[p] == i else 1)
    return order


# ------------------------------------------------------------------------------ light
@nb.njit(**_JIT)
def shadow_grid(pos, order, voxel, a, depth, decay):
    """Shadow-propagation voxel grid (Palubicki et al. 2009 §4) over the nodes ``order``.

    ``s`` at a voxel is ``Σ a · decay^-q`` over the internodes in the ``(2q+1)²`` voxels ``q``
    layers above it, ``q = 0 … depth``, from one summed-area table per layer (layers without
    internodes are skipped).

    Returns
    -------
    shadow : ndarray, shape (nx, ny, nz)
    lo : ndarray, shape (3,)
        World position of voxel (0, 0, 0)'s corner.
    """
    mn = np.full(3, np.inf)
    mx = np.full(3, -np.inf)
    for i in order:
        for k in range(3):
            mn[k] = min(mn[k], pos[i, k])
            mx[k] = max(mx[k], pos[i, k])
    m = depth + 2
    lo_i = np.empty(3)
    shape = np.empty(3, np.int64)
    for k in range(3):
        lo_i[k] = math.floor(mn[k] / voxel) - m
        hi = math.floor(mx[k] / voxel) + (8 if k == 1 else m)
        shape[k] = int(hi - lo_i[k] + 1)
    lo = lo_i * voxel
    nx, ny, nz = shape[0], shape[1], shape[2]
    sat = np.zeros((ny, nx + 1, nz + 1))
    # per layer, the x and z range of its internodes (empty layers: lo > hi)
    xlo, xhi = np.full(ny, nx), np.full(ny, -1)
    zlo, zhi = np.full(ny, nz), np.full(ny, -1)
    for i in order:
        x = min(max(int(math.floor((pos[i, 0] - lo[0]) / voxel)), 0), nx - 1)
        y = min(max(int(math.floor((pos[i, 1] - lo[1]) / voxel)), 0), ny - 1)
        z = min(max(int(math.floor((pos[i, 2] - lo[2]) / voxel)), 0), nz - 1)
        sat[y, x + 1, z + 1] += 1.0
        xlo[y], xhi[y] = min(xlo[y], x), max(xhi[y], x)
        zlo[y], zhi[y] = min(zlo[y], z), max(zhi[y], z)
    for y in range(ny):
        if xhi[y] >= 0:
            for x in range(nx):
                for z in range(nz):
                    sat[y, x + 1, z + 1] += sat[y, x, z + 1] + sat[y, x + 1, z] - sat[y, x, z]
    shadow = np.zeros((nx, ny, nz))
    for y in range(ny):
        for q in range(depth + 1):
            yy = y + q
            if yy >= ny:
                break
            if xhi[yy] < 0:
                continue
            w = a * decay ** (-q)
            # the box of half-width q around (x, z) meets the layer's internodes only here
            for x in range(max(xlo[yy] - q, 0), min(xhi[yy] + q, nx - 1) + 1):
                r0, r1 = sat[yy, max(x - q, 0)], sat[yy, min(x + q, nx - 1) + 1]
                if r1[nz] == r0[nz]:  # no internode in these rows of the layer
                    continue
                out = shadow[x, y]
                for z in range(max(zlo[yy] - q, 0), min(zhi[yy] + q, nz - 1) + 1):
                    z0, z1 = max(z - q, 0), min(z + q, nz - 1) + 1
                    out[z] += w * (r1[z1] - r0[z1] - r1[z0] + r0[z0])
    return shadow, lo


@nb.njit(**_JIT)
def _voxel(shadow, lo, voxel, px, py, pz):
    nx, ny, nz = shadow.shape
    x = min(max(int(math.floor((px - lo[0]) / voxel)), 0), nx - 1)
    y = min(max(int(math.floor((py - lo[1]) / voxel)), 0), ny - 1)
    z = min(max(int(math.floor((pz - lo[2]) / voxel)), 0), nz - 1)
    return x, y, z


@nb.njit(**_JIT)
def exposure(shadow, lo, voxel, a, full_light, px, py, pz):
    """Light exposure in [0, 1]: ``clip(1 - (s - a) / full_light, 0, 1)``."""
    x, y, z = _voxel(shadow, lo, voxel, px, py, pz)
    return min(max(1.0 - (shadow[x, y, z] - a) / full_light, 0.0), 1.0)


@nb.njit(**_JIT)
def light_direction(shadow, lo, voxel, up_weight, px, py, pz):
    """Unit direction of most light: ``normalise(up_weight · ŷ - ∇s)``, ∇ by central
    differences (one-sided at the border, like numpy.gradient)."""
    x, y, z = _voxel(shadow, lo, voxel, px, py, pz)
    nx, ny, nz = shadow.shape
    x0, x1 = max(x - 1, 0), min(x + 1, nx - 1)
    y0, y1 = max(y - 1, 0), min(y + 1, ny - 1)
    z0, z1 = max(z - 1, 0), min(z + 1, nz - 1)
    gx = (shadow[x1, y, z] - shadow[x0, y, z]) / max(x1 - x0, 1)
    gy = (shadow[x, y1, z] - shadow[x, y0, z]) / max(y1 - y0, 1)
    gz = (shadow[x, y, z1] - shadow[x, y, z0]) / max(z1 - z0, 1)
    return _unit3(-gx, up_weight - gy, -gz)


@nb.njit(**_JIT)
def apical_control_table(P, year, size):
    """Growth-rate multipliers of cycle ``year`` (see phenomenological.apical_control).

    Returns ``(table, decurrent)``: ``table[k]`` is the multiplier of a shoot of branch level
    ``k`` while the control ``C >= 1``, or of a shoot ``k - 1`` levels below the top of its
    subtree once ``C < 1`` (``decurrent``).
    """
    c = P[P_ACB] * P[P_ACAF] ** year
    f = P[P_ACLF]
    table = np.ones(size)
    for k in range(1, size):
        step = 1.0 / (1.0 + (c - 1.0) * f ** k) if c >= 1.0 else 1.0 - (1.0 - c) * f ** k
        table[k] = table[k - 1] * step
    return table, c < 1.0


@nb.njit(**_JIT)
def alive_order(alive, n):
    return np.flatnonzero(alive[:n])


@nb.njit(**_JIT)
def tree_levels(order, pos, parent, n):
    """Branch levels and lateral-branch starts of the living tree, the main axis carrying the most wood."""
    seg = np.zeros(n)
    for i in order:
        p = parent[i]
        if p >= 0:
            dx, dy, dz = pos[i, 0] - pos[p, 0], pos[i, 1] - pos[p, 1], pos[i, 2] - pos[p, 2]
            seg[i] = math.sqrt(dx * dx + dy * dy + dz * dz)
    return branch_levels(order, parent, accumulate(order, parent, seg, 1.0), n)


@nb.njit(**_JIT)
def _lateral_direction(q, nlb, pos, parent, nside, node, P, state):
    """Direction and roll reference of lateral bud ``q`` of the internode ending at ``node``.

    The ``nlb`` buds are spread evenly around the internode from its rolled side
    ``nside[node]`` (jittered by up to ± G_BAV) at the branching angle (normal, σ = G_BAV / 2).
    A lateral bud's direction is drawn when it flushes: most buds die waiting, and their
    directions are never needed.
    """
    p = parent[node]
    dx, dy, dz = _unit3(pos[node, 0] - pos[p, 0], pos[node, 1] - pos[p, 1], pos[node, 2] - pos[p, 2])
    sx, sy, sz = nside[node, 0], nside[node, 1], nside[node, 2]
    bx, by, bz = _cross3(dx, dy, dz, sx, sy, sz)
    phi = 2.0 * math.pi * (q + 1) / nlb + math.radians((2.0 * uniform(state) - 1.0) * P[P_BAV])
    beta = math.radians(P[P_BAM] + normal(state) * (P[P_BAV] / 2.0))
    cp, sp = math.cos(phi), math.sin(phi)
    ux, uy, uz = cp * sx + sp * bx, cp * sy + sp * by, cp * sz + sp * bz
    cb, sb = math.cos(beta), math.sin(beta)
    ex, ey, ez = _unit3(cb * dx + sb * ux, cb * dy + sb * uy, cb * dz + sb * uz)
    px, py, pz = _perp3(ex, ey, ez, dx, dy, dz)
    return ex, ey, ez, px, py, pz


@nb.njit(**_JIT)
def begin_cycle(year, n, n_fixed, pos, parent, nyear, alive, nside, bnode, bq, bdir, bside, bapical, bage, nbud,
                P, nlb, voxel, young_years, full_light, shadow_depth, shadow_decay, state):
    """Light, branch levels, shedding and bud fate of one growth cycle.

    Buds: the node they sit on, ``bq`` (-1: ``bdir`` / ``bside`` hold the bud's direction
    and roll reference; ``q >= 0``: lateral bud ``q`` of its internode, direction drawn when
    it flushes), apical?, age in years. Updates ``alive`` in place and compacts the waiting
    buds (age + 1) to the front of the bud arrays. Returns ``(shadow, lo, nbud, s_node,
    s_dir, s_side, s_level, s_n, s_apical)`` — the light grid and the shoots of the buds that
    flush (``nbud < 0``: no bud left).
    """
    a = P[P_LBF]
    order = alive_order(alive, n)
    shadow, lo = shadow_grid(pos, order, voxel, a, shadow_depth, shadow_decay)
    light = np.zeros(n)
    for i in order:
        light[i] = exposure(shadow, lo, voxel, a, full_light, pos[i, 0], pos[i, 1], pos[i, 2])
    level, starts = tree_levels(order, pos, parent, n)

    # shedding of shaded lateral branches and of every lateral branch below the pruning height
    if year >= 1:
        young = np.zeros(n)
        lit0 = np.zeros(n)
        tot, cnt_young = 0.0, 0
        for i in order:
            if year - nyear[i] <= young_years:
                young[i] = 1.0
                lit0[i] = light[i]
                tot += light[i]
                cnt_young += 1
        lit = accumulate(order, parent, lit0, 1.0)
        cnt = accumulate(order, parent, young, 1.0)
        tree_light = tot / cnt_young if cnt_young else 1.0
        cut = np.zeros(n, np.bool_)
        any_cut = False
        for i in order:
            if i < n_fixed or not starts[i]:
                continue
            mean_light = lit[i] / cnt[i] if cnt[i] > 0 else 0.0
            shaded = (year - nyear[i] >= 2) and mean_light < P[P_PPF] * tree_light
            low = pos[parent[i], 1] < P[P_LPF]
            if shaded or low:
                cut[i] = True
                any_cut = True
        if any_cut:
            shed(order, parent, alive, cut)
            order = alive_order(alive, n)

    # bud fate: death by chance and by age
    k = 0
    for b in range(nbud):
        keep = alive[bnode[b]] and bage[b] <= P[P_MBA]
        if year >= 1:
            kill = P[P_AKP] if bapical[b] else P[P_LKP]
            if kill > 0.0 and uniform(state) < kill:
                keep = False
        if keep:
            bnode[k], bq[k], bapical[k], bage[k] = bnode[b], bq[b], bapical[b], bage[b]
            if bq[b] < 0:
                bdir[k] = bdir[b]
                bside[k] = bside[b]
            k += 1
    nbud = k
    empty_i = np.zeros(0, np.int64)
    empty_f = np.zeros((0, 3))
    if nbud == 0:
        return shadow, lo, -1, empty_i, empty_f, empty_f, empty_i, empty_i, np.zeros(0, np.bool_)

    # flushing under light and apical dominance: exp(-A) · I^F, A the auxin from above
    own = np.zeros(n)
    prod = P[P_ADB] * P[P_AAF] ** year
    for b in range(nbud):
        if bapical[b]:
            own[bnode[b]] += prod
    auxin = accumulate_decay(order, parent, own, P[P_ADF], pos)
    top = subtree_max(order, parent, level)
    ymax = -np.inf
    max_level = 0
    lateral_p = np.zeros(n)  # flush probability of a lateral bud at each node
    for i in order:
        ymax = max(ymax, pos[i, 1])
        max_level = max(max_level, level[i])
        f = P[P_LLF]
        lateral_p[i] = math.exp(-max(auxin[i], 0.0)) * (light[i] if f == 1.0 else light[i] ** f)
    low_shoots = ymax > P[P_LPF]  # no lateral shoots below the pruning height once the tree is above it
    control, decurrent = apical_control_table(P, year, max_level + 3)
    flush = np.zeros(nbud, np.bool_)
    s_n = np.zeros(nbud, np.int64)
    s_lev = np.zeros(nbud, np.int64)
    m = 0
    for b in range(nbud):
        i = bnode[b]
        if bapical[b]:
            prob = math.exp(-max(auxin[i] - own[i], 0.0)) * light[i] ** P[P_ALF]
        else:
            prob = lateral_p[i]
        if prob <= 0.0 or not uniform(state) < prob:  # (no draw where nothing can flush)
            continue
        if low_shoots and not bapical[b] and pos[i, 1] < P[P_LPF]:
            continue
        s_lev[b] = level[i] + (0 if bapical[b] else 1)
        rate = P[P_GR] * control[max(top[i] - s_lev[b] + 1, 0) if decurrent else max(s_lev[b], 0)]
        s_n[b] = int(math.floor(rate + uniform(state)))  # stochastic rounding
        flush[b] = s_n[b] > 0
        if flush[b]:
            m += 1

    s_node = np.empty(m, np.int64)
    s_dir = np.empty((m, 3))
    s_side = np.empty((m, 3))
    s_level = np.empty(m, np.int64)
    s_cnt = np.empty(m, np.int64)
    s_apical = np.empty(m, np.bool_)
    j, k = 0, 0
    for b in range(nbud):
        if flush[b]:
            s_node[j], s_level[j], s_cnt[j], s_apical[j] = bnode[b], s_lev[b], s_n[b], bapical[b]
            if bq[b] < 0:
                s_dir[j] = bdir[b]
                s_side[j] = bside[b]
            else:
                (s_dir[j, 0], s_dir[j, 1], s_dir[j, 2], s_side[j, 0], s_side[j, 1],
                 s_side[j, 2]) = _lateral_direction(bq[b], nlb, pos, parent, nside, bnode[b], P, state)
            j += 1
        else:  # waits a year
            bnode[k], bq[k], bapical[k], bage[k] = bnode[b], bq[b], bapical[b], bage[b] + 1
            if bq[b] < 0:
                bdir[k] = bdir[b]
                bside[k] = bside[b]
            k += 1
    return shadow, lo, k, s_node, s_dir, s_side, s_level, s_cnt, s_apical


@nb.njit(**_JIT)
def propose(k, s_ok, s_n, s_apical, s_level, s_dir, s_pos, shadow, lo, voxel, up_weight, length, P, state,
            act, new_dir, new_pos):
    """Step ``k`` of every active shoot: its next direction and end point; returns how many."""
    c = 0
    for j in range(len(s_n)):
        if not s_ok[j] or s_n[j] <= k:
            continue
        dx, dy, dz = s_dir[j, 0], s_dir[j, 1], s_dir[j, 2]
        if (s_apical[j] or k > 0) and P[P_AAV] > 0:
            # the deviation is 2-D normal with sigma AAV / 2 per axis: its size is Rayleigh
            # distributed, its direction uniform about the shoot
            ang = math.radians(P[P_AAV] / 2.0 * math.sqrt(-2.0 * math.log(1.0 - uniform(state))))
            e1x, e1y, e1z = _perp3(dx, dy, dz, 1.0, 0.0, 0.0)
            e2x, e2y, e2z = _cross3(dx, dy, dz, e1x, e1y, e1z)
            th = 2.0 * math.pi * uniform(state)
            ct, st = math.cos(th), math.sin(th)
            ux, uy, uz = ct * e1x + st * e2x, ct * e1y + st * e2y, ct * e1z + st * e2z
            ca, sa = math.cos(ang), math.sin(ang)
            dx, dy, dz = _unit3(ca * dx + sa * ux, ca * dy + sa * uy, ca * dz + sa * uz)
        lx, ly, lz = light_direction(shadow, lo, voxel, up_weight, s_pos[j, 0], s_pos[j, 1], s_pos[j, 2])
        g = P[P_GGB] + P[P_GLF] * s_level[j]  # positive: toward gravity (-Y)
        pho = P[P_PHO]
        dx, dy, dz = _unit3(dx + pho * lx, dy + pho * ly - g, dz + pho * lz)
        act[c] = j
        new_dir[c, 0], new_dir[c, 1], new_dir[c, 2] = dx, dy, dz
        new_pos[c, 0] = s_pos[j, 0] + length * dx
        new_pos[c, 1] = s_pos[j, 1] + length * dy
        new_pos[c, 2] = s_pos[j, 2] + length * dz
        c += 1
    return c


@nb.njit(**_JIT)
def commit(c, ok, act, new_dir, new_pos, year, n, pos, parent, nyear, alive, nside, nl, lnode,
           s_ok, s_grown, s_node, s_dir, s_side, s_pos, P, state):
    """Add the internodes ``ok`` of step proposals, listing their nodes in ``lnode`` (they carry
    the lateral buds); returns ``(n, nl)``.

    A shoot whose proposal is refused (into the ground, out of the envelope) stops, and its
    bud is shed. The internode rolls about its axis by the roll angle: its rolled side
    (``nside``) is where its lateral buds are spread from.
    """
    for t in range(c):
        j = act[t]
        if not ok[t]:
            s_ok[j] = False
            continue
        dx, dy, dz = new_dir[t, 0], new_dir[t, 1], new_dir[t, 2]
        idx = n
        pos[idx] = new_pos[t]
        parent[idx] = s_node[j]
        nyear[idx] = year
        alive[idx] = True
        n += 1
        roll = math.radians(P[P_RAM] + (2.0 * uniform(state) - 1.0) * P[P_RAV])
        sx, sy, sz = _perp3(dx, dy, dz, s_side[j, 0], s_side[j, 1], s_side[j, 2])
        bx, by, bz = _cross3(dx, dy, dz, sx, sy, sz)
        cr, sr = math.cos(roll), math.sin(roll)
        sx, sy, sz = cr * sx + sr * bx, cr * sy + sr * by, cr * sz + sr * bz
        nside[idx, 0], nside[idx, 1], nside[idx, 2] = sx, sy, sz
        lnode[nl] = idx
        nl += 1
        s_dir[j, 0], s_dir[j, 1], s_dir[j, 2] = dx, dy, dz
        s_side[j, 0], s_side[j, 1], s_side[j, 2] = sx, sy, sz
        s_pos[j] = new_pos[t]
        s_node[j] = idx
        s_grown[j] = True
    return n, nl


@nb.njit(**_JIT)
def end_shoots(nbud, bnode, bq, bdir, bside, bapical, bage, s_ok, s_grown, s_node, s_dir, s_side, nl, lnode, nlb):
    """After the waiting buds: a new apical bud at the end of every shoot that grew and was not
    stopped, then the ``nlb`` lateral buds of every new internode; returns nbud.

    The order matters: on a tie in wood the lower node index continues the branch (the
    apical shoot, grown first next cycle).
    """
    for j in range(len(s_ok)):
        if s_ok[j] and s_grown[j]:
            bnode[nbud], bq[nbud], bapical[nbud], bage[nbud] = s_node[j], -1, True, 0
            bdir[nbud] = s_dir[j]
            bside[nbud] = s_side[j]
            nbud += 1
    for t in range(nl):
        for q in range(nlb):
            bnode[nbud], bq[nbud], bapical[nbud], bage[nbud] = lnode[t], q, False, 0
            nbud += 1
    return nbud


@nb.njit(**_JIT)
def grow_shoots(year, n, pos, parent, nyear, alive, nside, nbud, bnode, bq, bdir, bside, bapical, bage, s_node,
                s_dir, s_side, s_level, s_n, s_apical, shadow, lo, voxel, up_weight, length, nlb, P, state):
    """All steps of this cycle's shoots with no envelope (only the ground stops them); returns (n, nbud)."""
    m = len(s_n)
    s_ok = np.ones(m, np.bool_)
    s_grown = np.zeros(m, np.bool_)
    s_pos = np.empty((m, 3))
    for j in range(m):
        s_pos[j] = pos[s_node[j]]
    act = np.empty(m, np.int64)
    new_dir = np.empty((m, 3))
    new_pos = np.empty((m, 3))
    ok = np.empty(m, np.bool_)
    steps = s_n.max() if m else 0
    nl = 0
    lnode = np.empty(s_n.sum(), np.int64)
    for k in range(steps):
        c = propose(k, s_ok, s_n, s_apical, s_level, s_dir, s_pos, shadow, lo, voxel, up_weight, length, P, state,
                    act, new_dir, new_pos)
        if c == 0:
            break
        for t in range(c):
            ok[t] = new_pos[t, 1] >= 0.0
        n, nl = commit(c, ok, act, new_dir, new_pos, year, n, pos, parent, nyear, alive, nside, nl, lnode,
                       s_ok, s_grown, s_node, s_dir, s_side, s_pos, P, state)
    return n, end_shoots(nbud, bnode, bq, bdir, bside, bapical, bage, s_ok, s_grown, s_node, s_dir, s_side, nl,
                         lnode, nlb)


@nb.njit(**_JIT)
def prune_low(n, n_fixed, pos, parent, alive, low_height):
    """Cut every lateral branch that starts below ``low_height`` (the last cycle's shoots too)."""
    order = alive_order(alive, n)
    level, starts = tree_levels(order, pos, parent, n)
    cut = np.zeros(n, np.bool_)
    any_cut = False
    for i in order:
        if i >= n_fixed and starts[i] and pos[parent[i], 1] < low_height:
            cut[i] = True
            any_cut = True
    if any_cut:
        shed(order, parent, alive, cut)
