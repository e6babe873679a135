"""Text tables of an evaluation's results (the CLI summary and BENCHMARKS.md)."""

from __future__ import annotations

__all__ = ["SUMMARY_SCORES", "summary_lines", "markdown_table"]

SUMMARY_SCORES = (
    ("front_iou", "front IoU (true mask)"),
    ("front_iou_own", "front IoU (own mask)"),
    ("segmentation_iou", "segmentation IoU"),
    ("iou_side", "side IoU 90°"),
    ("iou_back", "back IoU 180°"),
    ("iou_top", "top IoU"),
    ("gap_err_side", "side gaps err."),
    ("rbv_err_l1", "RBV L1 %"),
    ("rbv_err_l3", "RBV L3 %"),
    ("rbv_err_l5", "RBV L5 %"),
    ("rel_err_height", "height rel. err."),
    ("rel_err_trunk_diameter", "trunk diam. rel. err."),
    ("abs_err_branching_angle_deg", "branch angle err. °"),
    ("rel_err_lai", "LAI rel. err."),
    ("rel_err_biomass", "biomass rel. err."),
    ("mrt_err_pct", "MRT err. % of height"),
    ("species_correct", "species accuracy"),
    ("registration_rate", "photos registered"),
    ("seconds", "seconds / case"),
)
"""(score key, column title) of the summary, in order."""


def _cell(stats: dict | None) -> str:
    if not stats:
        return "–"
    lo, hi = stats["ci95"]
    return f"{stats['median']:.3g} [{lo:.3g}, {hi:.3g}]"


def markdown_table(res: dict) -> str:
    """Methods x scores: median [95 % interval of the median] over the cases."""
    agg = res["aggregate"]
    keys = [(k, t) for k, t in SUMMARY_SCORES if any(k in a["scores"] for a in agg.values())]
    head = "| score | " + " | ".join(agg) + " |\n|---|" + "---|" * len(agg) + "\n"
    rows = [f"| {t} | " + " | ".join(_cell(a["scores"].get(k)) for a in agg.values()) + " |" for k, t in keys]
    rows.append("| cases (failed) | " + " | ".join(f"{a['cases']} ({a['failed']})" for a in agg.values()) + " |")
    return head + "\n".join(rows) + "\n"


def summary_lines(res: dict) -> list:
    """A few lines for the terminal: per method, the headline medians."""
    lines = [f"{res['evaluated']} case(s) evaluated, {res['resumed']} resumed, in {res['seconds']:.1f} s"]
    for m, a in res["aggregate"].items():
        s = a["scores"]
        parts = [f"{t} {s[k]['median']:.3g}" for k, t in SUMMARY_SCORES[:6] if k in s]
        lines.append(f"{m}: {a['cases'] - a['failed']}/{a['cases']} ok; " + ", ".join(parts))
    return lines
