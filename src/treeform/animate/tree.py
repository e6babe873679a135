"""``treeform animate``: a tree output folder -> a looping wind animation as a skinned GLB."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from treeform._shared.errors import InputError
from treeform.animate.joints import tree_joints
from treeform.animate.skin import skin_weights
from treeform.animate.wind import wind_sway


def _primitives(glb: Path):
    """(positions, indices, material name) of each primitive of a treeform GLB's one mesh."""
    from treeform.io.gltf import accessor_array, read_glb

    gltf, bin_chunk = read_glb(glb)
    try:
        mats = gltf.get("materials", [])
        out = []
        for prim in gltf["meshes"][0]["primitives"]:
            pos = accessor_array(gltf, bin_chunk, prim["attributes"]["POSITION"]).astype(np.float64)
            idx = accessor_array(gltf, bin_chunk, prim["indices"]).astype(np.int64).reshape(-1, 3)
            out.append((pos, idx, mats[prim["material"]].get("name", "") if "material" in prim else ""))
    except (KeyError, IndexError, TypeError, ValueError):
        raise InputError(f"{glb}: malformed glTF mesh data") from None
    return out


def _moved(pose, joint, points, weight=None):
    """Points bound to ``joint`` ((P,) or (P, 2) with ``weight``) under ``pose`` (:meth:`Rig.pose`;
    linear blend skinning)."""
    m = pose[joint] if weight is None else np.einsum("pk,pkij->pij", weight, pose[joint])
    return np.einsum("nij,nj->ni", m[:, :3, :3], points) + m[:, :3, 3]


def sway_checks(skeleton, rig, joints, *, wood=None, step: int = 1) -> dict:
    """How the animation behaves: attachment, trunk against twigs, loop closure.

    Returns ``skeleton_stretch`` (largest relative change of a skeleton edge's length over
    the frames), ``mesh_stretch`` (the same over the edges of ``wood``'s triangles, a
    ``(positions, indices, joints, weights)`` tuple, when given), ``trunk_bend`` (largest
    bend of a trunk joint, degrees) and ``twig_bend`` (median largest bend of the thinnest
    quarter of the joints), ``trunk_motion`` (largest displacement of a trunk node, m),
    ``tip_motion`` (95th percentile over the branch tips of their largest displacement, m),
    and ``loop_gap`` (largest difference between the first and last pose's matrices).
    """
    pos, par = skeleton.positions, skeleton.parent
    rest = np.linalg.norm(pos[1:] - pos[par[1:]], axis=1)
    good = rest > 1e-9
    trunk = np.flatnonzero(skeleton.order == 0)
    tips = skeleton.tips()
    stretch, mesh_stretch, trunk_d, tip_d = 0.0, 0.0, np.zeros(len(trunk)), np.zeros(len(tips))
    if wood is not None:
        wp, wi, wj, ww = wood
        e = np.concatenate([wi[:, [0, 1]], wi[:, [1, 2]], wi[:, [2, 0]]])
        e_rest = np.linalg.norm(wp[e[:, 0]] - wp[e[:, 1]], axis=1)
        ok = e_rest > 1e-6
    for k in range(0, len(rig.times), step):
        pose = rig.pose(k)
        p = _moved(pose, joints.node_joint, pos)
        length = np.linalg.norm(p[1:] - p[par[1:]], axis=1)
        stretch = max(stretch, float(np.max(np.abs(length[good] / rest[good] - 1.0), initial=0.0)))
        trunk_d = np.maximum(trunk_d, np.linalg.norm(p[trunk] - pos[trunk], axis=1))
        tip_d = np.maximum(tip_d, np.linalg.norm(p[tips] - pos[tips], axis=1))
        if wood is not None:
            q = _moved(pose, wj, wp, ww)
            le = np.linalg.norm(q[e[ok, 0]] - q[e[ok, 1]], axis=1)
            mesh_stretch = max(mesh_stretch, float(np.max(np.abs(le / e_rest[ok] - 1.0), initial=0.0)))
    bend = np.degrees(2 * np.arccos(np.clip(np.abs(rig.rotations[..., 3]), 0, 1))).max(axis=0)  # (J,)
    r = skeleton.radius[joints.pivot_node]
    on_trunk = skeleton.order[joints.pivot_node] == 0
    thin = r <= np.quantile(r, 0.25)
    first, last = rig.pose(0), rig.pose(len(rig.times) - 1)
    return {"skeleton_stretch": stretch, "mesh_stretch": mesh_stretch if wood is not None else None,
            "trunk_bend": float(bend[on_trunk].max()), "twig_bend": float(np.median(bend[thin])),
            "trunk_motion": float(trunk_d.max(initial=0.0)),
            "tip_motion": float(np.quantile(tip_d, 0.95)) if len(tip_d) else 0.0,
            "loop_gap": float(np.abs(first - last).max())}


