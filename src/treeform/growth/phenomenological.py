"""Phenomenological bud-based tree growth (seed 003 §4.3, Appendix Tables 2–3).

The growth function of Stava et al. 2014 (after Měch & Prusinkiewicz 1996) with light from a
shadow-propagation voxel grid (Palubicki et al. 2009). The extracted paper names the
parameters (Table 3) but gives no formulas; where it is silent or garbled we follow the
standard published forms and the growth code the authors used for Table 2's trees, and say
so below. The cycles run in compiled kernels (:mod:`treeform.growth._kernels`, numba) with
their own seeded random stream. One growth cycle is one year; each cycle, over all buds:

1. **Light.** Every living internode casts shadow into the voxels below it in a pyramid,
   ``Δs = a · b^-q`` in the ``(2q+1) × (2q+1)`` voxels ``q`` layers down, ``q = 0 … q_max``
   (Palubicki et al. 2009 §4; ``a`` = ``light_blocking_factor``, ``b`` =
   :data:`SHADOW_DECAY`). The light exposure at a voxel is
   ``I = clip(1 - (s - a) / C, 0, 1)`` (``+ a`` removes the internode's own shadow, ``C`` =
   :data:`FULL_LIGHT`), and the direction of most light is ``normalise(a · ŷ - ∇s)``.
2. **Branch levels.** At every node the child carrying the most wood continues the node's
   branch level; the others start lateral branches one level higher (recomputed yearly).
3. **Shedding.** A lateral branch at least two years old whose leaf-bearing (young)
   internodes receive a mean exposure below ``pruning_factor`` times the tree's mean is
   shed; every lateral branch attached lower than ``low_branch_pruning_factor`` metres is cut.
4. **Bud fate.** Apical / lateral buds die with probability ``apical_bud_kill_probability``
   / ``lateral_bud_kill_probability`` per cycle, and when older than ``max_bud_age``. A bud
   flushes with probability ``exp(-A) · I^F``, ``F`` the apical / lateral bud lighting
   factor, ``A`` the auxin reaching its node: every apical bud produces
   ``apical_dominance_base · apical_dominance_age_factor^t`` and the auxin is multiplied by
   ``apical_dominance_distance_factor`` per metre it travels down the shoots.
5. **Shoots.** A flushing bud grows ``growth_rate · m`` internodes (stochastic rounding),
   ``m`` the apical control of its branch level (:func:`apical_control`), each
   ``internode_length_base · internode_length_age_factor^t`` metres long. Each internode
   points along ``normalise(d + phototropism · L + g · (0, -1, 0))`` (the vector sum of
   Měch & Prusinkiewicz and Palubicki et al.), with ``d`` the previous direction turned by a
   random apical angle, ``L`` the direction of most light and ``g = gravitropism_base +
   gravitropism_level_factor · level`` (positive: toward gravity). It rolls about its axis
   by ``roll_angle_mean`` and carries ``lateral_buds`` lateral buds spread evenly around it
   at ``branching_angle_mean`` from it, and a new apical bud at its end. Nothing grows into
   the ground; with an envelope (§4.3, §4.4.1) an internode that would end outside it is not
   created and its bud is shed.

After ``age`` cycles the radii follow the pipe model and gravity bends every internode:
its direction gets ``w · (0, -1, 0)`` added, ``w = gravity_bending_strength ·
gravity_bending_angle_factor^(r / r_tip - 1)`` (thin twigs sag, thick limbs hardly do).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, fields, replace

import numpy as np

from treeform._shared.errors import InputError
from treeform._shared.rng import as_rng
from treeform._shared.timing import ProgressCallback, StageTimer
from treeform._shared.jit import announce_compile
from treeform.structures.skeleton import TreeSkeleton

__all__ = ["GrowthParameters", "PARAMETER_SYMBOLS", "apical_control", "grow"]

SHADOW_DECAY = 2.0
"""``b`` of the shadow pyramid ``Δs = a · b^-q`` (Palubicki et al. 2009)."""
SHADOW_DEPTH = 5
"""``q_max``: layers below an internode its shadow pyramid reaches."""
FULL_LIGHT = 10.0
"""Shadow ``s - a`` at which a bud's light exposure reaches 0 (Palubicki's full exposure C)."""
LIGHT_UP_BIAS = 1.0
"""Weight of +Y, in units of ``a``, against the shadow gradient in the direction of most light."""
VOXEL_FACTOR = 1.05
"""Voxel edge of the shadow grid, in units of ``internode_length_base``."""
YOUNG_YEARS = 2
"""Internodes at most this many years old carry leaves (they collect light for shedding)."""
TIP_RADIUS = 0.005
"""Radius of a terminal twig in metres (pipe model)."""
PIPE_EXPONENT = 2.0
"""Pipe-model exponent: ``r_parent^e = Σ r_child^e`` (2 = Leonardo's rule)."""

_UP = np.array([0.0, 1.0, 0.0])

log = logging.getLogger(__name__)

COMPILE_SECONDS = 15
"""Rough time numba takes to compile the growth kernels the first time (measured: 14 s on 2 cores)."""
_ENTRY_KERNELS = frozenset({"begin_cycle", "grow_shoots", "prune_low", "bend_segments", "place",
                            "pipe_accumulate", "main_child_orders"})


@dataclass
class GrowthParameters:
    """Every parameter of the phenomenological growth model (seed 003 Appendix Table 3).

    The defaults are Table 2's oak. Angles are in degrees, lengths in metres, time in years
    (growth cycles). Each field's docstring gives Table 3's symbol and meaning; the extracted
    table prints F_AAF and F_ALF twice, the second time for the apical control age and level
    factors (called F_ACAF and F_ACLF here).
    """

    lateral_buds: int = 3
    """G_NLB – number of lateral buds created per internode during growth."""
    apical_angle_variance: float = 20.0
    """G_AAV – variance (degrees) of the angle between the direction of the parent shoot and
    the direction of its apical bud: the deviation is 2-D normal with σ = G_AAV / 2 per axis,
    as in the authors' code."""
    branching_angle_mean: float = 29.0
    """G_BAM – mean angle (degrees) between the direction of the parent shoot and a lateral bud."""
    branching_angle_variance: float = 2.0
    """G_BAV – variance (degrees) of the branching angle: normal with σ = G_BAV / 2; the
    buds' positions around the internode are jittered by up to ± G_BAV too (authors' code)."""
    roll_angle_mean: float = 91.0
    """G_RAM – mean orientation (roll) angle (degrees) of the lateral buds of a new internode
    relative to those of the previous one. The buds of one internode are spread evenly
    around it (360° / G_NLB apart) and the internode rolls about its axis by this angle, as
    in the authors' code; the extracted Table 3 wording ("between two lateral buds created
    with the same internode") is ambiguous about which pair of buds is meant."""
    roll_angle_variance: float = 1.0
    """G_RAV – variance (degrees) of the roll angle: uniform within ± G_RAV (authors' code)."""
    apical_bud_kill_probability: float = 0.0
    """F_AKP – probability that a given apical bud dies during a growth cycle."""
    lateral_bud_kill_probability: float = 0.21
    """F_LKP – probability that a given lateral bud dies during a growth cycle."""
    apical_bud_lighting_factor: float = 0.39
    """F_ALF – influence of the light exposure I (0–1) on an apical bud's growth probability,
    which is proportional to I ** F_ALF (0: light does not matter)."""
    lateral_bud_lighting_factor: float = 1.0
    """F_LLF – influence of the light exposure I on a lateral bud's growth probability (I ** F_LLF)."""
    apical_dominance_base: float = 3.13
    """F_ADB – base level of auxin an apical bud produces to inhibit the buds below it from
    growing (a bud under auxin A flushes exp(-A) times as often)."""
    apical_dominance_distance_factor: float = 0.13
    """F_ADF – reduction of auxin by transmission along parent shoots: factor per metre."""
    apical_dominance_age_factor: float = 0.82
    """F_AAF – reduction of auxin with the tree's age: production ADB · F_AAF^t in year t."""
    growth_rate: float = 3.0
    """F_GR – expected number of internodes a shoot generates during a growth cycle."""
    internode_length_base: float = 1.0
    """F_ILB – base distance (metres) between two adjacent internodes on the same shoot."""
    internode_length_age_factor: float = 0.93
    """F_IAF – internode length factor per year of the tree's age (length ILB · IAF^t)."""
    apical_control_base: float = 2.2
    """F_ACB – impact of the branch level on the growth rate: with control C > 1 each branch
    level grows about C times fewer internodes than its parent level (excurrent); with C < 1
    the outermost shoots grow fastest (decurrent). See :func:`apical_control`."""
    apical_control_age_factor: float = 0.5
    """F_ACAF (printed a second time as F_AAF) – relation of the apical control to the tree's
    age: C(t) = F_ACB · F_ACAF^t."""
    apical_control_level_factor: float = 1.0
    """F_ACLF (printed a second time as F_ALF) – relation of the apical control to the branch
    level: the step from level k - 1 to k is 1 + (C - 1) · F_ACLF^k."""
    max_bud_age: float = 20.0
    """F_MBA – maximum life time (years) of a bud before forming a new shoot; older buds die."""
    light_blocking_factor: float = 0.5
    """E_LBF – how much light an internode (its branch and leaves) blocks: the shadow ``a`` it
    casts into its own voxel (``a · b^-q`` in the voxels q layers below)."""
    phototropism: float = 0.32
    """E_PHO – impact of the direction of most incoming light: its weight in a new
    internode's direction."""
    gravitropism_base: float = 0.08
    """E_GGB – impact of the direction of gravity: its weight in a new internode's direction
    (positive: shoots turn down, negative: up; the authors' convention)."""
    gravitropism_level_factor: float = -0.03
    """E_GLF – relation of the gravitropism to the branch level: weight E_GGB + E_GLF · level."""
    pruning_factor: float = 0.7
    """E_PPF – impact of the incoming light on shedding: a lateral branch whose leaf-bearing
    internodes receive less than E_PPF times the tree's mean light exposure is shed."""
    low_branch_pruning_factor: float = 1.3
    """E_LPF – height (metres) below which all lateral branches are pruned."""
    gravity_bending_strength: float = 0.72
    """E_GBS – impact of gravity on structural bending: the downward weight (0–1) added to the
    direction of a terminal twig."""
    gravity_bending_angle_factor: float = 0.83
    """E_GAF – relation of gravity bending to branch thickness: the weight is multiplied by
    E_GAF per twig radius of extra thickness (E_GBS · E_GAF^(r / r_tip - 1))."""
    age: int = 10
    """t – desired age of the tree in years (number of growth cycles)."""

    def validate(self) -> "GrowthParameters":
        """Check every value; raise :class:`InputError` naming the first bad one."""
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, bool) or not isinstance(v, (int, float, np.integer, np.floating)) or not math.isfinite(v):
                raise InputError(f"{f.name}: expected a finite number, got {v!r}")
        for name in ("lateral_buds", "age"):
            v = getattr(self, name)
            if float(v) != int(v):
                raise InputError(f"{name}: expected an integer, got {v!r}")
            setattr(self, name, int(v))
        for f in fields(self):
            if f.name not in ("lateral_buds", "age"):
                setattr(self, f.name, float(getattr(self, f.name)))
        if not 0 <= self.lateral_buds <= 8:
            raise InputError(f"lateral_buds: expected 0..8, got {self.lateral_buds}")
        if not 1 <= self.age <= 60:
            raise InputError(f"age: expected 1..60 years, got {self.age}")
        for name in ("apical_bud_kill_probability", "lateral_bud_kill_probability"):
            if not 0 <= getattr(self, name) <= 1:
                raise InputError(f"{name}: expected a probability in [0, 1], got {getattr(self, name)}")
        for name in ("apical_angle_variance", "branching_angle_variance", "roll_angle_variance",
                     "apical_bud_lighting_factor", "lateral_bud_lighting_factor", "apical_dominance_base",
                     "light_blocking_factor", "pruning_factor", "low_branch_pruning_factor",
                     "gravity_bending_strength"):
            if getattr(self, name) < 0:
                raise InputError(f"{name}: expected a non-negative number, got {getattr(self, name)}")
        for name in ("growth_rate", "internode_length_base", "internode_length_age_factor", "apical_control_base",
                     "apical_control_age_factor", "apical_control_level_factor", "max_bud_age",
                     "apical_dominance_distance_factor", "apical_dominance_age_factor",
                     "gravity_bending_angle_factor"):
            if not getattr(self, name) > 0:
                raise InputError(f"{name}: expected a positive number, got {getattr(self, name)}")
        if self.gravity_bending_strength >= 1:
            raise InputError(f"gravity_bending_strength: expected < 1, got {self.gravity_bending_strength}")
        return self

    def to_dict(self) -> dict:
        """Field name -> value (JSON-ready: every field is a number)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @classmethod
    def from_dict(cls, d: dict, *, base: "GrowthParameters | None" = None) -> "GrowthParameters":
        """Build from a dict of field values; unknown names raise :class:`InputError`.

        Fields missing from ``d`` come from ``base`` (default: every field required).
        """
        if not isinstance(d, dict):
            raise InputError(f"parameters: expected a mapping, got {type(d).__name__}")
        names = [f.name for f in fields(cls)]
        unknown = sorted(set(d) - set(names))
        if unknown:
            raise InputError(f"parameters: unknown name(s) {', '.join(unknown)}; known: {', '.join(names)}")
        if base is None:
            missing = [n for n in names if n not in d]
            if missing:
                raise InputError(f"parameters: missing {', '.join(missing)}")
            return cls(**d).validate()
        return replace(base, **d).validate()


PARAMETER_SYMBOLS = {
    "lateral_buds": "G_NLB", "apical_angle_variance": "G_AAV", "branching_angle_mean": "G_BAM",
    "branching_angle_variance": "G_BAV", "roll_angle_mean": "G_RAM", "roll_angle_variance": "G_RAV",
    "apical_bud_kill_probability": "F_AKP", "lateral_bud_kill_probability": "F_LKP",
    "apical_bud_lighting_factor": "F_ALF", "lateral_bud_lighting_factor": "F_LLF",
    "apical_dominance_base": "F_ADB", "apical_dominance_distance_factor": "F_ADF",
    "apical_dominance_age_factor": "F_AAF", "growth_rate": "F_GR", "internode_length_base": "F_ILB",
    "internode_length_age_factor": "F_IAF", "apical_control_base": "F_ACB",
    "apical_control_age_factor": "F_ACAF", "apical_control_level_factor": "F_ACLF", "max_bud_age": "F_MBA",
    "light_blocking_factor": "E_LBF", "phototropism": "E_PHO", "gravitropism_base": "E_GGB",
    "gravitropism_level_factor": "E_GLF", "pruning_factor": "E_PPF", "low_branch_pruning_factor": "E_LPF",
    "gravity_bending_strength": "E_GBS", "gravity_bending_angle_factor": "E_GAF", "age": "t",
}
"""Field name -> the symbol of seed 003 Table 3 (F_ACAF / F_ACLF are printed F_AAF / F_ALF there)."""


def apical_control(params: GrowthParameters, level, year, *, top_level=None) -> np.ndarray:
    """Growth-rate multiplier (0–1) of a shoot of branch ``level`` in cycle ``year`` (seed 003 Table 3).

    The apical control of the tree at age ``t`` is ``C = ACB · ACAF^t``. While ``C >= 1``
    (excurrent growth) each branch level grows ``1 + (C - 1) · ACLF^k`` times fewer
    internodes than the level below it: ``m = 1 / Π_{k=1..level} (1 + (C - 1) · ACLF^k)``.
    Once ``C < 1`` (decurrent growth) the order reverses: the outermost shoots of a branch
    grow fastest, the inner ones ``m = Π_{k=1..r} (1 - (1 - C) · ACLF^k)`` with
    ``r = top_level - level + 1`` (``top_level``: highest branch level in the subtree the bud
    sits on). The extracted text gives no formula; this is the form of the authors' growth
    code (Li et al.'s TreeUtilities), which produced Table 2's trees.

    Parameters
    ----------
    params : GrowthParameters
    level : array_like of int, shape (K,)
        Branch level of each shoot (0: trunk).
    year : int
    top_level : array_like of int, shape (K,), optional
        Needed once ``C < 1``; default ``level``.

    Returns
    -------
    ndarray, shape (K,)

    Examples
    --------
    >>> p = GrowthParameters(apical_control_base=3.0, apical_control_age_factor=1.0)
    >>> apical_control(p, [0, 1, 2], 0).round(3).tolist()
    [1.0, 0.333, 0.111]
    >>> p = GrowthParameters(apical_control_base=0.5, apical_control_age_factor=1.0)
    >>> apical_control(p, [0, 1, 2], 0, top_level=[2, 2, 2]).round(3).tolist()
    [0.125, 0.25, 0.5]
    """
    level = np.asarray(level, np.int64)
    c = params.apical_control_base * params.apical_control_age_factor ** year
    f = params.apical_control_level_factor
    if c >= 1:
        idx = np.clip(level, 0, None)
        steps = 1.0 + (c - 1.0) * f ** np.arange(1, int(idx.max(initial=0)) + 1)
    else:
        top = level if top_level is None else np.asarray(top_level, np.int64)
        idx = np.clip(top - level + 1, 0, None)
        steps = 1.0 / (1.0 - (1.0 - c) * f ** np.arange(1, int(idx.max(initial=0)) + 1))
    table = 1.0 / np.concatenate([[1.0], np.cumprod(steps)])
    return table[idx]


# ------------------------------------------------------------------------------------- helpers
def _unit(v: np.ndarray) -> np.ndarray:
    return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-12)


def _perpendicular(d: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Unit component of ``v`` perpendicular to unit ``d`` (any perpendicular where ``v ∥ d``)."""
    w = v - np.sum(v * d, axis=-1, keepdims=True) * d
    n = np.linalg.norm(w, axis=-1)
    bad = n < 1e-6
    if np.any(bad):
        alt = np.where(np.abs(d[bad, :1]) < 0.9, np.array([[1.0, 0, 0]]), np.array([[0, 0, 1.0]]))
        w[bad] = alt - np.sum(alt * d[bad], axis=-1, keepdims=True) * d[bad]
        n[bad] = np.linalg.norm(w[bad], axis=-1)
    return w / n[..., None]


# ------------------------------------------------------------------------------------- growth
def _check_envelope(envelope):
    if envelope is None:
        return None
    contains = getattr(envelope, "contains", None)
    if not callable(contains):
        raise InputError(f"envelope: expected an object with contains(points) -> bool array, "
                         f"got {type(envelope).__name__}")

    def inside(points: np.ndarray) -> np.ndarray:
        ok = np.asarray(contains(points), bool).reshape(-1)
        if ok.shape != (len(points),):
            raise InputError(f"envelope.contains: expected {len(points)} booleans, got shape {ok.shape}")
        return ok

    return inside


def grow(params: GrowthParameters, *, seed=0, envelope=None, initial: TreeSkeleton | None = None,
         progress: ProgressCallback | None = None) -> TreeSkeleton:
    """Grow a tree with the phenomenological bud-based model (seed 003 §4.3, Tables 2–3).

    See the module docstring for the growth function. The root is at the origin, the trunk
    starts along +Y.

    Parameters
    ----------
    params : GrowthParameters
        E.g. from :func:`treeform.growth.species.load_species`.
    seed : int or numpy.random.Generator
        Same parameters + seed -> identical skeleton.
    envelope : object, optional
        Anything with ``contains(points (N, 3)) -> (N,) bool`` (e.g. a
        :class:`~treeform.structures.RadialBoundingVolume`); it must contain the origin.
        Growth stays inside (seed 003 §4.3, §4.4.1): an internode that would end outside is
        not created and its bud is shed. Gravity bending is undone where it would move a
        node outside.
    initial : TreeSkeleton, optional
        A scaffold to grow from (seed 003 §4.4.1: the crown grows phenomenologically on the
        structure the self-organizing mode made). Its nodes come first in the result, in
        their order, are never shed or bent, and carry apical buds at its tips and
        lateral buds along it (above the pruning height); its root must be the origin.
    progress : callable, optional
        ``progress(stage, event, seconds)`` for the stages ``"grow"`` and ``"structure"``.

    Returns
    -------
    TreeSkeleton
        positions (N, 3) in metres (Y up), parent (``parent[i] < i``), pipe-model radius,
        branch order, and age = the growth cycle (year, 0-based) that created each node.
        ``meta`` holds the parameters and the seed.

    Examples
    --------
    >>> sk = grow(GrowthParameters(age=3), seed=1)
    >>> bool(sk.positions[:, 1].max() > 1), sk.n_nodes == grow(GrowthParameters(age=3), seed=1).n_nodes
    (True, True)
    """
    from treeform.growth import _kernels as _k  # numba: imported when a tree grows, not with the parameters

    if not isinstance(params, GrowthParameters):
        raise InputError(f"params: expected a GrowthParameters, got {type(params).__name__}")
    p = replace(params).validate()
    inside = _check_envelope(envelope)
    if inside is not None and not inside(np.zeros((1, 3)))[0]:
        raise InputError("envelope: must contain the tree's base (the origin)")
    rng = as_rng(seed)
    timer = StageTimer(progress)
    if initial is not None:
        if not isinstance(initial, TreeSkeleton):
            raise InputError(f"initial: expected a TreeSkeleton, got {type(initial).__name__}")
        if not np.allclose(initial.positions[0], 0.0):
            raise InputError("initial: the scaffold's root must be at the origin")
    announce_compile(log, "the growth kernels", COMPILE_SECONDS, _k.__file__, names=_ENTRY_KERNELS)
    with timer.stage("grow"):
        nodes = _simulate(p, rng, inside, initial)
    with timer.stage("structure"):
        skeleton = _structure(p, nodes, inside, 0 if initial is None else initial.n_nodes)
    skeleton.meta = {"method": "phenomenological",
                     "seed": int(seed) if isinstance(seed, (int, np.integer)) else None, "parameters": p.to_dict()}
    return skeleton


def _scaffold_buds(p: GrowthParameters, sk: TreeSkeleton, rng: np.random.Generator, outer: float = 1 / 3):
    """Apical buds at a scaffold's tips; lateral buds on the outer third of every branch above the pruning height.

    The crown grows at the scaffold's periphery, as foliage does, instead of sprouting
    along the bare main branches the scaffold reproduces."""
    n = sk.n_nodes
    seg = np.zeros((n, 3))
    seg[1:] = sk.positions[1:] - sk.positions[sk.parent[1:]]
    seg[0] = _UP
    d = _unit(np.where(np.linalg.norm(seg, axis=1, keepdims=True) > 1e-12, seg, _UP))
    tips = sk.tips()
    tips = tips[tips > 0]
    outer_part = np.zeros(n, bool)
    for chain in sk.chains():
        body = chain[1:] if len(chain) > 1 and sk.parent[chain[1]] == chain[0] and chain[0] != 0 else chain
        outer_part[body[int(len(body) * (1 - outer)):]] = True
    lat = np.flatnonzero((sk.positions[:, 1] >= p.low_branch_pruning_factor) & (np.arange(n) > 0) & outer_part)
    nlb = max(p.lateral_buds, 1)
    lat_node = np.repeat(lat, nlb)
    ld = d[lat_node]
    side = _perpendicular(ld, _unit(rng.normal(size=ld.shape)))
    binorm = np.cross(ld, side)
    phi = rng.uniform(0, 2 * np.pi, len(lat_node))[:, None]
    beta = np.radians(p.branching_angle_mean + rng.normal(0.0, p.branching_angle_variance / 2.0, len(lat_node)))[:, None]
    ldir = _unit(np.cos(beta) * ld + np.sin(beta) * (np.cos(phi) * side + np.sin(phi) * binorm))
    b_node = np.concatenate([tips, lat_node])
    b_dir = np.concatenate([d[tips], ldir])
    b_side = _perpendicular(b_dir, _unit(rng.normal(size=b_dir.shape)))
    b_apical = np.concatenate([np.ones(len(tips), bool), np.zeros(len(lat_node), bool)])
    return b_node.astype(np.int64), b_dir, b_side, b_apical, np.zeros(len(b_node), np.int64)


def _param_vector(p: GrowthParameters) -> np.ndarray:
    """The float parameters in the kernels' order (:mod:`treeform.growth._kernels` ``P_*``)."""
    from treeform.growth import _kernels as _k

    v = np.empty(_k.P_SIZE)
    for idx, name in ((_k.P_AAV, "apical_angle_variance"), (_k.P_BAM, "branching_angle_mean"),
                      (_k.P_BAV, "branching_angle_variance"), (_k.P_RAM, "roll_angle_mean"),
                      (_k.P_RAV, "roll_angle_variance"), (_k.P_AKP, "apical_bud_kill_probability"),
                      (_k.P_LKP, "lateral_bud_kill_probability"), (_k.P_ALF, "apical_bud_lighting_factor"),
                      (_k.P_LLF, "lateral_bud_lighting_factor"), (_k.P_ADB, "apical_dominance_base"),
                      (_k.P_ADF, "apical_dominance_distance_factor"), (_k.P_AAF, "apical_dominance_age_factor"),
                      (_k.P_GR, "growth_rate"), (_k.P_ILB, "internode_length_base"),
                      (_k.P_IAF, "internode_length_age_factor"), (_k.P_ACB, "apical_control_base"),
                      (_k.P_ACAF, "apical_control_age_factor"), (_k.P_ACLF, "apical_control_level_factor"),
                      (_k.P_MBA, "max_bud_age"), (_k.P_LBF, "light_blocking_factor"), (_k.P_PHO, "phototropism"),
                      (_k.P_GGB, "gravitropism_base"), (_k.P_GLF, "gravitropism_level_factor"),
                      (_k.P_PPF, "pruning_factor"), (_k.P_LPF, "low_branch_pruning_factor")):
        v[idx] = float(getattr(p, name))
    return v


class _Tree:
    """Growable arrays of the internodes (node i ends the internode from parent[i]) and of the buds."""

    def __init__(self, cap: int = 16384):
        self.n = 0
        self.pos = np.empty((cap, 3))
        self.parent = np.empty(cap, np.int64)
        self.year = np.empty(cap, np.int64)
        self.alive = np.empty(cap, bool)
        self.side = np.zeros((cap, 3))  # rolled side of each internode: its lateral buds spread from it
        self.nbud = 0
        self.bnode = np.empty(cap, np.int64)
        self.bq = np.empty(cap, np.int64)  # -1: direction in bdir / bside; q >= 0: lateral bud q of its internode
        self.bdir = np.empty((cap, 3))
        self.bside = np.empty((cap, 3))
        self.bapical = np.empty(cap, bool)
        self.bage = np.empty(cap, np.int64)

    @staticmethod
    def _grow(arrays, used: int, need: int):
        if need <= len(arrays[0]):
            return arrays
        cap = max(need, 2 * len(arrays[0]))
        out = []
        for old in arrays:
            new = np.empty((cap,) + old.shape[1:], old.dtype)
            new[:used] = old[:used]
            out.append(new)
        return out

    def reserve(self, nodes: int, buds: int) -> None:
        """Room for ``nodes`` more internodes and ``buds`` buds in all."""
        self.pos, self.parent, self.year, self.alive, self.side = self._grow(
            [self.pos, self.parent, self.year, self.alive, self.side], self.n, self.n + nodes)
        self.bnode, self.bq, self.bdir, self.bside, self.bapical, self.bage = self._grow(
            [self.bnode, self.bq, self.bdir, self.bside, self.bapical, self.bage], self.nbud, buds)

    def add_nodes(self, pos, parent, year) -> None:
        self.reserve(len(pos), 0)
        s = slice(self.n, self.n + len(pos))
        self.pos[s], self.parent[s], self.year[s], self.alive[s] = pos, parent, year, True
        self.n += len(pos)

    def set_buds(self, node, direction, side, apical, age) -> None:
        self.reserve(0, len(node))
        s = slice(0, len(node))
        self.bnode[s], self.bdir[s], self.bside[s], self.bapical[s], self.bage[s] = node, direction, side, apical, age
        self.bq[s] = -1
        self.nbud = len(node)


def _simulate(p: GrowthParameters, rng: np.random.Generator, inside, initial: TreeSkeleton | None = None):
    """Run ``p.age`` growth cycles (see the module docstring); returns the tree of every node ever grown."""
    from treeform.growth import _kernels as _k

    tree = _Tree()
    state = _k.seed_state(rng)
    if initial is None:
        tree.add_nodes(np.zeros((1, 3)), [-1], 0)
        # buds: node they sit on, direction, roll reference ("side", perpendicular to the direction), apical?, age
        tree.set_buds([0], _UP[None], [[1.0, 0.0, 0.0]], [True], [0])
        n_fixed = 0
    else:
        tree.add_nodes(initial.positions, initial.parent, 0)
        tree.set_buds(*_scaffold_buds(p, initial, rng))
        n_fixed = initial.n_nodes
    P = _param_vector(p)
    voxel = VOXEL_FACTOR * p.internode_length_base
    up_weight = LIGHT_UP_BIAS * max(p.light_blocking_factor, 1e-3)
    nlb = int(p.lateral_buds)
    for year in range(p.age):
        t = tree
        shadow, lo, nbud, s_node, s_dir, s_side, s_level, s_n, s_apical = _k.begin_cycle(
            year, t.n, n_fixed, t.pos, t.parent, t.year, t.alive, t.side, t.bnode, t.bq, t.bdir, t.bside, t.bapical,
            t.bage, t.nbud, P, nlb, voxel, YOUNG_YEARS, FULL_LIGHT, SHADOW_DEPTH, SHADOW_DECAY, state)
        if nbud < 0:
            t.nbud = 0
            break
        t.nbud = nbud
        steps = int(s_n.sum())
        tree.reserve(steps, nbud + steps * nlb + len(s_n))
        length = p.internode_length_base * p.internode_length_age_factor ** year
        if inside is None:
            t.n, t.nbud = _k.grow_shoots(year, t.n, t.pos, t.parent, t.year, t.alive, t.side, t.nbud, t.bnode, t.bq,
                                         t.bdir, t.bside, t.bapical, t.bage, s_node, s_dir, s_side, s_level, s_n,
                                         s_apical, shadow, lo, voxel, up_weight, length, nlb, P, state)
            continue
        # with an envelope the same steps run one at a time, the envelope asked in between
        m = len(s_n)
        s_ok, s_grown = np.ones(m, bool), np.zeros(m, bool)
        s_pos = t.pos[s_node].copy()
        act, new_dir, new_pos = np.empty(m, np.int64), np.empty((m, 3)), np.empty((m, 3))
        nl, lnode = 0, np.empty(steps, np.int64)
        for k in range(int(s_n.max()) if m else 0):
            c = _k.propose(k, s_ok, s_n, s_apical, s_level, s_dir, s_pos, shadow, lo, voxel, up_weight, length, P,
                           state, act, new_dir, new_pos)
            if c == 0:
                break
            ok = (new_pos[:c, 1] >= 0.0) & inside(new_pos[:c])
            t.n, nl = _k.commit(c, ok, act, new_dir, new_pos, year, t.n, t.pos, t.parent, t.year, t.alive, t.side,
                                nl, lnode, s_ok, s_grown, s_node, s_dir, s_side, s_pos, P, state)
        t.nbud = _k.end_shoots(t.nbud, t.bnode, t.bq, t.bdir, t.bside, t.bapical, t.bage, s_ok, s_grown, s_node,
                               s_dir, s_side, nl, lnode, nlb)
    # the last cycle's shoots are pruned below the pruning height too
    _k.prune_low(tree.n, n_fixed, tree.pos, tree.parent, tree.alive, p.low_branch_pruning_factor)
    return tree


def _structure(p: GrowthParameters, tree: _Tree, inside, n_fixed: int = 0) -> TreeSkeleton:
    """Compact the living nodes, give them pipe-model radii and bend them under gravity.

    The first ``n_fixed`` nodes (a scaffold) keep their positions."""
    from treeform.growth import _kernels as _k
    from treeform.growth.radii import branch_orders, pipe_model_radii

    n = tree.n
    keep = np.flatnonzero(tree.alive[:n])
    remap = np.full(n, -1, np.int64)
    remap[keep] = np.arange(len(keep))
    parent = np.where(tree.parent[keep] >= 0, remap[tree.parent[keep].clip(0)], -1)
    pos = tree.pos[keep]
    radius = pipe_model_radii(parent, tip_radius=TIP_RADIUS, exponent=PIPE_EXPONENT)
    if len(keep) > 1 and p.gravity_bending_strength > 0:
        seg, bent = _k.bend_segments(pos, parent, radius, p.gravity_bending_strength, p.gravity_bending_angle_factor,
                                     TIP_RADIUS, n_fixed)
        new_pos = _k.place(parent, pos[0], bent)

        def outside(q):
            out = q[:, 1] < 0.0
            return out | ~inside(q) if inside is not None else out

        # undo the bending along the path to every node it would push into the ground or out of the envelope
        for _ in range(8):
            out = outside(new_pos)
            if not out.any():
                break
            up_path = _k.ancestors_of(parent, out)
            bent[up_path] = seg[up_path]
            new_pos = _k.place(parent, pos[0], bent)
        else:
            new_pos = pos
        pos = new_pos
    return TreeSkeleton(pos, parent, radius, branch_orders(parent, radius), tree.year[keep].astype(np.float64))
