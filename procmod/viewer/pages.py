"""Whole pages around the viewer: the contact page of 3D samples."""

from __future__ import annotations

import html

from . import Layer, View, view_element, viewer_scripts, VIEWER_CSS

TILE = 260  # CSS pixels per view on a contact page
MAX_PAGE_BYTES = 24_000_000  # GLB bytes inlined into one page; later samples are listed, not shown


def contact_page_html(glbs, labels, links=None, title: str = "procmod samples", note: str = "") -> str:
    """A page of orbitable views, one per GLB file (``glbs``, bytes), captioned by ``labels``.

    ``links`` (optional, one per sample) are relative file names the caption links to.
    Views are added while their GLB files total at most :data:`MAX_PAGE_BYTES`; the page
    says how many it left out.
    """
    glbs, labels = list(glbs), [str(label) for label in labels]
    views, total = [], 0
    for glb, label in zip(glbs, labels):
        if views and total + len(glb) > MAX_PAGE_BYTES:
            break
        total += len(glb)
        views.append(View((Layer(label, glb),)))
    left_out = len(glbs) - len(views)
    cells = []
    for i, label in enumerate(labels[:len(views)]):
        caption = html.escape(label)
        if links is not None:
            caption = f'<a href="{html.escape(links[i])}">{caption}</a>'
        cells.append(f'<div class="cell">{view_element(i, TILE, TILE)}<div class="caption">{caption}</div></div>')
    more = (f"<p>{left_out} more samples are in the folder but not on this page (it holds "
            f"{MAX_PAGE_BYTES // 1_000_000} MB of models at most).</p>" if left_out else "")
    note_html = f"<p>{html.escape(note)}</p>" if note else ""
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>{html.escape(title)}</title>
<style>
body {{ font-family: sans-serif; margin: 2em; color: #222; }}
.grid {{ display: flex; flex-wrap: wrap; gap: 12px; }}
.cell .caption {{ font-size: 13px; margin-top: 2px; }}
{VIEWER_CSS}
.procmod-legend, .procmod-view-buttons {{ display: none; }}
</style></head><body>
<h1>{html.escape(title)}</h1>
{note_html}<p>Drag a view to turn it, right-drag to pan, double-click to reset; click a view, then scroll to zoom it
(elsewhere the wheel scrolls the page).</p>
<div class="grid">{''.join(cells)}</div>
{more}{viewer_scripts(views)}</body></html>
"""


__all__ = ["MAX_PAGE_BYTES", "TILE", "contact_page_html"]
