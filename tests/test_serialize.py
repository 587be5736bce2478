import dataclasses
import json

import numpy as np
import pytest

from procmod.core import (DerivationFormatError, UnknownModelError, derivation_from_dict, derivation_to_dict,
                          load_derivation, random_order, run_forward, save_derivation, start, step)
from procmod.models import get_model


@pytest.mark.parametrize("name", ["chain", "vines", "lightning"])
def test_save_load_replays_exactly(tmp_path, name):
    model = get_model(name)
    for seed in range(5):
        d = run_forward(model, np.random.default_rng(seed))
        path = tmp_path / f"{seed}.json"
        save_derivation(d, path)
        loaded = load_derivation(path, get_model)
        assert loaded.choice_map() == d.choice_map()
        assert loaded.geometry() == d.geometry()
        assert loaded.log_prior == d.log_prior
        assert np.array_equal(loaded.output.pixels, d.output.pixels)


def test_save_load_keeps_a_random_expansion_order(tmp_path):
    model = get_model("lightning")
    rng = np.random.default_rng(8)
    state = start(model)
    while step(state, rng, random_order):
        pass
    save_derivation(state, tmp_path / "d.json")
    loaded = load_derivation(tmp_path / "d.json", get_model)
    assert loaded.order() == state.order()
    assert loaded.geometry() == state.geometry()


def test_params_are_saved(tmp_path):
    model = get_model("vines").configure(start=[0.2, 0.5], direction=[1, 0])
    d = run_forward(model, np.random.default_rng(0))
    save_derivation(d, tmp_path / "d.json")
    loaded = load_derivation(tmp_path / "d.json", get_model)
    assert loaded.model.params["start"] == [0.2, 0.5]
    assert loaded.geometry() == d.geometry()


def _saved(tmp_path):
    d = run_forward(get_model("vines"), np.random.default_rng(1))
    return derivation_to_dict(d)


def _refused(tmp_path, data: dict, message: str) -> None:
    """Loading ``data`` from a file is refused with ``message``."""
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(data))
    with pytest.raises(DerivationFormatError, match=message):
        load_derivation(path, get_model)


def _as_format_1(data: dict) -> dict:
    """A format-2 dict as procmod wrote it before format 2: every call and choice by its
    whole address."""
    addresses = []
    for parent, site in data["calls"]:
        addresses.append([] if parent is None else addresses[parent] + [site])
    old = {key: value for key, value in data.items() if key not in ("calls", "choices")}
    return {**old, "format": "procmod-derivation/1", "order": addresses,
            "choices": [[addresses[call], name, value] for call, name, value in data["choices"]]}


def _saved_1(tmp_path):
    return _as_format_1(_saved(tmp_path))


@pytest.mark.parametrize("mutate,message", [
    (lambda d: d.update(format="procmod-derivation/99"), "format"),
    (lambda d: d.update(model=5), "model"),
    (lambda d: d.pop("choices"), "choices"),
    (lambda d: d.pop("calls"), "calls"),
    (lambda d: d["choices"].append([0, "bogus", 1.0]), "does not replay"),
    (lambda d: d["choices"].pop(0), "does not replay"),
    # a deleted choice is named, with where to put it back
    (lambda d: [d.pop("log_prior"), d["choices"].pop(1)],
     r"a choice the model makes is missing: the first, 'leaf' at calls\[0\], is not in its choices; add it as "
     r"\[0, \"leaf\", VALUE\]"),
    (lambda d: d["choices"].__setitem__(0, ["x", 1]), r"choices\[0\] must be \[call, name, value\]"),
    (lambda d: d["choices"].__setitem__(0, [len(d["calls"]), "angle", 0.1]), r"choices\[0\] must be"),
    (lambda d: d["choices"].__setitem__(0, [True, "angle", 0.1]), r"choices\[0\] must be"),
    (lambda d: d.update(log_prior=d["log_prior"] + 1.0), "its choices were edited, or the model has changed"),
    (lambda d: d["choices"].insert(0, [d["choices"][0][0], d["choices"][0][1], 0.5]),
     r"choices\[1\] gives choice 'angle' at calls\[0\] again \(choices\[0\] gave it first\)"),
    (lambda d: [d.pop("log_prior"), d["choices"][4].__setitem__(2, 5)],
     r"choices\[4\], 'terminate' at calls\[0\] = 5, is a value its distribution there cannot take"),
    (lambda d: d["choices"][1].__setitem__(2, "sideways"),
     r"choices\[1\], 'leaf' at calls\[0\] = \"sideways\", is a value its distribution there cannot take"),
    (lambda d: d.update(params={"colour": "red"}), "no parameter"),
])
def test_malformed_derivations_are_rejected(tmp_path, mutate, message):
    data = _saved(tmp_path)
    assert data["format"] == "procmod-derivation/2"
    mutate(data)
    _refused(tmp_path, data, message)


