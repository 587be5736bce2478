"""Steer the spaceship model into a target volume with the genetic algorithm, from Python.

Run: python examples/steer_spaceship.py OUT_DIR
"""

import sys
from pathlib import Path

from procmod.infer import Budget, ga
from procmod.models import get_model
from procmod.report import write_run
from procmod.targets import load_target_file

ROOT = Path(__file__).resolve().parents[1]

target = load_target_file(ROOT / "scenes" / "spaceship_volume" / "target.json")
result = ga(get_model("spaceship"), target, population=150, budget=Budget(seconds=10), seed=0)
print(f"best s_vol {result.best_score:.0f} of {target.best_attainable:.0f} attainable, "
      f"{result.evaluations} evaluations in {result.seconds:.1f} s")
report = write_run(result, target, Path(sys.argv[1] if len(sys.argv) > 1 else "spaceship-run"), size=400)
print(f"report: {report}")
