"""The report's contact sheet is a fixed-size sample of the final particles, drawn by weight."""

import math
from types import SimpleNamespace

from procmod.report import SAMPLE_TILES, sample_of_final


def _result(n, log_weights, engine="smc"):
    return SimpleNamespace(samples=[f"particle {i}" for i in range(n)], log_weights=log_weights, engine=engine)


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


def test_a_ga_population_or_mcmc_chains_are_shown_first_not_drawn_by_their_scores():
    """GA and MCMC give their states' log-likelihoods as log_weights: drawn by them, the
    report of a GA population of 200 showed one or two individuals (h75)."""
    peaked = [0.0] + [-50.0] * 199
    for engine in ("ga", "mcmc"):
        assert sample_of_final(_result(200, peaked, engine)) == [f"particle {i}" for i in range(SAMPLE_TILES)]
    assert sample_of_final(_result(200, peaked, "smc")) == ["particle 0"]  # importance weights: by weight


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


def test_settings_json_is_standard_json_when_log_z_is_minus_infinity(tmp_path):
    # Python wrote -Infinity: JavaScript's JSON.parse failed on the file and jq read -1.8e308
    import json

    import numpy as np

    from procmod.core.io import standard_json
    from procmod.data import glyph_target
    from procmod.infer import smc
    from procmod.models import get_model
    from procmod.report import write_run
    from procmod.targets import ShapeMatch

    result = smc(get_model("vines"), ShapeMatch(glyph_target("a")), particles=3, seed=0)
    result.log_marginal_likelihood = -math.inf
    write_run(result, ShapeMatch(glyph_target("a")), tmp_path / "run", size=64)

    def refuse(constant):
        raise ValueError(f"not JSON: {constant}")

    settings = json.loads((tmp_path / "run" / "settings.json").read_text(), parse_constant=refuse)
    assert settings["log_marginal_likelihood"] is None
    assert "<td>-inf</td>" in (tmp_path / "run" / "report.html").read_text()  # the page says what it was
    assert standard_json({"a": [np.float64("nan"), (1, np.inf)], "b": np.int64(3), "c": "x"}) == \
        {"a": [None, [1, None]], "b": 3, "c": "x"}
