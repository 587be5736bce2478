"""Sweep 33: user pictures of odd formats and shapes as 2D targets."""

import numpy as np

from procmod.targets import ShapeMatch
from procmod.targets.image import TargetImage


def test_display_mask_of_a_shape_thin_at_the_report_size_does_not_refuse():
    # a thin band (a 3x3000 strip's, padded to a square) survives the model's 50x50 canvas
    # but not the report's 128-pixel tiles: the report had failed after the run with a
    # TargetFileError about "the model's 128x128 canvas"
    mask = np.zeros((1500, 1500), dtype=bool)
    mask[749, 500:600] = True
    target = ShapeMatch(TargetImage("strip.png", mask))
    assert target.image.at_size(50, 50).any()  # what the run scores against
    tile = target.display_mask(128)
    assert tile.shape == (128, 128) and tile.dtype == bool


def test_a_real_valued_picture_with_a_few_highlights_past_1_is_read_as_0_to_1(tmp_path):
    # one pixel at 1.02 in a 0..1 float TIFF had switched its scale to 0..255: the drawing
    # read as black on black and the file was refused as empty ("draw the shape darker")
    from PIL import Image

    from procmod.targets.image import mask_from_image, open_image

    ink = np.zeros((40, 60), dtype=bool)
    ink[15:25, 10:50] = True
    real = np.where(ink, 0.1, 0.9).astype(np.float32)
    real[0, 0] = 1.02
    Image.fromarray(real, mode="F").save(tmp_path / "render.tif")
    mask = mask_from_image(open_image(tmp_path / "render.tif"))
    assert mask.sum() == ink.sum()


