"""Pictures an adversarial sweep found read wrong: a phone photo's dark corners, a card on
a transparent canvas, a faint layer under the whole drawing, a 12-bit scan in a 16-bit PNG."""

import numpy as np
import pytest
from PIL import Image, ImageDraw

from procmod.targets.image import load_target_image


def _drawing(width, height, pen=5):
    """A stem, a loop and a branch: thin strokes covering about 1% of the picture."""
    picture = Image.new("L", (width, height), 0)
    draw = ImageDraw.Draw(picture)
    draw.line([(width * 0.5, height * 0.85), (width * 0.5, height * 0.3)], fill=255, width=pen)
    draw.arc([width * 0.3, height * 0.15, width * 0.7, height * 0.45], 0, 300, fill=255, width=pen)
    draw.line([(width * 0.5, height * 0.6), (width * 0.35, height * 0.45)], fill=255, width=pen)
    return np.asarray(picture) > 127


def _unpadded(target, height, width):
    top, left, _, _ = target.picture
    return target.mask[top:top + height, left:left + width]


@pytest.mark.parametrize("corner", [150, 110, 70])
@pytest.mark.parametrize("suffix", [".png", ".jpg"])
def test_a_phone_photos_dark_corners_are_no_shape(tmp_path, corner, suffix):
    """Pencil (grey 150) on paper (235) whose corners darken to the pencil's grey or
    darker (a phone's vignetting): the corners were read as shape, or, darker, as the
    only shape, the drawing lost."""
    rng = np.random.default_rng(1)
    h, w = 400, 300
    ink = _drawing(w, h, 4)
    yy, xx = np.mgrid[:h, :w]
    falloff = ((((xx - w / 2) / (w / 2)) ** 2 + ((yy - h / 2) / (h / 2)) ** 2) / 2) ** 1.5
    grey = np.where(ink, 150.0, 235 - (235 - corner) * falloff) + rng.normal(0, 2, (h, w))
    Image.fromarray(np.clip(grey, 0, 255).astype(np.uint8)).save(tmp_path / f"photo{suffix}", quality=90)
    read = _unpadded(load_target_image(tmp_path / f"photo{suffix}"), h, w)
    assert (read & ink).sum() >= 0.9 * ink.sum()
    assert (read & ~ink).sum() <= 0.1 * ink.sum()


def test_a_phone_photos_fall_of_light_dims_the_ink_in_the_corners_too(tmp_path):
    """A lens dims ink and paper alike: an X drawn corner to corner, photographed with the
    corners at 40% of the middle's light. The fall-off subtracted, not divided out, had left
    the strokes' ends in the corners out of the shape (h160)."""
    rng = np.random.default_rng(4)
    side = 300
    picture = Image.new("L", (side, side), 0)
    draw = ImageDraw.Draw(picture)
    draw.line([(0, 0), (side, side)], fill=255, width=4)
    draw.line([(side, 0), (0, side)], fill=255, width=4)
    ink = np.asarray(picture) > 127
    yy, xx = np.mgrid[:side, :side] + 0.5
    r2 = (((xx - side / 2) / (side / 2)) ** 2 + ((yy - side / 2) / (side / 2)) ** 2) / 2
    grey = np.where(ink, 40.0, 238.0) * (1 - 0.6 * r2) + rng.normal(0, 2, ink.shape)
    Image.fromarray(np.clip(grey, 0, 255).astype(np.uint8)).save(tmp_path / "x.png")
    read = _unpadded(load_target_image(tmp_path / "x.png"), side, side)
    assert (read & ink).sum() >= 0.99 * ink.sum() and (read & ~ink).sum() <= 0.02 * ink.sum()


def test_a_glow_on_a_dark_ground_is_no_fall_of_light(tmp_path):
    """A sun's glow over a navy ground falls off as a lens's light does; taken for one, the
    glow was divided out and specks of noise read as the shape (h160)."""
    side = 400
    yy, xx = np.mgrid[:side, :side] + 0.5
    glow = np.exp(-(np.hypot(xx / (side / 2) - 1, yy / (side / 2) - 1) / 0.8) ** 2)[..., None]
    rgb = np.array([20, 30, 70.0]) + (np.array([255, 230, 120.0]) - np.array([20, 30, 70.0])) * glow
    rgb += np.random.default_rng(5).normal(0, 1.5, rgb.shape)
    Image.fromarray(np.clip(rgb, 0, 255).astype(np.uint8)).save(tmp_path / "sun.png")
    read = load_target_image(tmp_path / "sun.png").mask
    bright = glow[..., 0] > 0.5
    assert (read & bright).sum() / (read | bright).sum() > 0.7


@pytest.mark.parametrize("hill_grey, drop", [(199, 0), (182, 31)])
def test_a_light_shape_along_a_side_is_no_fall_of_light(tmp_path, hill_grey, drop):
    """A pale hill filling the bottom of the picture, on even paper or paper lit from one
    side: a surface of any shape fitted to the paper had bent through it as light, and
    only a sliver along its top was left of the shape (h157); the fall-off a photo's
    corners have is radial."""
    rng = np.random.default_rng(3)
    h, w = 240, 320
    yy, xx = np.mgrid[:h, :w]
    hill = yy > h * 0.56 + 10 * np.sin(xx / 40)
    paper = 240 - drop * (yy / h)
    grey = np.where(hill, hill_grey, paper) + rng.normal(0, 3, (h, w))
    Image.fromarray(np.clip(grey, 0, 255).astype(np.uint8)).save(tmp_path / "hill.png")
    read = _unpadded(load_target_image(tmp_path / "hill.png"), h, w)
    assert (read & hill).sum() >= 0.98 * hill.sum() and (read & ~hill).sum() <= 0.02 * hill.sum()


