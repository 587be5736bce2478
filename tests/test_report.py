"""The report's contact sheet is a fixed-size sample of the final particles, drawn by weight."""

import math
from types import SimpleNamespace

from procmod.report import SAMPLE_TILES, sample_of_final


def _result(n, log_weights):
    return SimpleNamespace(samples=[f"particle {i}" for i in range(n)], log_weights=log_weights)


def test_the_sample_does_not_grow_with_the_particles():
    for n in (1, 10, 600, 5000):
        chosen = sample_of_final(_result(n, [0.0] * n))
        assert len(chosen) == min(n, SAMPLE_TILES)
        assert len(set(chosen)) == len(chosen)


def test_the_sample_follows_the_weights():
    weights = [-math.inf] * 600
    weights[123] = 0.0
    weights[400] = math.log(3.0)  # three quarters of the mass
    chosen = sample_of_final(_result(600, weights))
    assert chosen == ["particle 123", "particle 400"]


def test_without_weights_the_first_samples_are_shown():
    assert sample_of_final(_result(100, None)) == [f"particle {i}" for i in range(SAMPLE_TILES)]
    assert sample_of_final(_result(100, [-math.inf] * 100)) == [f"particle {i}" for i in range(SAMPLE_TILES)]


def test_copies_share_one_picture_and_every_picture_is_the_one_drawn_alone():
    import numpy as np

    from procmod.core import run_forward
    from procmod.models import get_model
    from procmod.render import derivation_image, derivation_images

    model = get_model("vines")
    outputs = [run_forward(model, np.random.default_rng(seed)) for seed in (1, 2)]
    assert outputs[0].geometry() != outputs[1].geometry()
    derivations = [outputs[0], outputs[0].copy(), outputs[1], outputs[0].copy()]
    images = derivation_images(derivations, 64, supersample=2)
    assert images[0] is images[1] is images[3]  # copies of one particle: drawn once
    assert images[2] is not images[0]
    for derivation, image in zip(derivations, images):
        assert image.tobytes() == derivation_image(derivation, 64, supersample=2).tobytes()
