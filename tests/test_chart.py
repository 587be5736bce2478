"""The report's SVG line chart (procmod.chart)."""

import math
import xml.etree.ElementTree as ET

import pytest

from procmod.chart import Series, line_chart_svg, nice_ticks

SVG = "{http://www.w3.org/2000/svg}"


@pytest.mark.parametrize("low, high", [(0, 1), (0.013, 0.87), (-3.2, 17.5), (0, 123456), (5, 5), (-1e-4, 2e-4)])
def test_nice_ticks_cover_the_range_with_round_even_steps(low, high):
    ticks = nice_ticks(low, high)
    assert 2 <= len(ticks) <= 11
    steps = {round(b - a, 9) for a, b in zip(ticks, ticks[1:])}
    assert len(steps) == 1  # evenly spaced
    step = steps.pop()
    mantissa = step / 10 ** math.floor(math.log10(step))
    assert min(abs(mantissa - m) for m in (1, 2, 5, 10)) < 1e-6
    if high > low:
        assert low - 1e-9 <= ticks[0] < low + step and high - step < ticks[-1] <= high + 1e-9


def test_nice_ticks_of_a_non_finite_range_are_none():
    assert nice_ticks(0, math.inf) == [] and nice_ticks(math.nan, 1) == []


def _polylines(svg):
    root = ET.fromstring(svg)
    return [[tuple(map(float, p.split(","))) for p in line.get("points").split()]
            for line in root.iter(SVG + "polyline")]


def test_chart_is_valid_svg_with_one_polyline_per_series_and_stable_bytes():
    best = Series("smc best", [0, 10, 20, 40], [0.1, 0.3, 0.3, 0.8], step=True)
    mean = Series("smc mean", [0, 10, 20, 40], [0.05, 0.2, 0.25, 0.5], dashed=True)
    svg = line_chart_svg([best, mean], "title <&>", "evaluations", "score", "a note")
    assert svg == line_chart_svg([best, mean], "title <&>", "evaluations", "score", "a note")
    lines = _polylines(svg)
    assert len(lines) == 2
    step, plain = lines
    # a post-step: every rise is a vertical then a horizontal move, held to the axis' end
    assert len(step) == 2 * 4 - 1 + 1 and len(plain) == 4
    assert all(a[0] == b[0] or a[1] == b[1] for a, b in zip(step, step[1:]))
    # higher scores are drawn higher (smaller y), inside the plot
    assert plain[-1][1] < plain[0][1]
    texts = [t.text for t in ET.fromstring(svg).iter(SVG + "text")]
    assert "title <&>" in texts and "smc best" in texts and "a note" in texts


def test_chart_skips_non_finite_points_and_draws_empty_axes_without_data():
    svg = line_chart_svg([Series("s", [0, 1, 2], [-math.inf, 0.5, math.nan])])
    assert _polylines(svg) == [[_polylines(svg)[0][0]]]
    empty = line_chart_svg([Series("s", [], [])])
    ET.fromstring(empty)
    assert _polylines(empty) == []