@pytest.mark.parametrize("mutate,message", [
    (lambda d: d["calls"].__setitem__(0, [0, "branch"]), r"calls\[0\] must be the root call"),
    (lambda d: d["calls"].clear(), r"'calls' is empty"),
    (lambda d: d["calls"].__setitem__(1, [1, "branch"]), r"calls\[1\] names calls\[1\] as the call that spawned "
                                                         "it, which does not come before it"),
    (lambda d: d["calls"].__setitem__(1, [-1, "branch"]), r"calls\[1\] names calls\[-1\] .* which is no call"),
    (lambda d: d["calls"].__setitem__(1, ["0", "branch"]), r"calls\[1\] must be"),
    (lambda d: d["calls"].append(d["calls"][-1]), r"calls\[\d+\] is listed twice"),
    # a chain of calls 30,000 deep (a 0.5 MB file): its addresses took 3.7 GB and 13 s before
    # the refusal (h113)
    (lambda d: d["calls"].extend([i, "branch"] for i in range(len(d["calls"]) - 1, len(d["calls"]) + 29_999)),
     r"its [\d,]+ calls nest up to [\d,]+ deep, but its model allows 100,000 calls at most 10,000 deep"),
])
def test_malformed_calls_are_rejected(tmp_path, mutate, message):
    d = next(d for d in (run_forward(get_model("vines"), np.random.default_rng(seed)) for seed in range(50))
             if d.n_nodes >= 3)
    data = derivation_to_dict(d)
    mutate(data)
    _refused(tmp_path, data, message)


def test_deeply_nested_calls_are_checked_against_the_models_limits(tmp_path, monkeypatch):
    """Deep files are held to their model's max_depth and max_calls before any address is
    built; a file the model made within them still loads (a first check refused a stem
    9,000 deep with a leaf a level, which procmod itself had saved; h117)."""
    import procmod.core.serialize as serialize

    model = get_model("vines")
    d = max((run_forward(model, np.random.default_rng(seed)) for seed in range(30)), key=lambda d: d.n_nodes)
    data = derivation_to_dict(d)
    levels = sum(len(address) for address in d.order())
    monkeypatch.setattr(serialize, "MAX_ADDRESS_PARTS", levels - 1)  # as deep as a file past the check
    assert derivation_from_dict(data, get_model).order() == d.order()
    shallow = dataclasses.replace(model, max_depth=max(len(a) for a in d.order()) - 1)
    with pytest.raises(DerivationFormatError, match=r"but its model allows [\d,]+ calls at most \d+ deep"):
        derivation_from_dict(data, shallow)


def test_format_1_files_are_still_read(tmp_path):
    for seed in range(5):
        d = run_forward(get_model("vines"), np.random.default_rng(seed))
        (tmp_path / "d.json").write_text(json.dumps(_as_format_1(derivation_to_dict(d))))
        loaded = load_derivation(tmp_path / "d.json", get_model)
        assert loaded.order() == d.order() and loaded.geometry() == d.geometry()
        assert loaded.log_prior == d.log_prior


def test_a_deep_chain_is_written_in_space_linear_in_its_depth(tmp_path):
    """Format 1 named every call by its whole address: a chain 5,000 calls deep wrote
    200 MB (n^2 / 2 site names); format 2 names each call once."""
    from procmod.core import Model, Normal

    def link(ctx, n):
        ctx.sample("a", Normal(0.0, 1.0))
        ctx.emit(None)
        if n > 0:
            ctx.spawn("next", link, n - 1)

    sizes = {}
    for depth in (200, 800):
        model = Model(f"chain{depth}", "", link, root_args=lambda p, n=depth: (n,), new_output_from=lambda p: _Sink())
        d = run_forward(model, np.random.default_rng(0))
        save_derivation(d, tmp_path / f"{depth}.json")
        sizes[depth] = (tmp_path / f"{depth}.json").stat().st_size
        loaded = load_derivation(tmp_path / f"{depth}.json", lambda name, m=model: m)
        assert loaded.order() == d.order() and loaded.choice_map() == d.choice_map()
    assert sizes[800] < 5 * sizes[200]  # linear: 4x; format 1 wrote ~14x


class _Sink:
    """An output that takes any emit and draws nothing."""

    dimension = 0

    def add(self, value):
        pass

    def copy(self):
        return _Sink()