STAGES = ("read", "joints", "wind", "skin", "export", "checks")
"""Stages of :func:`animate_tree` (for a progress bar)."""


def animate_tree(tree, *, out=None, wind: float = 6.0, direction: float = 0.0, seconds: float = 4.0,
                 fps: int = 30, seed: int = 0, max_joints: int = 96, progress=None) -> dict:
    """Animate a treeform tree swaying in the wind; write a looping, skinned ``tree_animated.glb``.

    Parameters
    ----------
    tree : path
        An output folder of ``treeform grow`` / ``reconstruct`` (its ``skeleton.json`` and
        ``tree.glb``).
    out : path, optional
        The animated GLB (default ``TREE/tree_animated.glb``).
    wind, direction, seconds, fps, seed
        See :func:`~treeform.animate.wind.wind_sway`.
    max_joints : int
        Joints of the rig (see :func:`~treeform.animate.joints.tree_joints`).
    progress : callable, optional
        ``progress(stage, event, seconds)`` for each of :data:`STAGES`.

    Returns
    -------
    dict
        ``path`` of the GLB, ``joints``, ``frames``, ``period`` (s) and the checks of
        :func:`sway_checks`.

    Raises
    ------
    InputError
        ``tree`` is not a folder with ``skeleton.json`` and ``tree.glb``, a bad option, or
        an output path that cannot be written.
    """
    from scipy.spatial import cKDTree

    from treeform.io.gltf import write_animated_glb
    from treeform.structures.skeleton import TreeSkeleton

    from treeform.animate.wind import check_wind

    check_wind(wind, direction, seconds, fps, seed)
    folder = Path(tree)
    if not folder.is_dir():
        raise InputError(f"{folder}: not a folder (expected the output folder of treeform grow or reconstruct)")
    glb, sk = folder / "tree.glb", folder / "skeleton.json"
    for f in (glb, sk):
        if not f.is_file():
            raise InputError(f"{folder}: no {f.name} (expected the output folder of treeform grow or reconstruct)")
    out = Path(out) if out is not None else folder / "tree_animated.glb"
    if out.suffix.lower() != ".glb":
        raise InputError(f"--out: expected a .glb file, got {out}")
    if not out.parent.is_dir():
        raise InputError(f"--out: the folder {out.parent} does not exist")
    from treeform._shared.timing import StageTimer

    timer = StageTimer(progress)
    with timer.stage("read"):
        skeleton = TreeSkeleton.load(sk)
        prims = _primitives(glb)
    with timer.stage("joints"):
        joints = tree_joints(skeleton, max_joints=max_joints)
        leaf_area = np.zeros(skeleton.n_nodes)
        for pos, idx, mat in prims:
            if mat == "leaves" and len(idx):
                tri = pos[idx]
                area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
                _, near = cKDTree(skeleton.positions).query(tri.mean(axis=1))
                leaf_area += np.bincount(near, weights=area, minlength=skeleton.n_nodes)
    with timer.stage("wind"):
        rig = wind_sway(skeleton, joints, wind=wind, direction=direction, seconds=seconds, fps=fps, seed=seed,
                        leaf_area=leaf_area)
    with timer.stage("skin"):
        skins = [skin_weights(pos, idx, skeleton, joints) for pos, idx, _ in prims]
    with timer.stage("export"):
        write_animated_glb(glb, out, rig, skins)
    with timer.stage("checks"):
        wood = next(((p[0], p[1], *sk) for p, sk in zip(prims, skins) if p[2] != "leaves" and len(p[1])), None)
        checks = sway_checks(skeleton, rig, joints, wood=wood, step=max(1, (len(rig.times) - 1) // 24))
    return {"path": str(out), "joints": joints.n_joints, "frames": len(rig.times) - 1, "period": rig.period,
            **checks, "seconds": dict(timer.timings)}
