"""Wind sway: each jointed branch segment a damped rod spring driven by a turbulent, looping wind.

Paper 003 (Fig. 11) animates its trees with rod dynamics. Here each joint of
:func:`~treeform.animate.joints.tree_joints` is a rod clamped at its pivot: bending stiffness
``k = E * pi * r**4 / (4 * L)`` from the radius ``r`` at the pivot and the segment's length
``L`` (Euler–Bernoulli), moment of inertia ``I = sum m_i d_i**2`` over the wood it carries
(pipe-model volume times wood density, ``d_i`` the distance to the pivot), aerodynamic drag
``1/2 rho Cd A v(t)**2`` on the branch and leaf area ``A`` it carries (scaled per tree so that
the trunk's top moves :data:`SWAY_REF` of the height in the mean of a 10 m/s wind), structural damping
plus the aerodynamic damping of that drag.
The wind is a mean speed plus gusts, a sum of harmonics of the loop's period with a
Kolmogorov-like spectrum that travel downwind at the mean speed, so the force on every joint
is exactly periodic. Its steady response is solved per harmonic (the linear oscillator's
transfer function): no time stepping, unconditionally stable, and the last frame equals the
first, so the animation loops without a jump. Each joint turns about the horizontal axis
across the wind (downwind sway) and, with a smaller, independently phased forcing, about the
wind's own axis (the side-to-side flutter of a branch in a gust).
"""

from __future__ import annotations

import numpy as np

from treeform._shared.checks import check_finite, check_int, check_positive
from treeform._shared.errors import InputError
from treeform._shared.rng import as_rng
from treeform.animate.joints import TreeJoints
from treeform.structures.rig import Rig
from treeform.structures.skeleton import TreeSkeleton

WOOD_DENSITY = 800.0
"""kg/m³, green hardwood."""
YOUNG_MODULUS = 9.0e9
"""Pa, green wood along the grain."""
AIR_DENSITY = 1.2
DRAG = 0.6
"""Drag coefficient of branches and foliage (leaves streamline in strong wind: lower)."""
DAMPING = 0.12
"""Structural damping ratio of every joint (aerodynamic damping comes on top, from its drag)."""
GUSTS = 0.35
"""Standard deviation of the gusts relative to the mean wind speed (turbulence intensity)."""
STATIC_MAX = 0.02
"""Largest mean bend of one joint in a 10 m/s wind, radians (about 1.1 degrees; branches nest ten
joints deep, and their bends add up)."""
COHERENT = 4
"""Gust harmonics up to this one (periods of a quarter loop and longer) are coherent over the tree."""
MAX_BEND = 0.12
"""Largest bend of one joint, radians: the linear response is compressed smoothly towards it."""
SWAY_REF = 0.01
"""Static displacement of the trunk's top in the mean of a 10 m/s wind, as a share of the tree's
height (open-grown trees: about 1 %; gusts then move it about three times as far). A
reconstructed tree's radii and leaf cards do not carry its real mass and leaf area (cards are
clusters, larger than leaves), so the drag is scaled per tree to this; stiffness, inertia and
every natural frequency stay physical."""


