"""An orbitable 3D viewer inside procmod's HTML pages (run reports, contact pages of samples).

The viewer is three.js (npm ``three``, MIT; its licence is ``three-LICENSE.txt`` here and at
the top of the bundle) with orbit controls and the glTF loader, bundled with procmod's
``js/viewer.js`` into one classic script, ``procmod-viewer.js`` (package data; remade by
``build.py``). A page embeds the script and its models (GLB, base64) inline, so it shows the
models from disk (``file://``, where a browser neither fetches files nor loads ES modules)
and with no network, and it keeps working when it is moved or mailed on its own.

A :class:`View` is one orbitable viewport of :class:`Layer` s (a best result, a target's
volumes drawn translucent, ...); :func:`viewer_html` writes the markup for views laid out
in a grid, and :func:`view_element` / :func:`viewer_scripts` let a page place them itself.
This module imports nothing heavy; :mod:`procmod.viewer.layers` builds layers from parts
and targets.
"""

from __future__ import annotations

import base64
import html
import json
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path

BUNDLE = Path(__file__).with_name("procmod-viewer.js")
LICENCE = Path(__file__).with_name("three-LICENSE.txt")


@dataclass(frozen=True)
class Layer:
    """One model in a view.

    Attributes
    ----------
    name : str
        Its legend entry (a checkbox toggles it).
    glb : bytes
        The model as a binary glTF file (procmod's GLB exports: colours per vertex).
    opacity : float
        Below 1 the layer is translucent (drawn after opaque layers, both faces).
    colour : str, optional
        A CSS colour for the whole layer instead of the file's colours.
    visible : bool
        Shown when the page opens.
    frame : bool
        Counted when the view frames its content.
    """

    name: str
    glb: bytes
    opacity: float = 1.0
    colour: str | None = None
    visible: bool = True
    frame: bool = True

    def to_json(self) -> dict:
        return {"name": self.name, "glb": base64.b64encode(self.glb).decode("ascii"), "opacity": self.opacity,
                "colour": self.colour, "visible": self.visible, "frame": self.frame}


@dataclass(frozen=True)
class View:
    """One orbitable viewport.

    Attributes
    ----------
    layers : tuple of Layer
    label : str
        A caption drawn in the view's corner.
    bounds : tuple, optional
        ``(lo xyz, hi xyz)`` of a box drawn as grey lines (a volume target's grid).
    cameras : tuple of dict
        Target cameras (``eye``, ``look_at``, ``up``, ``projection``, ``fov`` as in
        ``procmod-silhouette/1``, and ``aspect``, their pictures' width over height); each
        gets a button that views the scene through it.
    """

    layers: tuple
    label: str = ""
    bounds: tuple | None = None
    cameras: tuple = field(default_factory=tuple)

    def to_json(self) -> dict:
        out = {"layers": [layer.to_json() for layer in self.layers], "label": self.label}
        if self.bounds is not None:
            out["bounds"] = [[float(v) for v in self.bounds[0]], [float(v) for v in self.bounds[1]]]
        if self.cameras:
            out["cameras"] = [dict(c) for c in self.cameras]
        return out


VIEWER_CSS = """
.procmod-canvas { position: fixed; left: 0; top: 0; width: 100%; height: 100%; z-index: -1; display: block; }
.procmod-views { display: grid; gap: 10px; margin: 1em 0; }
.procmod-view { position: relative; border: 1px solid #ccc; touch-action: none; cursor: grab; overflow: hidden;
  user-select: none; -webkit-user-select: none; }
.procmod-legend { position: absolute; left: 6px; top: 6px; font: 12px sans-serif; background: rgba(255,255,255,0.8);
  padding: 3px 6px; border-radius: 3px; }
.procmod-legend label { display: block; white-space: nowrap; cursor: pointer; }
.procmod-swatch { display: inline-block; width: 10px; height: 10px; margin: 0 3px 0 2px; border: 1px solid #777;
  vertical-align: middle; }
.procmod-view-label { position: absolute; right: 6px; bottom: 4px; font: 12px sans-serif; color: #444; }
.procmod-view-buttons { position: absolute; right: 6px; top: 6px; }
.procmod-view-buttons button { font: 11px sans-serif; margin-left: 4px; }
.procmod-view-error { position: absolute; left: 6px; bottom: 0; font: 12px sans-serif; color: #a33; }
"""


@lru_cache(maxsize=1)
def bundle_text() -> str:
    """The bundled viewer script (three.js licence at its top)."""
    return BUNDLE.read_text(encoding="utf-8")


def _script_safe(text: str) -> str:
    """JSON text that cannot end the <script> element holding it, and stays JSON: every
    ``<`` as ``\\u003c`` (``<\\!--``, the escape it had for ``<!--``, is no JSON escape, and
    ``JSON.parse`` refused the page's data)."""
    return text.replace("<", "\\u003c")


def view_element(index: int, width: int, height: int) -> str:
    """The element view ``index`` of :func:`viewer_scripts` is drawn into."""
    return (f'<div class="procmod-view" data-procmod-view="{index}" '
            f'style="width:{int(width)}px;height:{int(height)}px"></div>')


def viewer_scripts(views) -> str:
    """The data block for ``views`` and the viewer script (place after the view elements)."""
    data = json.dumps({"views": [v.to_json() for v in views]}, sort_keys=True, separators=(",", ":"))
    return (f'<script type="application/json" id="procmod-viewer-data">{_script_safe(data)}</script>\n'
            f"<script>\n{bundle_text()}\n</script>\n")


def viewer_html(views, width: int = 640, height: int = 480, columns: int | None = None,
                captions=None) -> str:
    """Markup (style, view elements in a grid, data, script) showing ``views``.

    ``captions`` (one string per view, optional) are written under each view as HTML text.
    """
    views = list(views)
    columns = columns or len(views) or 1
    cells = []
    for i in range(len(views)):
        caption = (f'<div class="procmod-view-caption">{html.escape(captions[i])}</div>'
                   if captions is not None else "")
        cells.append(f"<div>{view_element(i, width, height)}{caption}</div>")
    return (f"<style>{VIEWER_CSS}</style>\n"
            f'<div class="procmod-views" style="grid-template-columns: repeat({columns}, {int(width)}px)">'
            + "".join(cells) + "</div>\n" + viewer_scripts(views))


__all__ = ["BUNDLE", "LICENCE", "Layer", "View", "VIEWER_CSS", "bundle_text", "view_element", "viewer_html",
           "viewer_scripts"]
