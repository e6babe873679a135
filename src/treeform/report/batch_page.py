"""``summary.html`` of a batch: a contact sheet of every photo's preview with its metrics, and the failures."""

from __future__ import annotations

import html
from pathlib import Path

__all__ = ["write_batch_summary"]

_LABELS = {"reprojection_error": "error", "iou": "IoU", "front_ssim": "SSIM", "tree_height_m": "height (m)",
           "leaves": "leaves", "triangles": "triangles", "total_seconds": "seconds"}


def _fmt(v) -> str:
    if isinstance(v, float):
        return f"{v:.3g}"
    return html.escape(str(v))


def write_batch_summary(out_dir, entries: dict, *, title: str = "treeform batch") -> Path:
    """Write ``out_dir/summary.html`` for a batch's manifest entries (NAME -> entry); returns its path.

    A done entry shows ``NAME/preview.png`` (linked to the folder) with its metrics; a failed
    one its photo's name and the one-line reason. Relative links: the folder can be moved.

    Examples
    --------
    >>> import tempfile
    >>> d = Path(tempfile.mkdtemp())
    >>> p = write_batch_summary(d, {"a": {"photo": "a.jpg", "folder": "a", "status": "failed", "reason": "no tree"}})
    >>> "no tree" in p.read_text()
    True
    """
    out_dir = Path(out_dir)
    done = {n: e for n, e in entries.items() if e.get("status") == "done"}
    failed = {n: e for n, e in entries.items() if e.get("status") == "failed"}
    cards = []
    for n, e in done.items():
        folder = html.escape(e.get("folder", n))
        rows = "".join(f"<tr><td>{_LABELS.get(k, html.escape(k))}</td><td data-key='{html.escape(k)}'>{_fmt(v)}</td>"
                       f"</tr>" for k, v in e.get("metrics", {}).items())
        name = html.escape(e.get("photo", n))
        link = f"<a href='{folder}/'><img src='{folder}/preview.png' alt='{folder}'></a>"
        cards.append(f"<div class='card'>{link}<div class='name'>{name}</div><table>{rows}</table></div>")
    fails = "".join(f"<tr><td>{html.escape(e.get('photo', n))}</td>"
                    f"<td class='reason'>{html.escape(e.get('reason', ''))}</td></tr>" for n, e in failed.items())
    page = f"""<!doctype html>
<html><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>
body {{ font-family: sans-serif; margin: 1.5em; color: #222; }}
.sheet {{ display: flex; flex-wrap: wrap; gap: 14px; }}
.card {{ width: 420px; border: 1px solid #ddd; padding: 6px; }}
.card img {{ width: 100%; }}
.name {{ font-weight: bold; margin: 4px 0; }}
td {{ padding: 1px 8px 1px 0; font-size: 13px; }}
.reason {{ color: #a00; }}
</style></head><body>
<h1>{html.escape(title)}</h1>
<p>{len(done)} reconstructed, {len(failed)} failed, of {len(entries)} photos.</p>
<div class="sheet">{''.join(cards)}</div>
{f'<h2>Failures</h2><table>{fails}</table>' if fails else ''}
</body></html>
"""
    path = out_dir / "summary.html"
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(page)
    tmp.replace(path)
    return path
