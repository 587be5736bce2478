"""The strings results files hold what their scripts wrote, and nothing else: the fields the
scripts write, and a ``command`` that is the run's (its options parse to the recorded
settings). Explanations of a run go in docs/strings.md, not into a results file."""

import importlib.util
import json
import shlex
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "bench" / "results"


def _script(name: str):
    """A bench script as a module (bench/ on the path: the tagger script imports strings.py)."""
    sys.path.insert(0, str(ROOT / "bench"))
    try:
        spec = importlib.util.spec_from_file_location(f"_bench_{name}", ROOT / "bench" / f"{name}.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module
    finally:
        sys.path.remove(str(ROOT / "bench"))


def _options(script, command: str, name: str) -> dict:
    words = shlex.split(command)
    assert words[:2] == ["python", f"bench/{name}.py"], command
    return {k: str(v) if isinstance(v, Path) else v for k, v in vars(script.parser().parse_args(words[2:])).items()}


def _defaults(script) -> dict:
    return {k: str(v) if isinstance(v, Path) else v for k, v in vars(script.parser().parse_args(
        ["--work", "W"] if "strings_tagger" in script.__name__ else [])).items()}


BENCH_FILES = sorted(p.name for p in RESULTS.glob("strings*.json") if not p.name.startswith("strings_tagger_"))
TAGGER_FILES = sorted(p.name for p in RESULTS.glob("strings_tagger_*.json"))

# what bench/strings_tagger.py writes besides bench/strings.py's edge-category figures
TAGGER_FIELDS = {"command", "set", "distinct", "shapes", "train_shapes", "training_strings", "growth_seconds",
                 "tagger", "train_seconds", "history", "categories"}
FIGURE_FIELDS = {"held_out_shapes", "held_out_strings", "per_character_accuracy", "per_character_accuracy_argmax",
                 "per_character_accuracy_without_automorphisms",
                 "per_character_accuracy_argmax_without_automorphisms", "decoding_ms_per_string",
                 "all_characters_accuracy", "voted_edge_accuracy", "voted_edge_accuracy_without_automorphisms",
                 "voted_graphs_all_right", "majority_voted_edge_accuracy", "majority_voted_graphs_all_right"}


@pytest.fixture(scope="module")
def bench():
    return _script("strings")


@pytest.fixture(scope="module")
def tagger_script():
    return _script("strings_tagger")


def test_there_are_results_to_check():
    assert "strings.json" in BENCH_FILES and TAGGER_FILES


@pytest.mark.parametrize("name", BENCH_FILES)
def test_bench_results_hold_what_the_bench_wrote(bench, name):
    data = json.loads((RESULTS / name).read_text())
    assert set(data) <= {"command", "settings", "sets", "seconds"}, set(data) - {"command", "settings", "sets",
                                                                                 "seconds"}
    options, defaults = _options(bench, data["command"], "strings"), _defaults(bench)
    # older runs predate some options: those they lack must be at their defaults
    recorded = dict(data["settings"])
    if "--out" not in data["command"].split():  # the default is the checkout's own folder
        recorded.pop("out", None)
    assert {k: options[k] for k in recorded} == recorded
    assert all(options[k] == defaults[k] for k in set(options) - set(data["settings"]))
    stem = options["results"] or ("strings" if options["distinct"] == "histogram" else f"strings_{options['distinct']}")
    assert name == f"{stem}.json" and set(data["sets"]) == set(options["sets"])


@pytest.mark.parametrize("name", TAGGER_FILES)
def test_tagger_results_hold_what_the_tagger_script_wrote(tagger_script, name):
    data = json.loads((RESULTS / name).read_text())
    assert set(data) <= TAGGER_FIELDS | FIGURE_FIELDS, set(data) - TAGGER_FIELDS - FIGURE_FIELDS
    options = _options(tagger_script, data["command"], "strings_tagger")
    expected_name = f"strings_tagger_{options['set']}_{options['count']}" + (
        "" if options["distinct"] == "histogram" else f"_{options['distinct']}") + ".json"
    assert name == expected_name
    assert data["set"] == options["set"] and data.get("distinct", "histogram") == options["distinct"]
    assert data["shapes"] <= options["count"]
    tagger = data["tagger"]
    assert (tagger["epochs"], tagger["hidden"], tagger["lr_final"], tagger["graph_rounds"]) == (
        options["epochs"], options["hidden"], options["lr_final"], options["graph_rounds"])
    if "dropout" in tagger:
        assert tagger["dropout"] == options["dropout"]
