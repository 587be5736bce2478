import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from procmod.core import InvalidArgumentError
from procmod.geometry import (Canvas, Disc, Polygon, Segment, contact_sheet, leaf_polygon,
                              rasterize, render_image, render_svg)

VP = (0.0, 10.0, 0.0, 10.0)


def test_disc_and_segment_areas_match_geometry():
    size = 400  # 40 px per world unit
    disc = rasterize([Disc(5, 5, 2)], VP, size)
    px_area = (10 / size) ** 2
    assert abs(disc.sum() * px_area - math.pi * 4) / (math.pi * 4) < 0.01
    seg = rasterize([Segment(2, 5, 8, 5, 1.0)], VP, size)
    expected = 6 * 1.0 + math.pi * 0.25  # rectangle plus two half-disc caps
    assert abs(seg.sum() * px_area - expected) / expected < 0.01


def test_polygon_area_and_orientation():
    square = Polygon(((2, 2), (6, 2), (6, 4), (2, 4)))
    mask = rasterize([square], VP, 100)
    assert mask.sum() == 40 * 20
    assert mask[25, 30] and not mask[50, 30]  # row = y, column = x
    leaf = leaf_polygon(1, 5, 0.0, 4, 1)
    assert rasterize([leaf], VP, 200).sum() > 0


def test_last_changed_and_gain_are_incremental():
    rng = np.random.default_rng(0)
    gain = rng.normal(size=50 * 50)
    canvas = Canvas(VP, 50, 50, gain=gain)
    shapes = [Segment(1, 1, 9, 8, 0.8), Disc(5, 5, 2), Polygon(((0, 0), (4, 0), (0, 6))),
              Segment(9, 1, 1, 9, 0.3)]
    for shape in shapes:
        before = canvas.pixels.copy()
        n = canvas.add(shape)
        changed = np.flatnonzero((before == 0) & (canvas.pixels != 0))
        assert n == len(changed)
        assert np.array_equal(np.sort(canvas.last_changed), changed)
    assert math.isclose(canvas.gain_total, gain[canvas.pixels != 0].sum(), rel_tol=1e-9)


def test_thin_strokes_are_at_least_one_pixel():
    mask = rasterize([Segment(0.5, 5.1, 9.5, 5.1, 0.001)], VP, 10)
    assert mask.sum() >= 9


def test_copy_is_independent():
    a = Canvas(VP, 20)
    a.add(Disc(5, 5, 1))
    b = a.copy()
    b.add(Disc(2, 2, 1))
    assert a.filled.sum() < b.filled.sum()
    assert a.extent != b.extent


def test_out_of_bounds_fraction():
    c = Canvas(VP, 20)
    c.add(Segment(-1, 5, 5, 5, 0.0))
    ex, ey = c.out_of_bounds()
    assert math.isclose(ex, 0.1) and ey == 0.0


def test_render_any_resolution_and_svg():
    shapes = [Segment(1, 1, 9, 9, 0.5, "stem"), Disc(5, 5, 1, "flower"),
              leaf_polygon(3, 3, 1.0, 2, 1)]
    small = render_image(shapes, VP, 32)
    big = render_image(shapes, VP, 300)
    assert small.size == (32, 32) and big.size == (300, 300)
    svg = ET.fromstring(render_svg(shapes, VP, 300))
    tags = [child.tag.split("}")[1] for child in svg]
    assert tags == ["rect", "line", "circle", "polygon"]


def test_contact_sheet_tiles():
    tile = render_image([Disc(5, 5, 2)], VP, 40)
    sheet = contact_sheet([tile] * 5, labels=list("abcde"))
    assert sheet.size[0] == 3 * 46 + 6
    with pytest.raises(ValueError):
        contact_sheet([])


def test_ellipse_area_and_bounds():
    from procmod.geometry import Ellipse, bounds
    e = Ellipse(5, 5, 0.7, 6, 2)
    size = 400
    mask = rasterize([e], VP, size)
    area = math.pi * 3 * 1
    assert abs(mask.sum() * (10 / size) ** 2 - area) / area < 0.01
    x0, x1, y0, y1 = bounds(e)
    cols = np.flatnonzero(mask.any(axis=0)) * (10 / size)
    assert x0 - 0.05 <= cols.min() and cols.max() <= x1 + 0.05


def test_pictures_cover_what_the_scoring_raster_covers():
    # Pictures are drawn by PIL (fast), scores by the raster (a pixel centre inside the
    # primitive): the two must agree but for edge pixels, or a report would show another
    # shape than the one that was scored.
    import numpy as np
    from procmod.geometry.export import render_image
    from procmod.geometry.primitives import Disc, Ellipse, Segment, Viewport
    from procmod.geometry.raster import Canvas

    vp = Viewport(-10.0, 10.0, -10.0, 10.0)
    shapes = [Segment(-6.0, -5.0, 5.0, 3.0, 1.5), Disc(4.0, -4.0, 2.5, tag="disc"),
              Ellipse(-3.0, 5.0, 0.7, 6.0, 2.0, tag="leaf"), Segment(2.0, 7.0, 2.0, 7.0, 0.8)]
    for shape in shapes:
        picture = np.asarray(render_image([shape], vp, 200, supersample=1)).sum(axis=2) < 3 * 250
        canvas = Canvas(vp, 200, 200)
        canvas.add(shape)
        raster = canvas.pixels.reshape(200, 200) != 0
        union, both = (picture | raster).sum(), (picture & raster).sum()
        assert union > 0 and both / union > 0.85, (shape, both / union)


def test_huge_finite_coordinates_draw_what_lies_on_the_canvas_without_crashing():
    """A segment or polygon reaching 1e19-1e200 world units (a growth factor typed 1.9 for
    0.9) overflowed the kernels' int64 pixel bounds: a segfault, or a loop SIGTERM could
    not stop. Run in a child process, so that a crash fails this test, not the suite."""
    import subprocess
    import sys
    code = """
from procmod.geometry import Canvas, Polygon, Segment
from procmod.geometry.camera import Camera, Silhouettes
from procmod.geometry.solid import Box
import numpy as np
far = Canvas((-12, 12, -22, 2), 50)
near = Canvas((-12, 12, -22, 2), 50)
print(far.add(Segment(0, -10, 1e19, -10, 0.5)) == near.add(Segment(0, -10, 12, -10, 0.5)))
print(Canvas((-12, 12, -22, 2), 50).add(Segment(0, -10, 0, 1e200, 0.5)) > 0)
print(Canvas((-12, 12, -22, 2), 50).add(Polygon(((0, -10), (1e19, -5), (3, -8)))) > 0)
views = Silhouettes([Camera((0, 0, 10), (0, 0, 0), projection="orthographic", fov=4, width=20, height=20)])
print(views.add(Box((1e20, 1.0, 1.0))) > 0)
"""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.split() == ["True"] * 4, done.stdout


def test_a_reversed_or_empty_viewport_is_refused():
    """Canvas((12, -12, -22, 2), 50), x reversed, drew nothing at all, without a word."""
    for viewport in ((12, -12, -22, 2), (-12, 12, 2, -22), (0, 0, -22, 2), (-12, 12, -22, float("inf"))):
        with pytest.raises(InvalidArgumentError, match="viewport is \\(xmin, xmax, ymin, ymax\\) with xmin < xmax"):
            Canvas(viewport, 50)
    assert Canvas((-12, 12, -22, 2), 50).add(Disc(0, -10, 1)) > 0