@pytest.mark.parametrize("mutate,message", [
    (lambda d: d.update(format="procmod-derivation/99"), "format"),
    (lambda d: d.update(model=5), "model"),
    (lambda d: d.pop("choices"), "choices"),
    (lambda d: d["choices"].append([[], "bogus", 1.0]), "does not replay"),
    (lambda d: d["choices"].pop(0), "does not replay"),
    # a deleted choice is named, with where to put it back ("choices were missing" before)
    (lambda d: [d.pop("log_prior"), d["choices"].pop(1)],
     r"a choice the model makes is missing: the first, 'leaf' at \[\], is not in its choices; add it as "
     r"\[\[\], \"leaf\", VALUE\]"),
    (lambda d: d["choices"].__setitem__(0, ["x", 1]), r"choices\[0\]"),
    (lambda d: d.update(log_prior=d["log_prior"] + 1.0), "its choices were edited, or the model has changed"),
    # a choice given twice: one silently won over the other
    (lambda d: d["choices"].insert(0, [d["choices"][0][0], d["choices"][0][1], 0.5]),
     r"choices\[1\] gives choice 'angle' at \[\] again \(choices\[0\] gave it first\)"),
    # a coin stored as 5: named, though its fresh draw may send the replay to calls whose
    # choices the file lacks
    (lambda d: [d.pop("log_prior"), d["choices"][4].__setitem__(2, 5)],
     r"choices\[4\], 'terminate' at \[\] = 5, is a value its distribution there cannot take"),
    # a value the distribution cannot take: the message names the choice
    (lambda d: d["choices"][1].__setitem__(2, "sideways"),
     r"choices\[1\], 'leaf' at \[\] = \"sideways\", is a value its distribution there cannot take"),
    (lambda d: d.update(params={"colour": "red"}), "no parameter"),
    # an edited order: its calls are named, not the choices it left unused
    (lambda d: d.update(order=[["branch"]] + d["order"]), r"order\[0\] \[\"branch\"\] comes before the call that "
                                                          "spawns it"),
    (lambda d: d["order"].append(d["order"][-1]), r"order\[\d+\] .* is listed twice"),
])
def test_malformed_format_1_derivations_are_rejected(tmp_path, mutate, message):
    data = _saved_1(tmp_path)
    mutate(data)
    _refused(tmp_path, data, message)


def test_unreadable_files_are_rejected(tmp_path):
    with pytest.raises(DerivationFormatError, match="missing.json does not exist"):
        load_derivation(tmp_path / "missing.json", get_model)
    (tmp_path / "bad.json").write_text("{not json")
    with pytest.raises(DerivationFormatError, match="not valid JSON"):
        load_derivation(tmp_path / "bad.json", get_model)
    (tmp_path / "list.json").write_text("[1, 2]")
    with pytest.raises(DerivationFormatError, match="JSON object"):
        load_derivation(tmp_path / "list.json", get_model)
    data = _saved(tmp_path)
    data["model"] = "teapot"
    (tmp_path / "unknown.json").write_text(json.dumps(data))
    with pytest.raises(UnknownModelError):
        load_derivation(tmp_path / "unknown.json", get_model)


def test_partial_derivations_cannot_be_saved(tmp_path):
    state = start(get_model("vines"))
    step(state, np.random.default_rng(0))
    with pytest.raises(DerivationFormatError, match="complete"):
        save_derivation(state, tmp_path / "p.json")
    assert not (tmp_path / "p.json").exists()


def test_a_model_of_ones_own_named_like_a_file_reaches_its_resolver_unchanged(tmp_path):
    """Only a learned program's program.json is named relative to the derivation file; a
    model of one's own called "chain.json" was looked up as a path beside the file."""
    from dataclasses import replace
    model = replace(get_model("chain"), name="chain.json")
    d = run_forward(model, np.random.default_rng(2))
    save_derivation(d, tmp_path / "d.json")
    asked = []
    loaded = load_derivation(tmp_path / "d.json", lambda name: asked.append(name) or model)
    assert asked == ["chain.json"] and loaded.geometry() == d.geometry()


def test_a_deleted_maybe_coin_is_named_not_the_choices_it_leaves_unused(tmp_path):
    chain = get_model("chain")
    made = next(d for d in (run_forward(chain, np.random.default_rng(seed)) for seed in range(50)) if d.n_nodes >= 4)
    data = derivation_to_dict(made)
    data.pop("log_prior")
    data["choices"] = [c for c in data["choices"] if c[:2] != [0, "next"]]
    (tmp_path / "d.json").write_text(json.dumps(data))
    with pytest.raises(DerivationFormatError, match=r"a choice the model makes is missing: the first, 'next' at "
                                                      r"calls\[0\], is not in its choices"):
        load_derivation(tmp_path / "d.json", get_model)
