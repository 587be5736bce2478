"""A small line chart written straight to SVG, for the run report.

Why not matplotlib: a run's report has one chart, and importing matplotlib and drawing it
cost ~0.7 s of every ``procmod infer`` (more than a 10-particle guided run's inference),
growing with the history's length. This draws the same information — lines, steps,
dashes, nice axis ticks, a legend, a title and a note — as a few kilobytes of text in
about a millisecond, and as vector graphics it stays sharp at any zoom. Numbers are
written with fixed precision, so equal inputs give equal bytes.
"""

from __future__ import annotations

import html
import math
from dataclasses import dataclass

# matplotlib's default colour cycle, so reports look as they did
COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f")


@dataclass(frozen=True)
class Series:
    """One curve: ``step`` draws a post-step (held until the next x), ``dashed`` a dashed
    line, ``markers`` a dot at each point (a curve of one point is seen)."""

    label: str
    x: list
    y: list
    colour: str = COLOURS[0]
    dashed: bool = False
    step: bool = False
    opacity: float = 1.0
    markers: bool = False


def nice_ticks(low: float, high: float, count: int = 5) -> list:
    """About ``count`` round tick values (1, 2 or 5 times a power of ten apart) covering
    [low, high]."""
    if not (math.isfinite(low) and math.isfinite(high)):
        return []
    if high <= low:
        high = low + (abs(low) or 1.0)
    raw = (high - low) / max(1, count)
    power = 10.0 ** math.floor(math.log10(raw))
    step = next(m * power for m in (1, 2, 5, 10) if m * power >= raw)
    first = math.ceil(low / step - 1e-9)
    last = math.floor(high / step + 1e-9)
    return [round(i * step, 12) for i in range(first, last + 1)]


def _label(value: float) -> str:
    """A tick label: 250k, 1.5M, 0.25, 1e-05."""
    for scale, suffix in ((1e9, "G"), (1e6, "M"), (1e4, "k")):
        if abs(value) >= scale:
            return f"{value / (scale if suffix != 'k' else 1e3):.6g}{suffix}"
    if value != 0 and abs(value) < 1e-3:
        return f"{value:.0e}"
    return f"{value:.6g}"


def line_chart_svg(series: list, title: str = "", xlabel: str = "", ylabel: str = "", note: str = "",
                   width: int = 640, height: int = 380) -> str:
    """An SVG document plotting ``series`` (:class:`Series`) on shared linear axes.

    Points with a non-finite coordinate are left out. With no finite point at all the
    axes are drawn empty.
    """
    points = [[(float(a), float(b)) for a, b in zip(s.x, s.y) if math.isfinite(a) and math.isfinite(b)]
              for s in series]
    xs = [p[0] for pts in points for p in pts]
    ys = [p[1] for pts in points for p in pts]
    x_low, x_high = (min(xs), max(xs)) if xs else (0.0, 1.0)
    y_low, y_high = (min(ys), max(ys)) if ys else (0.0, 1.0)
    if x_high <= x_low:
        x_high = x_low + 1.0
    if y_high <= y_low:
        pad = abs(y_low) * 0.05 or 0.05
        y_low, y_high = y_low - pad, y_high + pad
    pad = 0.05 * (y_high - y_low)  # room above and below the curves, as matplotlib leaves
    y_low, y_high = y_low - pad, y_high + pad
    note_lines = [line for line in note.splitlines() if line]
    left, right, top = 62, 14, 34 if title else 14
    bottom = 46 + 12 * len(note_lines)
    plot_w, plot_h = width - left - right, height - top - bottom

    def px(x: float) -> float:
        return left + plot_w * (x - x_low) / (x_high - x_low)

    def py(y: float) -> float:
        return top + plot_h * (1.0 - (y - y_low) / (y_high - y_low))

    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
           f'viewBox="0 0 {width} {height}" font-family="sans-serif" font-size="11">',
           f'<rect width="{width}" height="{height}" fill="white"/>']
    if title:
        out.append(f'<text x="{left + plot_w / 2:.1f}" y="20" text-anchor="middle" font-size="13">'
                   f'{html.escape(title)}</text>')
    for value in nice_ticks(x_low, x_high):
        x = px(value)
        out.append(f'<line x1="{x:.1f}" y1="{top}" x2="{x:.1f}" y2="{top + plot_h}" stroke="#e6e6e6"/>')
        out.append(f'<text x="{x:.1f}" y="{top + plot_h + 15}" text-anchor="middle">{_label(value)}</text>')
    for value in nice_ticks(y_low, y_high):
        y = py(value)
        out.append(f'<line x1="{left}" y1="{y:.1f}" x2="{left + plot_w}" y2="{y:.1f}" stroke="#e6e6e6"/>')
        out.append(f'<text x="{left - 5}" y="{y + 4:.1f}" text-anchor="end">{_label(value)}</text>')
    out.append(f'<rect x="{left}" y="{top}" width="{plot_w}" height="{plot_h}" fill="none" stroke="#444"/>')
    if xlabel:
        out.append(f'<text x="{left + plot_w / 2:.1f}" y="{top + plot_h + 32}" text-anchor="middle">'
                   f'{html.escape(xlabel)}</text>')
    if ylabel:
        cy = top + plot_h / 2
        out.append(f'<text x="14" y="{cy:.1f}" text-anchor="middle" transform="rotate(-90 14 {cy:.1f})">'
                   f'{html.escape(ylabel)}</text>')
    for s, pts in zip(series, points):
        if not pts:
            continue
        coords = []
        for i, (x, y) in enumerate(pts):
            if s.step and i:
                coords.append(f"{px(x):.1f},{py(pts[i - 1][1]):.1f}")
            coords.append(f"{px(x):.1f},{py(y):.1f}")
        if s.step:  # held to the axis' end, as a post-step plot is
            coords.append(f"{px(x_high):.1f},{py(pts[-1][1]):.1f}")
        dash = ' stroke-dasharray="6 3"' if s.dashed else ""
        out.append(f'<polyline points="{" ".join(coords)}" fill="none" stroke="{s.colour}" stroke-width="1.5"'
                   f' stroke-opacity="{s.opacity:g}"{dash}/>')
        if s.markers:
            out.extend(f'<circle cx="{px(x):.1f}" cy="{py(y):.1f}" r="2.5" fill="{s.colour}"/>' for x, y in pts)
    labelled = [s for s in series if s.label]
    if labelled:
        # lower right: score curves rise to the upper right
        lx, ly = left + plot_w - 150, top + plot_h - 16 - 15 * len(labelled)
        out.append(f'<rect x="{lx}" y="{ly}" width="142" height="{8 + 15 * len(labelled)}" fill="white" '
                   'fill-opacity="0.85" stroke="#ccc"/>')
        for i, s in enumerate(labelled):
            y = ly + 14 + 15 * i
            dash = ' stroke-dasharray="6 3"' if s.dashed else ""
            out.append(f'<line x1="{lx + 6}" y1="{y - 4}" x2="{lx + 30}" y2="{y - 4}" stroke="{s.colour}" '
                       f'stroke-width="1.5" stroke-opacity="{s.opacity:g}"{dash}/>')
            out.append(f'<text x="{lx + 36}" y="{y}" font-size="10">{html.escape(s.label[:24])}</text>')
    for i, line in enumerate(note_lines):
        out.append(f'<text x="6" y="{height - 6 - 12 * (len(note_lines) - 1 - i)}" font-size="9" fill="#595959">'
                   f'{html.escape(line)}</text>')
    out.append("</svg>")
    return "\n".join(out) + "\n"