def test_a_sidecar_given_as_the_target_names_its_picture(tmp_path, capsys):
    # `--target drawing.json` (the sidecar, not the picture) was told it needs a 3D target's
    # "format", sending the user of a 2D picture to the volume and silhouette targets
    from PIL import Image

    from procmod.cli import main

    Image.new("L", (40, 40), 255).save(tmp_path / "drawing.jpg")
    (tmp_path / "drawing.json").write_text('{"start": [0.5, 0.9], "direction": [0, -1]}')
    assert main(["infer", "vines", "--target", str(tmp_path / "drawing.json"), "--particles", "2",
                 "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "sidecar" in err and "drawing.jpg" in err and "format" not in err
    assert not (tmp_path / "run").exists()


def test_a_sidecar_coordinate_of_true_or_false_is_refused(tmp_path):
    # {"start": [true, 0.5]} was read as start (1.0, 0.5) without a word (--param start refuses it)
    import pytest
    from PIL import Image

    from procmod.targets import load_target_image
    from procmod.targets.image import TargetFileError

    picture = np.full((40, 40), 255, dtype=np.uint8)
    picture[10:35, 18:22] = 0
    Image.fromarray(picture).save(tmp_path / "stem.png")
    for text in ('{"start": [true, 0.5]}', '{"direction": [0, false]}'):
        (tmp_path / "stem.json").write_text(text)
        with pytest.raises(TargetFileError, match="two finite numbers"):
            load_target_image(tmp_path / "stem.png")


def test_a_label_mask_of_0_and_1_is_read_as_its_shape(tmp_path):
    # a segmentation mask saved as is (numpy's 0/1 as an 8-bit or 16-bit PNG, a 32-bit TIFF)
    # was refused as empty, "draw the shape darker": its 1s are 1 grey level from its 0s
    from PIL import Image

    from procmod.targets import load_target_image

    ink = np.zeros((40, 40), dtype=bool)
    ink[8:36, 18:24] = True
    Image.fromarray(ink.astype(np.uint8)).save(tmp_path / "mask.png")
    Image.fromarray(ink.astype(np.uint16)).save(tmp_path / "mask16.png")
    Image.fromarray(ink.astype(np.int32), mode="I").save(tmp_path / "mask.tif")
    for name in ("mask.png", "mask16.png", "mask.tif"):
        assert np.array_equal(load_target_image(tmp_path / name).mask, ink), name


def test_a_utf16_sidecar_from_windows_powershell_is_read(tmp_path):
    # PowerShell's `>` writes UTF-16 with its byte-order mark: the sidecar had been refused
    # as "not UTF-8 text: a picture or another binary file?"
    from PIL import Image

    from procmod.targets import load_target_image

    picture = np.full((40, 40), 255, dtype=np.uint8)
    picture[10:35, 18:22] = 0
    Image.fromarray(picture).save(tmp_path / "stem.png")
    text = '{"start": [0.5, 0.25], "direction": [1, 0]}\r\n'
    for encoding in ("utf-16", "utf-16-be", "utf-32"):
        data = text.encode(encoding)
        if encoding == "utf-16-be":
            data = b"\xfe\xff" + data
        (tmp_path / "stem.json").write_bytes(data)
        target = load_target_image(tmp_path / "stem.png")
        assert target.start == (0.5, 0.25) and target.direction == (1.0, 0.0), encoding


def test_a_phone_jpeg_with_an_mp_format_preview_gets_no_frames_note(tmp_path):
    # Pillow opens a JPEG with MP Format images (a phone's preview or HDR gain map) as MPO of
    # several frames: every such photo was told to save the frame with the drawing on its own
    from PIL import Image

    from procmod.targets import load_target_image

    picture = np.full((60, 60, 3), 255, dtype=np.uint8)
    picture[10:55, 26:34] = 0
    photo = Image.fromarray(picture)
    Image.init()  # (the MPO writer: a .jpg name alone imports the JPEG plugin only)
    photo.save(tmp_path / "photo.jpg", format="MPO", save_all=True, append_images=[photo.resize((20, 20))])
    with Image.open(tmp_path / "photo.jpg") as opened:
        assert opened.format == "MPO" and opened.n_frames == 2
    target = load_target_image(tmp_path / "photo.jpg")
    assert target.mask.any() and not any("frames" in note for note in target.notes)


def test_a_bright_thin_drawing_on_a_dark_0_to_1_ground_of_a_0_to_255_float_picture(tmp_path):
    # a 0..255 float picture whose bright line covers under 1% (0.6%) on a ground of 0..1
    # noise had been read as a 0..1 picture with highlights: the noise filled 0..255 and the
    # mask was empty, or the ground itself (review h171)
    from PIL import Image

    from procmod.targets import load_target_image

    rng = np.random.default_rng(1)
    ink = np.zeros((100, 100), dtype=bool)
    ink[20:80, 50] = True
    for ground in (rng.random((100, 100)), np.round(rng.random((100, 100)))):
        picture = np.where(ink, 200.0, ground).astype(np.float32)
        Image.fromarray(picture, mode="F").save(tmp_path / "line.tif")
        mask = load_target_image(tmp_path / "line.tif").mask
        assert mask.sum() == ink.sum() and (mask & ink).sum() == ink.sum()


def test_a_label_mask_as_a_silhouette_view_hits_its_1s(tmp_path):
    # 1 the object, 0 the rest: read as white on black, the object was to be avoided and the
    # rest hit, without a word (review h171); a silhouette view's dark pixels are its hits
    import json

    from PIL import Image

    from procmod.targets.files import load_target_file

    labels = np.zeros((60, 80), dtype=np.uint8)
    labels[15:45, 30:50] = 1
    Image.fromarray(labels).save(tmp_path / "mask.png")
    camera = {"eye": [0, 0, 10], "look_at": [0, 0, 0], "projection": "orthographic", "fov": 4}
    (tmp_path / "t.json").write_text(json.dumps({"format": "procmod-silhouette/1",
                                                 "views": [{"image": "mask.png", "camera": camera}]}))
    weights = np.asarray(load_target_file(tmp_path / "t.json").weights[0])
    shape = labels.astype(bool)
    assert (weights[shape] > 0).all() and (weights[~shape] < 0).all()


def test_a_json_file_with_cr_line_ends_says_the_right_line(tmp_path):
    # read as bytes (for UTF-16's mark), a CR-only file's lines were one: "at line 1" for an
    # error on line 4 (review h171)
    import pytest

    from procmod.core.io import read_json

    (tmp_path / "cr.json").write_bytes(b'{\r  "a": 1,\r  "b": 2\r  "c": 3\r}\r')
    with pytest.raises(Exception, match="at line 4"):
        read_json(tmp_path / "cr.json")


def test_a_0_to_1_render_with_a_glint_past_2_is_still_read_as_0_to_1(tmp_path):
    # one specular pixel at 2.5 (or 12) in a 0..1 float render: a cap at 2 on highlights had
    # read the whole picture as 0..255, all black, and refused it as empty (review h175)
    from PIL import Image

    from procmod.targets.image import mask_from_image, open_image

    ink = np.zeros((60, 60), dtype=bool)
    ink[20:40, 10:50] = True
    for glint in (2.5, 12.0):
        real = np.where(ink, 0.1, 0.9).astype(np.float32)
        real[0, 0] = glint
        Image.fromarray(real, mode="F").save(tmp_path / "render.tif")
        assert mask_from_image(open_image(tmp_path / "render.tif")).sum() == ink.sum()


def test_a_piped_non_picture_is_named_by_its_path(tmp_path):
    # Pillow names what it opened: a pipe read into memory was "<_io.BytesIO object at 0x...>"
    # in the one line (review h175)
    import os
    import subprocess
    import sys
    from pathlib import Path

    run = subprocess.run([sys.executable, "-m", "procmod", "infer", "chain", "--target", "/dev/stdin",
                          "--out", str(tmp_path / "run")], input=b"some notes, not a picture\n",
                         capture_output=True, timeout=120,
                         env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])})
    err = run.stderr.decode()
    assert run.returncode == 2 and len(err.strip().splitlines()) == 1, err
    assert "BytesIO" not in err and "/dev/stdin" in err
