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
    "crown_extent_x_m": "m", "crown_extent_y_m": "m", "crown_extent_z_m": "m", "crown_width_m": "m",
    "max_radial_extent_m": "m",
}


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
    from treeform.io.gltf import read_glb_geometry
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
    verts, leaves = read_glb_geometry(tree)
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

    table = Table(title=f"tree-form metrics (Li et al. 2021): {res['source']}")
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
    tree: Path = typer.Argument(..., metavar="TREE", help="A treeform skeleton JSON, or a treeform GLB (skeleton.json beside it)."),
    as_json: bool = typer.Option(False, "--json", help="Print JSON instead of a table."),
):
    """Tree-form metrics (Li et al. 2021): branching angle, height, trunk diameter, LAI, biomass, MRT."""
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