def _quat(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """(..., 4) quaternions (x, y, z, w) turning ``angle`` (...) about a unit ``axis`` (3,)."""
    h = 0.5 * np.asarray(angle)[..., None]
    return np.concatenate([np.sin(h) * axis, np.cos(h)], axis=-1)


def _qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ax, ay, az, aw = np.moveaxis(a, -1, 0)
    bx, by, bz, bw = np.moveaxis(b, -1, 0)
    return np.stack([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz], axis=-1)


def joint_mechanics(skeleton: TreeSkeleton, joints: TreeJoints, leaf_area=None) -> dict:
    """Per joint: stiffness (N m/rad), moment of inertia (kg m²), wind lever ``sum A_i d_i`` (m³) and
    ``sum A_i d_i**2`` (m⁴, for the aerodynamic damping).

    ``leaf_area`` (N,) is the leaf area (m²) hanging at each node (default none).
    """
    n = skeleton.n_nodes
    area = np.zeros(n) if leaf_area is None else np.asarray(leaf_area, np.float64).reshape(-1)
    if area.shape != (n,):
        raise InputError(f"leaf_area: expected {n} values (one per node), got shape {area.shape}")
    par = skeleton.parent
    seg = skeleton.segment_lengths()
    r = skeleton.radius.copy()
    r[1:] = 0.5 * (r[1:] + r[par[1:]])
    mass = WOOD_DENSITY * np.pi * r * r * seg
    drag_area = 2.0 * r * seg + area
    J = joints.n_joints
    # joints carried by each joint: itself and its descendants (parents precede children)
    carried = np.eye(J, dtype=bool)
    for j in range(J - 1, 0, -1):
        carried[joints.parent[j]] |= carried[j]
    inertia, lever, lever2 = np.zeros(J), np.zeros(J), np.zeros(J)
    for j in range(J):
        sub = carried[j][joints.node_joint]
        d = np.linalg.norm(skeleton.positions[sub] - joints.pivots[j], axis=1)
        inertia[j] = float(np.sum(mass[sub] * d * d))
        lever[j] = float(np.sum(drag_area[sub] * d))
        lever2[j] = float(np.sum(drag_area[sub] * d * d))
    # the segment a joint owns: from its pivot to its farthest own node
    length = np.array([max(np.linalg.norm(skeleton.positions[joints.node_joint == j] - joints.pivots[j], axis=1).max(),
                           1e-3) for j in range(J)])
    radius = np.maximum(skeleton.radius[joints.pivot_node], 1e-4)
    stiffness = YOUNG_MODULUS * np.pi * radius ** 4 / (4.0 * length)
    return {"stiffness": stiffness, "inertia": np.maximum(inertia, 1e-9), "lever": lever, "lever2": lever2,
            "length": length}


def check_wind(wind, direction, seconds, fps, seed):
    """Checked ``(wind, direction, frames, fps, rng)`` of :func:`wind_sway`'s options (one clear
    :class:`~treeform._shared.errors.InputError` for a bad one)."""
    wind = check_positive(wind, "wind")
    if wind > 60:
        raise InputError(f"wind: expected a speed up to 60 m/s, got {wind}")
    direction = check_finite(direction, "direction")
    seconds = check_positive(seconds, "seconds")
    fps = check_int(fps, "fps", 1, 240)
    frames = max(2, int(round(seconds * fps)))
    if frames > 20000:
        raise InputError(f"seconds x fps: expected at most 20000 frames, got {frames}")
    return wind, direction, frames, fps, as_rng(seed)


def wind_sway(skeleton: TreeSkeleton, joints: TreeJoints, *, wind: float = 6.0, direction: float = 0.0,
              seconds: float = 4.0, fps: int = 30, seed: int = 0, leaf_area=None) -> Rig:
    """A looping sway of ``skeleton``'s joints in a turbulent wind.

    Parameters
    ----------
    skeleton : TreeSkeleton
    joints : TreeJoints
    wind : float
        Mean wind speed, m/s (> 0; 6 is a moderate breeze, 15 a strong wind).
    direction : float
        Where the wind blows towards, degrees about the vertical: 0 = +X, 90 = +Z.
    seconds : float
        Length of the loop (rounded to whole frames).
    fps : int
        Keyframes per second.
    seed : int
        Phases of the gusts.
    leaf_area : ndarray, shape (N,), optional
        Leaf area (m²) at each node: the foliage catches most of the wind.

    Returns
    -------
    Rig
        Keyframes ``0 .. round(seconds * fps)``; the last pose equals the first.
    """
    wind, direction, frames, fps, rng = check_wind(wind, direction, seconds, fps, seed)
    period = frames / fps
    mech = joint_mechanics(skeleton, joints, leaf_area)
    a = np.deg2rad(direction)
    d = np.array([np.cos(a), 0.0, np.sin(a)])
    across = np.cross([0.0, 1.0, 0.0], d)  # turning about it tips a branch downwind
    # gusts: harmonics m = 1..K of the period, amplitude ~ m^(-5/6), random phases, travelling downwind
    K = 12
    m = np.arange(1, K + 1)
    amp = m ** (-5.0 / 6.0)
    amp *= GUSTS / np.sqrt(0.5 * np.sum(amp ** 2))
    # large gusts are coherent over the tree (one phase each, travelling downwind); eddies smaller
    # than a branch (harmonics above COHERENT) reach every joint with its own phase
    J = joints.n_joints
    phase = np.broadcast_to(rng.uniform(0, 2 * np.pi, K), (J, K)).copy()
    phase_x = np.broadcast_to(rng.uniform(0, 2 * np.pi, K), (J, K)).copy()
    small = m > COHERENT
    phase[:, small] = rng.uniform(0, 2 * np.pi, (J, int(small.sum())))
    phase_x[:, small] = rng.uniform(0, 2 * np.pi, (J, int(small.sum())))
    S = 4 * frames  # samples per period of the force (keyframes at every 4th)
    t = np.arange(S) * period / S
    delay = (joints.pivots @ d) / wind  # s: when a gust front reaches each joint
    arg = 2 * np.pi * m[None, None, :] * (t[None, :, None] - delay[:, None, None]) / period
    gust = np.sum(amp * np.cos(arg + phase[:, None, :]), axis=2)        # (J, S)
    flutter = np.sum(amp * np.cos(arg + phase_x[:, None, :]), axis=2)   # (J, S), independent phases
    q = 0.5 * AIR_DENSITY * DRAG * wind ** 2
    # calibration: at 10 m/s the trunk's top moves SWAY_REF of the height (see its note); the
    # trunk's joints are those whose pivots are trunk nodes, each bend moves the top by its lever
    trunk = np.flatnonzero(skeleton.order[joints.pivot_node] == 0)
    top = skeleton.positions[np.flatnonzero(skeleton.order == 0)[-1]]
    height = float(np.ptp(skeleton.positions[:, 1])) or 1.0
    static10 = 0.5 * AIR_DENSITY * DRAG * 100.0 * mech["lever"][trunk] / mech["stiffness"][trunk]
    reach = float(np.sum(static10 * np.linalg.norm(top - joints.pivots[trunk], axis=1)))
    scale = SWAY_REF * height / reach if reach > 0 else 1.0
    q *= scale
    force_down = q * (1.0 + gust) ** 2 * mech["lever"][:, None]
    force_side = 0.3 * q * flutter * mech["lever"][:, None]
    # no joint is softer than its load allows: a branch whose mean bend at 10 m/s would pass
    # STATIC_MAX (thin twigs under a large card area) is stiffened to it, as real branches grow
    # thick enough to carry their leaves
    q10 = q * (10.0 / wind) ** 2
    stiffness = np.maximum(mech["stiffness"], q10 * mech["lever"] / STATIC_MAX)
    omega = np.sqrt(stiffness / mech["inertia"])
    # aerodynamic damping: the drag on a moving branch resists its motion (linearised about the
    # mean wind, same drag scale); leafy, light branches are damped most
    c_aero = scale * AIR_DENSITY * DRAG * wind * mech["lever2"]
    zeta = DAMPING + c_aero / (2.0 * np.sqrt(stiffness * mech["inertia"]))
    Omega = 2 * np.pi * np.fft.rfftfreq(S, d=period / S)

    def respond(moment):
        h = 1.0 / (mech["inertia"][:, None] * (omega[:, None] ** 2 - Omega[None, :] ** 2
                                               + 2j * zeta[:, None] * omega[:, None] * Omega[None, :]))
        theta = np.fft.irfft(np.fft.rfft(moment, axis=1) * h, n=S, axis=1)
        return MAX_BEND * np.tanh(theta / MAX_BEND)

    bend = respond(force_down)[:, ::4]   # (J, frames)
    side = respond(force_side)[:, ::4]
    bend = np.concatenate([bend, bend[:, :1]], axis=1).T  # (frames + 1, J): the loop closes exactly
    side = np.concatenate([side, side[:, :1]], axis=1).T
    rot = _qmul(_quat(across, bend), _quat(d, side))
    rot /= np.linalg.norm(rot, axis=-1, keepdims=True)
    times = np.arange(frames + 1) / fps
    return Rig(joints.pivots, joints.parent, times, rot)
