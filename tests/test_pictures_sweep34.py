"""Picture targets users give that had read wrong (sweep 34): a 16-bit colour PNG holding a
10-, 12- or 14-bit scan, real-valued and integer TIFFs of 0..1000, NaN or infinity as the
paper, and a GIF or palette PNG whose ink is its transparent colour."""

import os
import struct
import zlib

import numpy as np
import pytest
from PIL import Image

from procmod.core import ProcmodError
from procmod.data import target_from_spec
from procmod.targets import load_target_image
from procmod.targets.image import grey_levels, open_image


def _drawing(size: int = 96, pen: int = 0) -> np.ndarray:
    """An upside-down T: a stem and a bar across its foot, drawn ``pen`` pixels wide (0: an
    eighth and a sixteenth of the picture)."""
    ink = np.zeros((size, size), dtype=bool)
    stem, bar = (pen, pen) if pen else (size // 8, size // 16)
    ink[size // 8:size * 7 // 8, size // 2 - stem // 2:size // 2 - stem // 2 + stem] = True
    ink[size * 3 // 4:size * 3 // 4 + bar, size // 5:size * 4 // 5] = True
    return ink


def _paeth(a: int, b: int, c: int) -> int:
    p = a + b - c
    pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
    return a if pa <= pb and pa <= pc else (b if pb <= pc else c)


def _filtered(rows: list, bpp: int) -> bytes:
    """PNG scanlines with the Sub, Up, Average and Paeth filters in turn (each reads bytes a
    whole pixel back: a decoder that took a 16-bit pixel for fewer bytes gets them wrong)."""
    out, previous = [], bytes(len(rows[0]))
    for k, row in enumerate(rows):
        kind = k % 4 + 1
        line = bytearray(len(row))
        for i in range(len(row)):
            a = row[i - bpp] if i >= bpp else 0
            b, c = previous[i], previous[i - bpp] if i >= bpp else 0
            line[i] = (row[i] - {1: a, 2: b, 3: (a + b) // 2, 4: _paeth(a, b, c)}[kind]) % 256
        out.append(bytes([kind]) + bytes(line))
        previous = row
    return b"".join(out)


_ADAM7 = [(0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2), (0, 1, 1, 2)]


def _png16(path, values: np.ndarray, colour_type: int, interlace: bool = False, trns=None):
    """A 16-bit PNG as a scanner writes one (Pillow writes no 16-bit colour PNG)."""
    height, width = values.shape[:2]
    bpp = 2 * (values.shape[2] if values.ndim == 3 else 1)
    passes = _ADAM7 if interlace else [(0, 0, 1, 1)]
    data = b""
    for x0, y0, dx, dy in passes:
        part = values[y0::dy, x0::dx]
        if part.size:
            data += _filtered([row.astype(">u2").tobytes() for row in part], bpp)

    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body))

    png = b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 16, colour_type, 0, 0,
                                                          int(interlace)))
    if trns is not None:
        png += chunk(b"tRNS", struct.pack(">HHH", *trns))
    path.write_bytes(png + chunk(b"IDAT", zlib.compress(data)) + chunk(b"IEND", b""))
    return path


@pytest.mark.parametrize("interlace", [False, True])
def test_a_12_bit_scan_in_a_16_bit_rgb_png_is_read_at_full_depth(tmp_path, interlace):
    """Pillow keeps a 16-bit RGB PNG's high bytes only: a 12-bit scan (0..4095) read 0..15,
    near black, and was refused as empty ("draw the shape darker")."""
    ink = _drawing(64)
    noise = np.random.default_rng(0).integers(0, 40, ink.shape + (3,))
    values = (np.where(ink[:, :, None], [300, 200, 100], [3900, 3950, 4000]) + noise).astype(np.uint16)
    path = _png16(tmp_path / "scan.png", values, 2, interlace=interlace)
    assert np.array_equal(load_target_image(path).mask, ink)
    # every pixel, through the PNG's filters and interlacing, scaled from 12 bits' white
    expected = np.round(values * (255.0 / 4095)).astype(np.uint8)
    assert np.array_equal(np.asarray(open_image(path)), expected)


def test_12_bit_rgba_grey_with_alpha_and_a_transparent_colour_are_read_too(tmp_path):
    ink = _drawing()
    rgb = np.where(ink[:, :, None], [300, 200, 100], [3900, 3950, 4000]).astype(np.uint16)
    rgba = np.concatenate([rgb, np.full(ink.shape + (1,), 4095, np.uint16)], axis=2)
    grey_alpha = np.stack([np.where(ink, 200, 4000), np.full(ink.shape, 4095)], axis=2).astype(np.uint16)
    cut_out = np.where(ink[:, :, None], [300, 200, 100], [4000, 4000, 4000]).astype(np.uint16)
    for path in (_png16(tmp_path / "rgba.png", rgba, 6), _png16(tmp_path / "la.png", grey_alpha, 4),
                 _png16(tmp_path / "cut.png", cut_out, 2, trns=(4000, 4000, 4000))):
        assert np.array_equal(target_from_spec(str(path)).image.mask, ink), path.name
    assert open_image(tmp_path / "cut.png").mode == "RGBA"  # the tRNS colour's pixels see-through


def test_a_16_bit_rgb_png_that_uses_all_16_bits_reads_as_before(tmp_path):
    """Its high bytes are its 8 bits: Pillow's reading is kept, pixel for pixel."""
    ink = _drawing()
    values = np.where(ink[:, :, None], [3000, 2000, 1000], [60000, 61000, 62000]).astype(np.uint16)
    path = _png16(tmp_path / "full.png", values, 2)
    assert np.array_equal(np.asarray(open_image(path)), (values >> 8).astype(np.uint8))
    assert np.array_equal(load_target_image(path).mask, ink)


@pytest.mark.skipif(not os.path.isdir("/proc/self/fd"), reason="a pipe named by /proc/self/fd (Linux)")
def test_a_12_bit_rgb_png_piped_in_is_read_at_full_depth(tmp_path):
    """Through a pipe (``--target /dev/stdin``) the picture is read once into memory and
    decoded again from there."""
    ink = _drawing(48)
    values = np.where(ink[:, :, None], [300, 200, 100], [3900, 3950, 4000]).astype(np.uint16)
    data = _png16(tmp_path / "scan.png", values, 2).read_bytes()
    assert len(data) < 65536  # (all of it in the pipe's buffer before procmod reads: no writer to wait on)
    read_end, write_end = os.pipe()
    try:
        os.write(write_end, data)
        os.close(write_end)
        picture = open_image(f"/proc/self/fd/{read_end}")
    finally:
        os.close(read_end)
    assert np.array_equal(np.asarray(picture), np.round(values * (255.0 / 4095)).astype(np.uint8))


@pytest.mark.parametrize("kind", ["float", "int32", "uint16"])
def test_a_tiff_of_0_to_1000_is_read_by_its_own_range(tmp_path, kind):
    """Scaled from 65535 (no white declared, or 16 bits declared), 0..1000 read as black
    and the drawing was refused as empty."""
    ink = _drawing()
    for name, paper, drawn in (("dark_ink", 1000, 0), ("light_ink", 0, 1000)):
        values = np.where(ink, drawn, paper).astype({"float": np.float32, "int32": np.int32,
                                                      "uint16": np.uint16}[kind])
        path = tmp_path / f"{name}.tif"
        Image.fromarray(values, "F" if kind == "float" else ("I" if kind == "int32" else None)).save(path)
        assert np.array_equal(load_target_image(path).mask, ink), name
    # white is that of the 10 bits the values use, as a 16-bit PNG's
    assert grey_levels(open_image(tmp_path / "light_ink.tif")).max() == pytest.approx(1000 * 255 / 1023)


def test_nan_or_infinity_as_the_paper_is_paper(tmp_path):
    """A render's NaN background read black and an infinite one as its white: a shaded
    object on NaN lost its dark side, one on infinity (a depth map's misses) was refused."""
    yy, xx = np.mgrid[:96, :96]
    disc = (yy - 48) ** 2 + (xx - 48) ** 2 < 30 ** 2
    shade = np.clip(0.02 + 0.9 * (xx - 18) / 60, 0, 1)
    Image.fromarray(np.where(disc, shade, np.nan).astype(np.float32), "F").save(tmp_path / "render.tif")
    Image.fromarray(np.where(disc, 500.0 + yy % 7, np.inf).astype(np.float32), "F").save(tmp_path / "depth.tif")
    for name in ("render.tif", "depth.tif"):
        assert np.array_equal(load_target_image(tmp_path / name).mask, disc), name
    # a few NaN pixels in a drawing on paper are paper, not specks of ink
    ink = _drawing()
    page = np.where(ink, 0.1, 0.95).astype(np.float32)
    page[~ink & (yy % 13 == 5) & (xx % 17 == 3)] = np.nan
    Image.fromarray(page, "F").save(tmp_path / "dropouts.tif")
    assert np.array_equal(load_target_image(tmp_path / "dropouts.tif").mask, ink)


def test_a_picture_all_nan_says_so(tmp_path):
    """It had been told to draw the shape darker."""
    for value in (np.nan, np.inf):
        Image.fromarray(np.full((20, 20), value, np.float32), "F").save(tmp_path / "blank.tif")
        with pytest.raises(ProcmodError, match="all NaN or infinite") as caught:
            target_from_spec(str(tmp_path / "blank.tif"))
        assert "\n" not in str(caught.value)


@pytest.mark.parametrize("suffix", ["gif", "png"])
def test_ink_that_is_the_transparent_colour_is_the_drawing(tmp_path, suffix):
    """A GIF or palette PNG whose tool made the ink's index (0, black) the transparent one
    was read inverted: the page around the drawing as the shape."""
    ink = _drawing(pen=4)
    picture = Image.fromarray(np.where(ink, 0, 1).astype(np.uint8), "P")
    picture.putpalette([0, 0, 0, 255, 255, 255] + [0] * 762)
    picture.save(tmp_path / f"drawing.{suffix}", transparency=0)
    assert np.array_equal(load_target_image(tmp_path / f"drawing.{suffix}").mask, ink)


def test_a_silhouette_view_whose_ink_is_the_transparent_colour_hits_the_strokes(tmp_path):
    """A silhouette view drawn as such a GIF hit its blank page and avoided its strokes (the
    picture target reads it right, above); a blank page on a transparent ground stays the
    shape to hit."""
    from procmod.targets.files import _picture_view_weights

    ink = _drawing(pen=4)
    picture = Image.fromarray(np.where(ink, 0, 1).astype(np.uint8), "P")
    picture.putpalette([0, 0, 0, 255, 255, 255] + [0] * 762)
    picture.save(tmp_path / "view.gif", transparency=0)
    notes = []
    weights = _picture_view_weights(tmp_path / "view.gif", "views[0]", 1.0, -1.0, notes)
    assert np.array_equal(weights > 0, ink) and np.array_equal(weights < 0, ~ink)
    assert len(notes) == 1 and "see-through" in notes[0] and "\n" not in notes[0]
    page = np.zeros((96, 96, 4), np.uint8)
    page[8:88, 8:88] = 255
    Image.fromarray(page, "RGBA").save(tmp_path / "page.png")
    weights = _picture_view_weights(tmp_path / "page.png", "views[0]", 1.0, -1.0, [])
    assert np.array_equal(weights > 0, page[:, :, 3] > 0)


def test_see_through_strokes_on_a_page_inside_a_margin_are_the_drawing(tmp_path):
    ink = _drawing(160, pen=5)
    rgba = np.zeros((160, 160, 4), np.uint8)
    rgba[10:150, 10:150] = (250, 250, 250, 255)
    for row, col in ((10, 10), (10, 149), (149, 10), (149, 149)):  # rounded corners
        rgba[max(row - 3, 0):row + 4, max(col - 3, 0):col + 4, 3] = 0
    blank = rgba.copy()
    rgba[ink] = 0
    Image.fromarray(rgba, "RGBA").save(tmp_path / "stencil.png")
    assert np.array_equal(load_target_image(tmp_path / "stencil.png").mask, ink)
    # a blank page stays the shape: its clear corners and margin are no drawing
    Image.fromarray(blank, "RGBA").save(tmp_path / "blank.png")
    assert np.array_equal(load_target_image(tmp_path / "blank.png").mask, blank[:, :, 3] > 0)


def test_wide_see_through_holes_keep_the_opaque_part_as_the_shape(tmp_path):
    """A window's frame with clear panes, a thick ring: the opaque part is the shape, as before."""
    frame = np.zeros((96, 96, 4), np.uint8)
    frame[:, :] = (90, 60, 30, 255)
    frame[10:44, 10:44, 3] = frame[10:44, 52:86, 3] = frame[52:86, 10:44, 3] = frame[52:86, 52:86, 3] = 0
    Image.fromarray(frame, "RGBA").save(tmp_path / "window.png")
    assert np.array_equal(load_target_image(tmp_path / "window.png").mask, frame[:, :, 3] > 0)
