"""Picture targets users give that had read wrong (sweep 35): a float picture whose drawing is
NaN (with a soft grey edge, or thick), a stencil cut with a fat brush (a GIF or palette PNG
whose ink is its transparent colour, drawn with thick strokes), and a float 0..255 or 0..1
picture whose paper goes a little past its white (a resample's overshoot)."""

import numpy as np
import pytest
from PIL import Image, ImageDraw
from scipy import ndimage

from procmod.data import target_from_spec
from procmod.targets import load_target_image
from procmod.targets.image import grey_levels, picture_in_square


def _letter(size: int = 200, pen: int = 6) -> np.ndarray:
    """An "A": two legs and a bar, drawn ``pen`` pixels wide."""
    picture = Image.new("L", (size, size), 0)
    draw = ImageDraw.Draw(picture)
    s = size / 200
    draw.line([(40 * s, 160 * s), (100 * s, 40 * s), (160 * s, 160 * s)], fill=255, width=pen)
    draw.line([(70 * s, 110 * s), (130 * s, 110 * s)], fill=255, width=pen)
    return np.asarray(picture) > 127


def _read(path) -> np.ndarray:
    """The mask a picture reads as, cut back from its square to the picture's own pixels."""
    target = load_target_image(path)
    top, left, height, width = target.picture
    return target.mask[top:top + height, left:left + width]


def _overlap(mask: np.ndarray, truth: np.ndarray) -> float:
    return float((mask & truth).sum()) / float((mask | truth).sum())


def _stencil(path, ink: np.ndarray, page=(255, 255, 255), fmt=None) -> None:
    """A palette picture of a page whose ink is the transparent colour (index 1)."""
    picture = Image.fromarray(ink.astype(np.uint8), "P")
    picture.putpalette(list(page) + [0, 0, 0] + [0] * 762)
    picture.save(path, format=fmt, transparency=1)


@pytest.mark.parametrize("suffix", [".png", ".gif"])
def test_stencil_cut_with_a_fat_brush_reads_as_its_strokes(tmp_path, suffix):
    ink = _letter(pen=22)  # strokes 11% of the picture wide: the 2% thinning left most of them
    _stencil(tmp_path / f"fat{suffix}", ink)
    assert _overlap(_read(tmp_path / f"fat{suffix}"), ink) > 0.95


def test_fat_see_through_holes_that_are_no_strokes_stay_the_page(tmp_path):
    # square panes and straight slots are convex: a window, a vent, not a drawing
    for name, holes in (("panes", [(40, 40, 90, 90), (40, 170, 90, 90), (170, 40, 90, 90), (170, 170, 90, 90)]),
                        ("slots", [(30, 60, 240, 40), (30, 200, 240, 40)])):
        ink = np.zeros((300, 300), dtype=bool)
        for top, left, height, width in holes:
            ink[top:top + height, left:left + width] = True
        _stencil(tmp_path / f"{name}.png", ink, page=(250, 250, 250))
        assert np.array_equal(_read(tmp_path / f"{name}.png"), ~ink), name


def test_fat_see_through_strokes_on_a_dark_plate_stay_the_plate(tmp_path):
    ink = _letter(pen=22)
    _stencil(tmp_path / "plate.png", ink, page=(60, 60, 60))  # a stencil's plate, not paper
    assert np.array_equal(_read(tmp_path / "plate.png"), ~ink)


def test_thick_nan_drawing_on_a_light_float_ground_is_the_shape(tmp_path):
    ink = _letter(pen=22)
    values = np.full(ink.shape, 0.95, dtype=np.float32)
    values[ink] = np.nan
    Image.fromarray(values, "F").save(tmp_path / "nan.tif")
    assert _overlap(_read(tmp_path / "nan.tif"), ink) > 0.95


def test_nan_drawing_with_a_soft_grey_edge_is_read_whole(tmp_path):
    # a render's anti-aliasing: a finite grey rim around strokes of NaN had alone been the drawing
    ink = _letter()
    rim = ndimage.binary_dilation(ink) & ~ink
    values = np.full(ink.shape, 0.95, dtype=np.float32)
    values[rim] = 0.5
    values[ink] = np.nan
    Image.fromarray(values, "F").save(tmp_path / "rim.tif")
    mask = _read(tmp_path / "rim.tif")
    assert mask[ink].all() and not mask[~(ink | rim)].any()


def test_nan_ground_around_a_finite_drawing_stays_paper(tmp_path):
    ink = _letter(pen=22)
    values = np.full(ink.shape, np.nan, dtype=np.float32)
    values[ink] = 0.3
    Image.fromarray(values, "F").save(tmp_path / "render.tif")
    assert np.array_equal(_read(tmp_path / "render.tif"), ink)


@pytest.mark.parametrize("white", [255.5, 256.0, 270.0])
def test_float_paper_a_little_past_255_reads_against_255(tmp_path, white):
    ink = _letter()
    values = np.full(ink.shape, white, dtype=np.float32)
    values[ink] = 190.0  # pencil: against a white of 1023 it was too faint to be a drawing
    picture = Image.fromarray(values, "F")
    assert grey_levels(picture)[0, 0] == 255.0
    picture.save(tmp_path / "pencil.tif")
    assert np.array_equal(_read(tmp_path / "pencil.tif"), ink)


def test_integer_picture_of_0_to_256_reads_against_255(tmp_path):
    ink = _letter()
    values = np.where(ink, 180, 256).astype(np.int32)  # a 32-bit TIFF declares no white
    Image.fromarray(values, "I").save(tmp_path / "int.tif")
    assert np.array_equal(_read(tmp_path / "int.tif"), ink)


def test_float_0_to_1_paper_a_little_past_1_reads_against_1(tmp_path):
    ink = _letter()
    values = np.full(ink.shape, 1.004, dtype=np.float32)
    values[ink] = 0.75
    Image.fromarray(values, "F").save(tmp_path / "unit.tif")
    assert np.array_equal(_read(tmp_path / "unit.tif"), ink)


def test_float_10_bit_paper_a_little_past_1023_reads_against_1023(tmp_path):
    ink = _letter()
    values = np.full(ink.shape, 1030.0, dtype=np.float32)
    values[ink] = 700.0
    Image.fromarray(values, "F").save(tmp_path / "ten.tif")
    assert np.array_equal(_read(tmp_path / "ten.tif"), ink)


def test_cli_spec_reads_the_fat_stencil(tmp_path):
    ink = _letter(pen=22)
    _stencil(tmp_path / "fat.gif", ink)
    target = target_from_spec(str(tmp_path / "fat.gif"))
    top, left, height, width = picture_in_square(*ink.shape)
    assert _overlap(target.image.mask[top:top + height, left:left + width], ink) > 0.95
