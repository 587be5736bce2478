import runpy
from pathlib import Path

import numpy as np

from procmod import run_forward

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def test_custom_model_example_runs(tmp_path):
    namespace = runpy.run_path(str(EXAMPLES / "custom_model.py"))
    d = run_forward(namespace["model"], np.random.default_rng(0))
    assert d.done and d.n_emits == d.n_nodes >= 1


def test_steer_spaceship_example_runs(tmp_path, monkeypatch):
    import procmod.infer
    from procmod.infer import Budget

    real_ga = procmod.infer.ga

    def short_ga(*args, **kwargs):  # the example runs 10 s; the test only needs it to work
        kwargs.update(population=8, budget=Budget(generations=2))
        return real_ga(*args, **kwargs)

    monkeypatch.setattr(procmod.infer, "ga", short_ga)
    monkeypatch.setattr("sys.argv", ["steer_spaceship.py", str(tmp_path / "run")])
    runpy.run_path(str(EXAMPLES / "steer_spaceship.py"), run_name="__main__")
    assert (tmp_path / "run" / "best.glb").exists() and (tmp_path / "run" / "report.html").exists()