@pytest.mark.parametrize("fill", [(255, 230, 80), (200, 230, 255), (255, 200, 220)])
def test_a_coloured_sticker_with_an_outline_stays_the_shape(tmp_path, fill):
    """A yellow, pastel or pink box with a dark outline on a transparent canvas (clip art)
    is the shape, not a card whose drawing is its outline (h157)."""
    rgba = np.zeros((300, 300, 4), dtype=np.uint8)
    rgba[90:210, 90:210] = (*fill, 255)
    for edge in (np.s_[90:96, 90:210], np.s_[204:210, 90:210], np.s_[90:210, 90:96], np.s_[90:210, 204:210]):
        rgba[edge] = (20, 20, 20, 255)
    target = load_target_image(_save(rgba, tmp_path / "sticker.png"))
    assert target.mask.sum() == 120 * 120 and not target.notes


@pytest.mark.parametrize("share", [0.25, 0.36, 0.64])
def test_a_white_card_on_a_transparent_canvas_is_named(tmp_path, share):
    """A card with a drawing on it covering 36% of the canvas read as a filled square, with
    no word. Under half the canvas it is still the shape -- a white sticker, button or label
    meant as the shape looks the same, pixel for pixel (h157, h160) -- but a note says so
    and how to read the drawing; over half, the card is a page and its drawing is read."""
    side = 200
    card = int(side * share ** 0.5)
    top = (side - card) // 2
    ink = _drawing(card, card, 4)
    rgba = np.zeros((side, side, 4), dtype=np.uint8)
    rgba[top:top + card, top:top + card, :3] = np.where(ink[..., None], 0, 255)
    rgba[top:top + card, top:top + card, 3] = 255
    Image.fromarray(rgba, "RGBA").save(tmp_path / "card.png")
    target = load_target_image(tmp_path / "card.png")
    named = [note for note in target.notes if "crop the picture to the card" in note]
    if share < 0.5:
        assert target.mask.sum() == card * card and len(named) == 1 and f"covering {card * card / side ** 2:.0%}" \
            in named[0], target.notes
    else:
        assert np.array_equal(target.mask[top:top + card, top:top + card], ink) and target.mask.sum() == ink.sum()
        assert not named


def test_a_dark_rectangle_with_an_outline_under_half_the_canvas_stays_the_shape(tmp_path):
    """Only a light card is a page: a coloured badge with a darker outline is the shape."""
    rgba = np.zeros((200, 200, 4), dtype=np.uint8)
    rgba[60:140, 60:140] = (40, 60, 160, 255)
    rgba[60:63, 60:140] = rgba[137:140, 60:140] = (0, 0, 0, 255)
    read = load_target_image(_save(rgba, tmp_path / "badge.png")).mask
    assert read[60:140, 60:140].all() and read.sum() == 80 * 80


def _save(rgba, path):
    Image.fromarray(rgba, "RGBA").save(path)
    return path


@pytest.mark.parametrize("colour", [0, 255])
def test_a_faint_layer_over_the_whole_canvas_is_not_called_translucent_strokes(tmp_path, colour):
    """Every pixel at alpha 40, the strokes opaque: the mask was right, but the note said
    the faint layer was translucent strokes left out (34 times the shape)."""
    ink = _drawing(200, 200, 5)
    rgba = np.zeros((200, 200, 4), dtype=np.uint8)
    rgba[..., :3] = colour
    rgba[ink, :3] = 0
    rgba[..., 3] = np.where(ink, 255, 40)
    target = load_target_image(_save(rgba, tmp_path / "layer.png"))
    assert np.array_equal(target.mask, ink)
    assert not any("translucent" in note for note in target.notes)


def test_a_faint_stroke_is_still_named(tmp_path):
    """A pressure brush's faint stroke, off the opaque drawing, keeps its note."""
    rgba = np.zeros((200, 200, 4), dtype=np.uint8)
    rgba[20:180, 40:46] = (0, 0, 0, 255)
    rgba[20:180, 140:146] = (0, 0, 0, 60)
    notes = load_target_image(_save(rgba, tmp_path / "brush.png")).notes
    assert any("translucent strokes" in note for note in notes)


def test_pressure_strokes_over_a_faint_layer_are_still_named(tmp_path):
    """A faint layer over the canvas (alpha 40) under an opaque stem and a pressure brush's
    stroke (alpha 110): the stroke, left out of the shape, is named; the layer is not (h157:
    both had gone without a word)."""
    rgba = np.zeros((200, 200, 4), dtype=np.uint8)
    rgba[...] = (255, 255, 255, 40)
    rgba[20:180, 95:101] = (0, 0, 0, 255)
    rgba[30:170, 140:150] = (0, 0, 0, 110)
    notes = load_target_image(_save(rgba, tmp_path / "layer_and_brush.png")).notes
    assert any("translucent strokes" in note and "146% as many pixels" in note for note in notes), notes


@pytest.mark.parametrize("bits", [10, 12, 14])
def test_a_scan_of_fewer_bits_in_a_16_bit_png_is_read(tmp_path, bits):
    """A 12-bit scan stored in a 16-bit PNG (values 0..4095) read as near black and was
    refused with "draw the shape darker"."""
    rng = np.random.default_rng(2)
    ink = _drawing(160, 160, 5)
    white = 2 ** bits - 1
    values = np.where(ink, 0.08 * white, 0.95 * white) + rng.uniform(0, 0.01 * white, ink.shape)
    Image.fromarray(values.astype(np.uint16)).save(tmp_path / "scan.png")
    assert np.array_equal(load_target_image(tmp_path / "scan.png").mask, ink)
