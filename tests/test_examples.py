import runpy
from pathlib import Path

import numpy as np

from procmod import run_forward

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def test_custom_model_example_runs(tmp_path):
    namespace = runpy.run_path(str(EXAMPLES / "custom_model.py"))
    d = run_forward(namespace["model"], np.random.default_rng(0))
    assert d.done and d.n_emits == d.n_nodes >= 1
