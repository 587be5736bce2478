"""Save and load derivations as versioned JSON.

Format ``procmod-derivation/2``::

    {"format": "procmod-derivation/2",
     "model": "vines", "params": {...},
     "log_prior": -12.3,
     "calls": [[null, null], [0, "branch1"], ...],   # in the order they ran: [the call that
                                                     #   spawned it (its index here), spawn site]
     "choices": [[1, "angle", 0.12], ...]}           # call (its index in "calls"), name, value

Loading replays the model under the stored choices in the stored order, so the loaded
derivation is the saved one exactly (same tree, same geometry, same log-prior); a file
that does not replay without fresh or left-over choices is rejected.

``procmod-derivation/1`` files are still read. They named every call and choice by its
whole address (``"order": [[], ["branch1"], ...]``, ``"choices": [[["branch1"], "angle",
0.12], ...]``), so a chain of n calls wrote n^2 / 2 site names: 200 MB for a chain 5,000
calls deep, which took 1.1 GB to write. Format 2 names each call once, by its spawner.
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Callable

import numpy as np

from .errors import DerivationFormatError, InvalidArgumentError, ProcmodError, cut_text
# The file recipes live in .io; these names are kept here for the modules that import them
# from serialize.
from .io import check_format, fingerprint, parse_json, read_json, write_text_atomic  # noqa: F401
from .limits import check_memory
from .model import Model
from .runtime import Derivation, replay, rule_function

FORMAT = "procmod-derivation/2"
FORMAT_1 = "procmod-derivation/1"  # read, no longer written (see the module docstring)


def _json_value(value):
    if isinstance(value, (bool, int, float, str)):
        return value
    if isinstance(value, np.generic):
        return value.item()
    raise DerivationFormatError(f"choice value {value!r} of type {type(value).__name__} cannot be saved as JSON")


def derivation_to_dict(derivation: Derivation) -> dict:
    """The JSON-ready dict of a complete derivation."""
    if not derivation.done:
        raise DerivationFormatError("only complete derivations can be saved; run it to the end first")
    nodes = derivation.nodes()
    position = {}  # address -> index in "calls" (a call runs after the call that spawned it)
    calls = []
    for i, node in enumerate(nodes):
        address = node.address
        position[address] = i
        calls.append([position[address[:-1]], address[-1]] if address else [None, None])
    return {
        "format": FORMAT,
        "model": derivation.model.name,
        "root": root_rule_id(derivation.model),
        "params": dict(derivation.model.params),
        "log_prior": float(derivation.log_prior),  # a model's numpy densities sum to a numpy float
        "calls": calls,
        "choices": [[i, _json_name(node, name), _json_value(choice.value)]
                    for i, node in enumerate(nodes) for name, choice in node.choices.items()],
    }


def root_rule_id(model: Model) -> str:
    """``module:qualname`` of a model's root rule: which model a saved derivation came
    from, beyond its name (a user's model may be named like a built-in one)."""
    root = rule_function(model.root)
    return f"{getattr(root, '__module__', None) or '?'}:{getattr(root, '__qualname__', None) or type(root).__name__}"


def _same_root(stored: str, model: Model) -> bool:
    """Whether a derivation file's ``root`` can be ``model``'s root rule: the same rule
    (qualified name), in a module of any name where neither is procmod's own. A user's
    module may be imported under other names (``__main__`` when run as a script,
    ``pkg.mymodels`` or ``mymodels``, a ``procmod_user_...`` module when the command line
    runs ``FILE.py:NAME``); a procmod model's rule is only ever its own (a user's model
    named like a built-in one is another model)."""
    here = root_rule_id(model)
    (module, _, name), (here_module, _, here_name) = stored.partition(":"), here.partition(":")
    if stored == here:
        return True
    return name == here_name and not any(m.startswith("procmod.") for m in (module, here_module))


def _json_name(node, name):
    if isinstance(name, str):
        return name
    from .runtime import rule_name
    raise DerivationFormatError(f"rule {rule_name(node.rule)!r} names a choice {name!r} ({type(name).__name__}); "
                                "choice names must be strings (they are saved as JSON)")


def derivation_json(data: dict) -> str:
    """A derivation's dict as JSON text, one field per line and one call or choice per line
    of its lists: as readable as an indented file and written by json's C encoder (an
    indented dump goes through the pure-Python one, ~40 ms for a vine of 100 segments,
    which made the run report's cost grow with the output)."""
    lines = []
    for key, value in data.items():
        if isinstance(value, list) and value:
            items = ",\n  ".join(json.dumps(item) for item in value)
            lines.append(f"{json.dumps(key)}: [\n  {items}\n ]")
        else:
            lines.append(f"{json.dumps(key)}: {json.dumps(value)}")
    return "{\n " + ",\n ".join(lines) + "\n}\n"


def save_derivation(derivation: Derivation, path: str | os.PathLike) -> None:
    """Write a complete derivation to ``path`` as ``procmod-derivation/2`` JSON."""
    if not isinstance(derivation, Derivation):
        raise InvalidArgumentError(f"derivation must be a procmod Derivation, got {type(derivation).__name__}")
    if not isinstance(path, (str, os.PathLike)):
        raise InvalidArgumentError(f"path must be a str or pathlib.Path, got {type(path).__name__}")
    data = derivation_to_dict(derivation)
    data["model"] = program_reference(data["model"], Path(path).parent)
    text = derivation_json(data)
    try:
        write_text_atomic(path, text)
    except OSError as exc:  # no such folder, a folder of that name, no permission
        raise InvalidArgumentError(f"cannot write the derivation to {cut_text(str(path))}: "
                                   f"{getattr(exc, 'strerror', None) or exc}") from None


def _names_program(name: str) -> bool:
    """Whether a derivation's model name is a learned program's ``program.json`` (its
    path) rather than a model's name."""
    return name.lower().endswith(".json")


def program_reference(name: str, folder: Path) -> str:
    """A learned program's model name (the absolute path of its ``program.json``) written
    relative to the derivation's ``folder``, as every file procmod writes names another
    (README, "Files that name other files"): a run folder and the program it sampled
    keep working when they are moved together. Other names are kept."""
    if not (_names_program(name) and os.path.isabs(name)):
        return name
    try:
        # from the folder's real path: the program's is resolved, and '..' climbs the real tree
        return Path(os.path.relpath(name, os.path.realpath(folder))).as_posix()
    except ValueError:  # on another drive (Windows): only the absolute path reaches it
        return name


def _program_files(path: str) -> tuple:
    """The bytes of a learned program's ``program.json`` and of the tensors file it names."""
    data = Path(path).read_bytes()
    tensors = json.loads(data).get("tensors", "program.pt")
    return data, (Path(path).parent / str(tensors)).read_bytes()


def other_program(named: str, given: str) -> bool:
    """Whether a derivation that names the learned program ``named`` (its resolved path)
    is given another program, ``given`` (a model's name): both name programs, the named
    one exists, and it is neither the given file nor a copy of it (the same program.json
    and tensors). A derivation whose program was moved or deleted is the user's to pair
    with a program, as before; one whose program is there was drawn by that program, and
    another of the same parts had replayed it under the wrong program, or failed with
    'does not replay' and no word of the program the file names."""
    if not (_names_program(named) and _names_program(given) and os.path.isfile(named)):
        return False
    if os.path.realpath(named) == os.path.realpath(given):
        return False
    try:
        named_files = _program_files(named)
    except (OSError, ValueError, AttributeError):  # its tensors gone: a program no longer there
        return False
    try:
        return named_files != _program_files(given)
    except (OSError, ValueError, AttributeError):  # unreadable or not JSON: not that program
        return True


def _fail(source: str, problem: str) -> DerivationFormatError:
    return DerivationFormatError(f"{source}: {problem}")


MAX_ADDRESS_PARTS = 50_005_000
"""Levels of nesting summed over a derivation file's calls above which its model's limits
are checked before any address is built: each call's address holds the spawn sites of
every call above it, so a chain of calls costs memory and time growing with the square of
its length (a 0.5 MB file of one chain 30,000 deep took 3.7 GB and 13 s before it was
refused; h113). A chain 10,000 deep (``Model.max_depth``'s default) is 50,005,000."""


def stored_calls(data: dict, source: str = "derivation", limits=None) -> tuple[list, dict, dict]:
    """The calls and choices of a derivation's dict (format 2 or 1), checked:
    ``(order, choices, index)`` with ``order`` the calls' addresses in the order they ran,
    ``choices`` ``(address, name) -> value`` and ``index`` ``(address, name) -> the
    choice's position in the file``; a file that does not hold them is a
    :class:`DerivationFormatError` in one line naming ``source``.

    Calls nesting past :data:`MAX_ADDRESS_PARTS` levels in all must keep within the
    model's ``max_depth`` and ``max_calls`` (``limits()`` returns them; by default a
    :class:`Model`'s defaults) and the machine's memory, checked before the addresses
    are built."""
    if isinstance(data, dict) and data.get("format") == FORMAT_1:
        return _calls_1(data, source)
    check_format(data, FORMAT, source)
    calls, entries = data.get("calls"), data.get("choices")
    for key, value in (("calls", calls), ("choices", entries)):
        if not isinstance(value, list):
            raise _fail(source, f"field {key!r} is missing or not a list")
    if not calls:
        raise _fail(source, "'calls' is empty; it lists every call as it ran, the root call first, [null, null]")
    depths = []  # each call's depth, checked before any address (a tuple as long as it) is built
    for i, call in enumerate(calls):
        if i == 0:
            if call != [None, None]:
                raise _fail(source, "calls[0] must be the root call, [null, null]")
            depths.append(0)
            continue
        if (not isinstance(call, list) or len(call) != 2 or isinstance(call[0], bool)
                or not isinstance(call[0], int) or not isinstance(call[1], str)):
            raise _fail(source, f"calls[{i}] must be [the index of the call that spawned it, spawn site]")
        if not 0 <= call[0] < i:
            raise _fail(source, f"calls[{i}] names calls[{call[0]}] as the call that spawned it, which "
                                + ("does not come before it" if call[0] >= 0 else "is no call")
                                + ": 'calls' lists the calls as they ran; restore it as it was saved")
        depths.append(depths[call[0]] + 1)
    if sum(depths) > MAX_ADDRESS_PARTS:
        _check_nesting(depths, limits() if limits is not None else (Model.max_depth, Model.max_calls), source)
    order, seen = [()], {()}
    for i, call in enumerate(calls[1:], 1):
        address = order[call[0]] + (call[1],)
        if address in seen:
            raise _fail(source, f"calls[{i}] is listed twice (spawn site {cut_text(call[1], 60)!r} of "
                                f"calls[{call[0]}]); restore 'calls' as it was saved")
        seen.add(address)
        order.append(address)
    choices, index = {}, {}
    for i, entry in enumerate(entries):
        if (not isinstance(entry, list) or len(entry) != 3 or isinstance(entry[0], bool)
                or not isinstance(entry[0], int) or not 0 <= entry[0] < len(order) or not isinstance(entry[1], str)
                or not isinstance(entry[2], (bool, int, float, str))):
            raise _fail(source, f"choices[{i}] must be [call, name, value], the call its index in 'calls' (0 to "
                                f"{len(order) - 1})")
        _add_choice(choices, index, (order[entry[0]], entry[1]), entry[2], i, source, f"calls[{entry[0]}]")
    return order, choices, index


def _check_nesting(depths: list, limits: tuple, source: str) -> None:
    """Refuse calls deeper or more than the model allows, or whose addresses would not fit
    in memory (:func:`stored_calls`)."""
    max_depth, max_calls = limits
    deepest, levels = max(depths), sum(depths)
    if deepest > max_depth or len(depths) - 1 > max_calls:
        raise _fail(source, f"its {len(depths):,} calls nest up to {deepest:,} deep, but its model allows "
                            f"{max_calls:,} calls at most {max_depth:,} deep (max_calls, max_depth): the model "
                            "cannot have made it; is it the file that was saved?")
    # an address of n spawn sites: a tuple of 56 + 8n bytes
    check_memory(f"{source}: replaying its {len(depths):,} calls ({levels:,} levels of nesting in all)",
                 8.0 * levels + 56.0 * len(depths), "is it the file that was saved?")


def _add_choice(choices: dict, index: dict, key: tuple, value, i: int, source: str, where: str) -> None:
    if key in choices:  # one would silently win over the other
        raise _fail(source, f"choices[{i}] gives choice {cut_text(key[1], 60)!r} at {where} again "
                            f"(choices[{index[key]}] gave it first); keep one of the two")
    choices[key], index[key] = value, i


def _calls_1(data: dict, source: str) -> tuple[list, dict, dict]:
    """:func:`stored_calls` of a ``procmod-derivation/1`` dict (whole addresses)."""
    for key in ("order", "choices"):
        if not isinstance(data.get(key), list):
            raise _fail(source, f"field {key!r} is missing or not a list")
    choices, index = {}, {}
    for i, entry in enumerate(data["choices"]):
        if (not isinstance(entry, list) or len(entry) != 3 or not isinstance(entry[0], list)
                or not all(isinstance(s, str) for s in entry[0]) or not isinstance(entry[1], str)
                or not isinstance(entry[2], (bool, int, float, str))):
            raise _fail(source, f"choices[{i}] must be [[site, ...], name, value]")
        _add_choice(choices, index, (tuple(entry[0]), entry[1]), entry[2], i, source,
                    cut_text(json.dumps(entry[0]), 80))
    order = []
    for i, address in enumerate(data["order"]):
        if not isinstance(address, list) or not all(isinstance(s, str) for s in address):
            raise _fail(source, f"order[{i}] must be a list of spawn-site names")
        order.append(tuple(address))
    ran = set()  # calls run in an order where each comes after the call that spawned it
    for i, address in enumerate(order):
        if address in ran or (address and address[:-1] not in ran):
            raise _fail(source, f"order[{i}] {cut_text(json.dumps(list(address)), 80)} "
                                + ("is listed twice" if address in ran else "comes before the call that spawns it")
                                + ": 'order' lists the calls as they ran (an edited order was blamed on the choices); "
                                  "restore it as it was saved")
        ran.add(address)
    return order, choices, index


def _file_model(data: dict, resolve_model, source: str, folder) -> Model:
    """The model a derivation's dict names, resolved (:func:`derivation_from_dict`)."""
    name = data["model"]
    if _names_program(name) and "\\" in name and os.sep == "/" and not os.path.isfile(
            name if folder is None else os.path.join(folder, name)):  # (a folder may have a \ in its name here)
        name = name.replace("\\", "/")  # written on Windows: names in files may use / or \ (README)
    if folder is not None and _names_program(name) and not os.path.isabs(name) \
            and os.path.isfile(os.path.join(folder, name)):  # else a model's own name: as it is
        name = os.path.realpath(os.path.join(folder, name))  # '..' climbs the real tree, as it was written
    if isinstance(resolve_model, Model):  # the model itself: it must be the one the file names
        if not _names_program(name) and name != resolve_model.name:
            raise _fail(source, f"it is a derivation of model {name!r}, not {resolve_model.name!r}: give its model")
        resolve_model = _itself(resolve_model)
    elif not callable(resolve_model):
        raise InvalidArgumentError(f"resolve_model must be the Model or a function from a model's name to its Model "
                                   f"(e.g. procmod.models.get_model), got {type(resolve_model).__name__}")
    try:
        model = resolve_model(name)
    except ProcmodError as exc:  # an unknown model: say which file names it (same kind of error)
        raise type(exc)(f"{source}: {exc}") from None
    if not isinstance(model, Model):  # e.g. a dict's .get() that does not know the name
        raise _fail(source, f"resolve_model({name!r}) returned {type(model).__name__}, not a procmod Model: give "
                            "load_derivation a resolver that returns the model that made the file")
    if other_program(name, model.name):  # whichever way it was given: a Model, --model's resolver
        raise _fail(source, f"it is a derivation of the learned program {name!r}, not {model.name!r}: give its "
                            "program (procmod render: or leave out --model)")
    return model


def derivation_from_dict(data, resolve_model: Model | Callable[[str], Model], source: str = "derivation",
                         folder: str | os.PathLike | None = None) -> Derivation:
    """Rebuild a derivation from its dict by replaying its model exactly.

    ``resolve_model`` is the model that made it, or a function of a model's name that
    returns the model registered under it (``procmod.models.get_model``). ``folder``: where
    the file lay; a learned program named by a relative path (as :func:`save_derivation`
    writes it) is found from there.
    """
    if not isinstance(data, dict):
        raise _fail(source, "expected a JSON object")
    if data.get("format") != FORMAT_1:
        check_format(data, FORMAT, source)
    for key, kind in (("model", str), ("params", dict)):
        if not isinstance(data.get(key), kind):
            raise _fail(source, f"field {key!r} is missing or not a {kind.__name__}")
    resolved = []  # the model, resolved once: the calls' check asks for its limits only when they nest deep

    def model_of_file() -> Model:
        if not resolved:
            resolved.append(_file_model(data, resolve_model, source, folder))
        return resolved[0]

    # the file's own faults before the model's
    order, choices, index = stored_calls(data, source, lambda: (model_of_file().max_depth, model_of_file().max_calls))
    model = model_of_file()
    stored_root = data.get("root")
    if isinstance(stored_root, str) and not _same_root(stored_root, model):
        same = "another model of the same name (give a model of your own a name of its own); " \
            if model.name == data["model"] else ""
        raise _fail(source, f"was made by model {data['model']!r}, whose root rule is {stored_root}, but the model "
                            f"here, {model.name!r}, starts at {root_rule_id(model)}: {same}replay it with the model "
                            "that made it (load_derivation(path, lambda name: that_model); procmod render --model)")
    try:
        model = model.configure(**data["params"])
    except ProcmodError as exc:
        raise _fail(source, str(exc)) from exc
    # Replaying needs no randomness when the file matches; a fixed generator keeps any
    # mismatch reproducible while we report it.
    try:
        result = replay(model, choices, np.random.default_rng(0), order=order)
    except ProcmodError as exc:  # e.g. a parameter the model's rules refuse
        raise _fail(source, str(exc)) from None
    except MemoryError as exc:  # numpy refuses an absurd allocation at once (params.size 10^9)
        raise _fail(source, f"replaying it under params {cut_text(json.dumps(data['params']), 120)} needs more "
                            f"memory than this machine has ({exc})") from None
    if result.unused or result.log_fresh != 0.0 or result.derivation.order() != order:
        # choices the file lacks (a deleted 'maybe' coin too: the calls after it then leave
        # stored choices unused, which would be named instead of the cause)
        made = [(node.address, name) for node in result.derivation.nodes() for name in node.choices]
        missing = [key for key in made if key not in choices]
        # a stored value its distribution cannot take is drawn afresh at its own address,
        # and may send the replay elsewhere: that value is the cause, not what went missing
        unusable = not set(made).isdisjoint(result.unused)
        calls = {address: i for i, address in enumerate(order)}

        def where(address) -> tuple:  # (how the message names the call, how the file names it)
            shown = cut_text(json.dumps(list(address)), 80)
            if data.get("format") == FORMAT_1:
                return shown, shown
            return (f"calls[{calls[address]}]", str(calls[address])) if address in calls else (shown, "CALL")

        if missing and not unusable:  # drawn afresh in the replay: name the first, where the file should hold it
            address, name = missing[0]
            shown, written = where(address)
            what = (f"a choice the model makes is missing: the first, {cut_text(name, 60)!r} at {shown}, is not in its "
                    f"choices; add it as [{written}, {json.dumps(name)}, VALUE]")
        elif result.unused:
            first = min(result.unused, key=index.__getitem__)  # the first in the file
            what = (f"{len(result.unused)} stored choices were not used; the first, choices[{index[first]}], "
                    f"{cut_text(first[1], 60)!r} at {where(first[0])[0]} = "
                    f"{cut_text(json.dumps(choices[first]), 40)}, is a value its distribution there cannot take "
                    "(outside its range, not a number, another type) or a choice the model does not make")
        else:
            what = ("choices were missing" if result.log_fresh != 0.0 or
                    len(result.derivation.choice_map()) != len(choices) else "the calls ran in another order")
        raise _fail(source, f"does not replay under model {model.name!r} ({what}); was the file edited, or saved by "
                            "another version of the model?")
    stored = data.get("log_prior")
    if isinstance(stored, (int, float)) and not math.isclose(stored, result.derivation.log_prior,
                                                             rel_tol=1e-9, abs_tol=1e-9):
        raise _fail(source, f"stored log_prior {stored} differs from the replayed {result.derivation.log_prior}: "
                            "its choices were edited, or the model has changed since it was saved; to replay "
                            "edited choices, delete the file's \"log_prior\"")
    return result.derivation


def _itself(model: Model) -> Callable[[str], Model]:
    return lambda name: model


def load_derivation(path: str | os.PathLike, resolve_model: Model | Callable[[str], Model]) -> Derivation:
    """Read a ``procmod-derivation/2`` (or ``/1``) file and replay it exactly (``resolve_model``: see
    :func:`derivation_from_dict`)."""
    data = read_json(path, DerivationFormatError, "derivation file")
    return derivation_from_dict(data, resolve_model, source=cut_text(str(path)), folder=Path(path).parent)
