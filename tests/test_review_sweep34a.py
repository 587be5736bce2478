"""Review of sweep 34's see-through drawings: an opaque shape on a transparent ground with
small see-through holes or slots (a building's windows, a white calendar icon's day cells, a
dark stencil plate's cut letters) is the shape, as before; only strokes see-through on a
light page are a drawing."""

import numpy as np
from PIL import Image, ImageDraw

from procmod.targets import load_target_image


def _picture(tmp_path, name: str, colour: tuple, box: tuple, holes: list) -> np.ndarray:
    """A ``colour`` rectangle ``box`` on a clear 200x200 ground with clear ``holes``
    (rectangles) cut into it, saved as ``name``; returns its opaque part."""
    picture = Image.new("RGBA", (200, 200), (0, 0, 0, 0))
    draw = ImageDraw.Draw(picture)
    draw.rectangle(box, fill=colour + (255,))
    for hole in holes:
        draw.rectangle(hole, fill=(0, 0, 0, 0))
    picture.save(tmp_path / name)
    return np.asarray(picture)[:, :, 3] > 0


def test_a_building_with_see_through_windows_is_the_shape(tmp_path):
    windows = [(20 + 20 * i + 6, 45 + 20 * j + 6, 20 + 20 * i + 13, 45 + 20 * j + 13) for i in range(8)
               for j in range(7)]
    opaque = _picture(tmp_path, "facade.png", (150, 150, 150), (20, 45, 180, 195), windows)
    assert np.array_equal(load_target_image(tmp_path / "facade.png").mask, opaque)


def test_a_white_icon_with_small_square_holes_is_the_shape(tmp_path):
    cells = [(20 + 24 * i, 60 + 25 * j, 32 + 24 * i, 72 + 25 * j) for i in range(7) for j in range(5)]
    opaque = _picture(tmp_path, "calendar.png", (255, 255, 255), (10, 10, 190, 190), cells)
    assert np.array_equal(load_target_image(tmp_path / "calendar.png").mask, opaque)


def test_a_dark_stencil_plate_with_cut_letters_is_the_shape(tmp_path):
    slots = [slot for x in (30, 70, 110, 150) for slot in ((x, 40, x + 6, 160), (x, 40, x + 25, 46))]
    opaque = _picture(tmp_path, "stencil.png", (30, 30, 30), (2, 2, 197, 197), slots)
    assert np.array_equal(load_target_image(tmp_path / "stencil.png").mask, opaque)
