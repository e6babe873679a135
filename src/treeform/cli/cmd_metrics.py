"""``treeform metrics TREE``: tree-form metrics (seed 003 §6) of a skeleton JSON or a GLB."""

from __future__ import annotations

import math
from pathlib import Path

import typer

from treeform._shared.errors import InputError, TreeformError
from treeform.cli.app import app

_UNITS = {
    "branching_angle_deg": "deg", "tree_height_m": "m", "trunk_diameter_m": "m", "leaf_area_index": "",
    "biomass_m3": "m³", "mrt_m": "m", "projected_leaf_area_m2": "m²", "crown_projection_area_m2": "m²",
    "crown_extent_x_m": "m", "crown_extent_y_m": "m", "crown_extent_z_m": "m", "max_radial_extent_m": "m",
}


def _node_matrix(node: dict):
    """A glTF node's local 4x4 transform (``matrix``, or translation * rotation * scale)."""
    import numpy as np

    if "matrix" in node:
        return np.array(node["matrix"], np.float64).reshape(4, 4).T  # column-major in glTF
    x, y, z, w = node.get("rotation", (0.0, 0.0, 0.0, 1.0))
    rot = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                    [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                    [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    m = np.eye(4)
    m[:3, :3] = rot * np.asarray(node.get("scale", (1.0, 1.0, 1.0)), np.float64)
    m[:3, 3] = node.get("translation", (0.0, 0.0, 0.0))
    return m


def _glb_arrays(path: Path):
    """(all vertex positions (V, 3), leaf triangles (T, 3, 3) or None) of a GLB, in world space.

    Node transforms of the default scene are applied; leaf triangles are those of primitives
    whose material is named ``leaves`` (treeform's leaf material).
    """
    import numpy as np

    from treeform.io.gltf import accessor_array, read_glb

    gltf, bin_chunk = read_glb(path)
    mats, nodes = gltf.get("materials", []), gltf.get("nodes", [])
    verts, leaves = [], []
    try:
        scenes = gltf.get("scenes", [])
        if scenes:
            roots = list(scenes[gltf.get("scene", 0)].get("nodes", []))
        else:
            kids = {c for n in nodes for c in n.get("children", [])}
            roots = [i for i in range(len(nodes)) if i not in kids]
        stack = [(i, np.eye(4), 0) for i in roots]
        while stack:
            i, parent_m, depth = stack.pop()
            if depth > 64:
                raise InputError(f"{path}: glTF node hierarchy too deep (a cycle?)")
            node = nodes[i]
            m = parent_m @ _node_matrix(node)
            stack.extend((c, m, depth + 1) for c in node.get("children", []))
            if "mesh" not in node:
                continue
            for prim in gltf["meshes"][node["mesh"]]["primitives"]:
                pos = accessor_array(gltf, bin_chunk, prim["attributes"]["POSITION"]).astype(np.float64)
                pos = pos @ m[:3, :3].T + m[:3, 3]
                verts.append(pos)
                mat = mats[prim["material"]].get("name", "") if "material" in prim else ""
                if mat == "leaves" and prim.get("mode", 4) == 4:
                    idx = (accessor_array(gltf, bin_chunk, prim["indices"]).astype(np.int64)
                           if "indices" in prim else np.arange(len(pos)))
                    leaves.append(pos[idx.reshape(-1, 3)])
    except (KeyError, IndexError, TypeError, ValueError):
        raise InputError(f"{path}: malformed glTF scene or mesh data") from None
    if not verts or not sum(len(v) for v in verts):
        raise InputError(f"{path}: the GLB holds no mesh vertices")
    return np.concatenate(verts), (np.concatenate(leaves) if leaves else None)


def _load_skeleton(path: Path):
    from treeform.structures import TreeSkeleton

    try:
        return TreeSkeleton.load(path)
    except InputError as exc:
        if str(path) in str(exc):
            raise
        raise InputError(f"{path}: {exc}") from None
    except (ValueError, TypeError) as exc:
        raise InputError(f"{path}: not a valid treeform skeleton ({exc})") from None


def compute_metrics(tree: Path) -> dict:
    """Metrics of a treeform skeleton JSON, or of a treeform GLB (with skeleton.json beside it).

    Returns a dict: ``source``, ``skeleton`` (path used or None), ``notes`` (list of str) and
    ``metrics`` (see :func:`treeform.metrics.tree_metrics` / :func:`~treeform.metrics.mesh_metrics`).
    """
    from treeform.metrics.treeform_metrics import mesh_metrics, tree_metrics

    tree = Path(tree)
    if not tree.exists():
        raise InputError(f"{tree}: no such file")
    if tree.is_dir():
        raise InputError(f"{tree}: is a directory; expected a skeleton .json or a .glb file")
    suffix = tree.suffix.lower()
    notes: list[str] = []
    if suffix == ".json":
        skel = _load_skeleton(tree)
        notes.append("no foliage in a skeleton JSON: leaf area index not computed")
        return {"source": str(tree), "skeleton": str(tree), "notes": notes, "metrics": tree_metrics(skel)}
    if suffix != ".glb":
        raise InputError(f"{tree}: unknown format {suffix or '(none)'}; expected a treeform skeleton .json or a .glb")
    verts, leaves = _glb_arrays(tree)
    if leaves is None:
        notes.append("the GLB has no 'leaves' primitive: leaf area index not computed")
    sk_path = tree.with_name("skeleton.json")
    if sk_path.is_file():
        skel = _load_skeleton(sk_path)
        notes.append(f"skeleton from {sk_path}; leaf area index from the GLB's leaf triangles")
        return {"source": str(tree), "skeleton": str(sk_path), "notes": notes,
                "metrics": tree_metrics(skel, leaf_triangles=leaves)}
    notes.insert(0, f"no skeleton.json next to {tree.name}: only height, extents and LAI from the mesh; "
                    "branching angle, trunk diameter, biomass and MRT need the skeleton")
    return {"source": str(tree), "skeleton": None, "notes": notes, "metrics": mesh_metrics(verts, leaf_triangles=leaves)}


def _jsonable(v):
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, list):
        return [_jsonable(x) for x in v]
    if isinstance(v, dict):
        return {k: _jsonable(x) for k, x in v.items()}
    return v


def _fmt(v) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "n/a"
    if isinstance(v, list):
        return "  ".join(_fmt(x) for x in v)
    return f"{v:.4g}" if isinstance(v, float) else str(v)


def _print(res: dict) -> None:
    from rich.console import Console
    from rich.table import Table

    table = Table(title=f"tree-form metrics (seed 003 §6): {res['source']}")
    table.add_column("metric")
    table.add_column("value", justify="right")
    table.add_column("unit")
    for k, v in res["metrics"].items():
        table.add_row(k, _fmt(v), _UNITS.get(k, ""))
    con = Console()
    con.print(table)
    for n in res["notes"]:
        con.print(f"note: {n}", highlight=False)


@app.command()
def metrics(
    tree: Path = typer.Argument(..., help="A treeform skeleton JSON, or a treeform GLB (skeleton.json beside it)."),
    as_json: bool = typer.Option(False, "--json", help="Print JSON instead of a table."),
):
    """Tree-form metrics: branching angle, height, trunk diameter, LAI, biomass, MRT (seed 003 §6)."""
    import json

    try:
        res = compute_metrics(tree)
    except TreeformError as exc:
        typer.echo(f"error: {exc}", err=True)
        raise typer.Exit(exc.exit_code)
    if as_json:
        typer.echo(json.dumps(_jsonable(res), indent=1, allow_nan=False))
    else:
        _print(res)
