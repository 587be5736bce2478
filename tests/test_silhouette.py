import json
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from procmod.core import InvalidArgumentError, run_forward
from procmod.geometry.camera import Camera
from procmod.geometry.solid import Box, translation
from procmod.models import get_model
from procmod.targets import Silhouette, TargetFileError, load_target_file

SCENES = Path(__file__).resolve().parents[1] / "scenes"
CAM = Camera((0, 0, 20), (0, 0, 0), projection="orthographic", fov=8, width=32, height=32)


def test_s_img_is_the_weighted_sum_of_covered_pixels():
    rng = np.random.default_rng(0)
    weights = rng.normal(size=(32, 32))
    target = Silhouette([(weights, CAM)])
    out = target.new_output(get_model("city"))
    out.add(Box((2, 1, 1)))
    out.add(Box((1, 3, 1), translation(0.5, 0, 0)))
    assert target.score(out) == pytest.approx(weights[out.image(0)].sum())
    assert target.log_likelihood(out) == pytest.approx(target.score(out) / target.temperature)
    with pytest.raises(InvalidArgumentError, match="3D model"):
        target.new_output(get_model("vines"))


@pytest.mark.parametrize("scene", ["spaceship_volume", "spaceship_proxy", "tree_heart", "trees_avoid_cylinder",
                                   "city_skyline", "city_volume"])
def test_stored_scenes_load_and_score(scene):
    target = load_target_file(SCENES / scene / "target.json")
    model = get_model({"spaceship": "spaceship", "tree": "tree", "trees": "tree", "city": "city"}[scene.split("_")[0]])
    d = run_forward(model, np.random.default_rng(1), output=target.new_output(model))
    assert np.isfinite(target.score(d.output))


def test_bad_silhouette_files(tmp_path):
    Image.fromarray(np.full((8, 8), 255, np.uint8)).save(tmp_path / "white.png")
    cam = {"eye": [0, 0, 5], "look_at": [0, 0, 0]}
    cases = [
        ({"format": "procmod-silhouette/1", "views": []}, "non-empty"),
        ({"format": "procmod-silhouette/1", "views": [{"image": "white.png", "camera": cam}]},
         "no pixel is dark enough to hit"),
        ({"format": "procmod-silhouette/1", "views": [{"image": "none.png", "camera": cam}]},
         "views\\[0\\].image: picture file .* does not exist"),
        ({"format": "procmod-silhouette/1", "views": [{"image": "white.png", "camera": {"eye": [0, 0, 0],
                                                                                      "look_at": [0, 0, 0]}}]},
         "coincide"),
        ({"format": "procmod-silhouette/1", "views": [{"camera": cam}]}, "needs \"image\""),
        ({"format": "procmod-silhouette/1", "views": [{"image": "white.png", "weights": "w.npy", "camera": cam}]},
         "gives 'weights' and 'image'; give one of them"),
        ({"format": "procmod-silhouette/1", "views": [{"image": "white.png", "camera": dict(cam, width=8)}]},
         "views\\[0\\].camera.width: a picture's or weights' size is its own"),
        ({"format": "something"}, "format"),
    ]
    for spec, message in cases:
        (tmp_path / "t.json").write_text(json.dumps(spec))
        with pytest.raises(TargetFileError, match=message):
            load_target_file(tmp_path / "t.json")


def test_a_transparent_picture_is_read_as_it_shows_on_a_page(tmp_path):
    """A shape exported as a transparent PNG (drawn in its alpha channel, its transparent
    pixels black) was "hit" over the whole view."""
    rgba = np.zeros((32, 32, 4), dtype=np.uint8)
    rgba[8:24, 12:20, 3] = 255  # the shape: opaque black; the rest: transparent black
    Image.fromarray(rgba).save(tmp_path / "shape.png")
    cam = {"eye": [0, 0, 20], "look_at": [0, 0, 0], "projection": "orthographic", "fov": 8}
    (tmp_path / "target.json").write_text(json.dumps({"format": "procmod-silhouette/1",
                                                      "views": [{"image": "shape.png", "camera": cam}]}))
    weights = load_target_file(tmp_path / "target.json").weights[0]
    assert (weights[8:24, 12:20] > 0).all()
    outside = np.ones((32, 32), dtype=bool)
    outside[8:24, 12:20] = False
    assert (weights[outside] < 0).all()
