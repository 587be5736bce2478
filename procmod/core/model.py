"""A procedural model: a root rule, named parameters, and a factory for its output.

A *rule* is a plain Python function ``rule(ctx, *args)`` that makes random choices with
``ctx.sample``, emits geometry with ``ctx.emit`` and spawns child rule calls with
``ctx.spawn`` / ``ctx.maybe`` (see :class:`procmod.core.runtime.Context`). A rule must be
a deterministic function of its arguments and of the values its choices return: the
runtime re-executes a rule call to resume it after a pause and to replay it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, Callable, Mapping

from .errors import InvalidArgumentError, ModelError, plain_value, shown_value


LIMIT_CEILING = 10 ** 9  # of max_calls, max_depth, max_call_emits, max_call_choices: a guard that never trips is none


@dataclass(frozen=True)
class Model:
    """A procedural model that every engine can run.

    Parameters
    ----------
    name : str
        Registry name, also stored in saved derivations.
    description : str
        One line shown by ``procmod models``.
    root : callable
        The rule called first, as ``root(ctx, *root_args(params))``.
    root_args : callable
        Maps the parameter dict to the root rule's positional arguments.
    new_output_from : callable
        ``new_output_from(params) -> Output``: a fresh, empty output (e.g. a raster
        canvas) into which emitted geometry is drawn: ``add(geometry)``, a cheap
        ``copy()`` and declared capabilities (:class:`procmod.core.protocols.Output`).
    params : mapping
        Parameter values (e.g. start point and direction); change them with
        :meth:`configure`. Values must be JSON-serialisable.
    rules : tuple of callables
        Every rule of the model (its generator graph's nodes), for documentation and for
        engines that reason about spawn sites.
    choices_doc : str
        Documentation of the random choices and their distributions.
    arg_ranges : mapping
        ``rule name -> ((low, high), ...)``, one range per positional argument of the
        rule (after ``ctx``); neural guides normalise scalar arguments to [-1, 1] with
        them (``None`` for an argument that is not a scalar feature, ``"angle"`` for a
        direction in radians, which guides see as its cosine and sine).
    heading_rules : tuple of str
        Rules (2D models) whose ``ctx.at`` positions are ``(x, y, heading)``: the heading,
        in radians, of the rule's local frame at that point. Neural guides see its cosine
        and sine as two more local-state features (seed 003: local state includes "the
        current orientation of any local reference frame"); unlike a rule argument it
        follows the call as it turns, e.g. to the angle a segment was just drawn at.
    param_ranges : mapping
        ``parameter name -> (low, high)``: the inclusive range of a numeric parameter (of
        each number of a list parameter). :meth:`configure` refuses a value outside it,
        e.g. a canvas ``size`` whose pixels no machine holds.
    max_calls : int
        The most rule calls one derivation may make (default 100,000); a
        derivation that goes past it raises a :class:`ModelError`, since a model that
        never stops growing (a recursion without a depth limit or with a spawn chance that
        keeps it alive) would otherwise run every engine until memory runs out. The
        built-in models make a few hundred at most; raise it for a larger model.
    max_depth : int
        The deepest rule call (spawn sites from the root) one derivation may reach
        (default 10,000), for the same reason: a call's address grows with its depth, so a
        runaway recursion would slow every call and fill memory long before
        ``max_calls``. The built-in models stay under depth 100 (chain's own bound).
    max_call_emits : int
        The most emits one rule call may make (default 20,000): a loop that never ends
        would otherwise draw until memory ran out.
    max_resumed_emits : int
        The most emits one rule call may make under engines that pause at emits (SMC,
        SOSMC; default 500, and never more than ``max_call_emits``): they re-run a call
        from its start to resume it after each of its emits, about n^2 / 2 emits for n,
        so a loop of 20,000 emits ran for hours a particle before ``max_call_emits``
        said so. A long run of parts is better emitted from child calls; raise this for
        one meant to be a single call.
    max_call_choices : int
        The most random choices one rule call may make (default 100,000): a loop of
        choices that never ends (``while not ctx.sample(...)`` with a coin that never
        comes up) ran every engine, its budget unread, until memory ran out.
    settle : callable or None
        ``settle(derivation) -> derivation``: what :func:`procmod.core.run_forward` does
        to a complete forward sample before returning it (default None: nothing). It
        must return a derivation of the model (e.g. one replayed with a choice moved), so
        that a saved sample replays to the same output; engines running toward a target
        never call it. Learned programs whose examples stand on one ground set their
        samples on it (:mod:`procmod.learn.ground`).

    :meth:`configure` also checks each value against the parameter's default: a bool
    stays a bool (``"yes"`` is refused, not read as true), an integer an integer, a
    number a finite number, a list a list of as many items, each checked the same way;
    but the ``start`` and ``direction`` a picture target places (:func:`picture_placed`)
    take real numbers however their defaults are written (``[0, 1]``, ``[0, -1]``), and
    the defaults themselves stay as written (a ``start`` of [1, 1] may be a grid cell).
    """

    name: str
    description: str
    root: Callable
    root_args: Callable[[Mapping[str, Any]], tuple]
    new_output_from: Callable[[Mapping[str, Any]], Any]
    params: Mapping[str, Any] = field(default_factory=dict)
    rules: tuple = ()
    choices_doc: str = ""
    arg_ranges: Mapping[str, tuple] = field(default_factory=dict)
    heading_rules: tuple = ()
    param_ranges: Mapping[str, tuple] = field(default_factory=dict)
    max_calls: int = 100_000
    max_depth: int = 10_000
    max_call_emits: int = 20_000
    max_call_choices: int = 100_000
    max_resumed_emits: int = 500
    settle: Callable | None = None

    def __post_init__(self):
        # a model built wrong fails here, naming the field, not at its first run
        if not isinstance(self.name, str) or not self.name.strip():
            raise ModelError(f"a model's name must be a non-empty string (it names the model in saved derivations, "
                             f"guides and reports), got {shown_value(self.name)}")
        if not isinstance(self.params, Mapping) or not all(isinstance(key, str) for key in self.params):
            raise ModelError(f"model {self.name!r}: params must be a dict of parameter names (strings) to their "
                             f"defaults, got {shown_value(self.params)}")
        for what in ("root", "root_args", "new_output_from"):
            value = getattr(self, what)
            if not callable(value):
                raise ModelError(f"model {self.name!r}: {what} must be a function, got {value!r:.40}")
        if self.settle is not None and not callable(self.settle):
            raise ModelError(f"model {self.name!r}: settle must be a function of a complete derivation or None, "
                             f"got {self.settle!r:.40}")
        for what in ("max_calls", "max_depth", "max_call_emits", "max_call_choices", "max_resumed_emits"):
            value = getattr(self, what)
            if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= LIMIT_CEILING:
                raise ModelError(f"model {self.name!r}: {what} must be a whole number from 1 to "
                                 f"{LIMIT_CEILING:,}, got {shown_value(value)}")
        # numpy numbers in the defaults as Python's: a saved derivation's JSON failed on an
        # np.int64, and a numpy default switched configure's checks of its type off
        if any(_has_numpy(value) for value in self.params.values()):
            object.__setattr__(self, "params", {name: _without_numpy(value) for name, value in self.params.items()})

    def configure(self, **params) -> "Model":
        """Return a copy of the model with some parameters changed.

        Raises
        ------
        InvalidArgumentError
            If a name is not one of the model's parameters, or a value does not fit the
            parameter (see the class docstring); the message names the parameter.
        """
        unknown = sorted(set(params) - set(self.params))
        if unknown:
            raise InvalidArgumentError(
                f"model {self.name!r} has no parameter {shown_value(unknown[0])}; "
                f"its parameters are: {', '.join(sorted(self.params)) or 'none'}")
        params = {name: plain_value(value) for name, value in params.items()}  # JSON values: saved with derivations
        placed = picture_placed(self.params)
        for name, value in params.items():
            default = self.params[name]
            if name in placed:  # a picture's point and heading: real numbers however the default is written
                default = [float(v) for v in default]
            _check_param(name, value, default, self.param_ranges.get(name))
        merged = dict(self.params)
        merged.update({name: _like(value, self.params[name]) for name, value in params.items()})
        return replace(self, params=merged)

    def new_output(self):
        """A fresh, empty output accumulator for one derivation."""
        output = self.new_output_from(self.params)
        if not hasattr(output, "add"):
            raise ModelError(f"model {self.name!r}: new_output returned {output!r:.40}, not an output (an object "
                             "with add(geometry) and copy(), e.g. a procmod.geometry canvas); return one")
        return output

    def initial_args(self) -> tuple:
        """The root rule's arguments under the current parameters."""
        args = self.root_args(self.params)
        if type(args) is tuple:  # the usual case, before the ABC check: a process's first
            return args  # isinstance(tuple, Mapping) walks Mapping's subclasses (~0.2 ms)
        if not isinstance(args, (str, bytes, Mapping)):
            try:
                return tuple(args)
            except TypeError:
                pass
        raise ModelError(f"model {self.name!r}: root_args returned {args!r:.40}, not a tuple of the root "
                         "rule's arguments; return a tuple, e.g. lambda p: (p['x'],) or lambda p: ()")


def picture_placed(params) -> tuple:
    """The parameters a picture target sets, as the built-in models take them: ``start``
    when it defaults to a point in normalised image coordinates (two numbers in [0, 1]),
    then ``direction`` when it defaults to a 2D vector. A model's own ``start`` in world
    units, or a heading in radians, is its own (:func:`procmod.targets.image.place_model`)."""
    if not _pair_of_numbers(params.get("start"), within_unit=True):
        return ()  # (a direction alone could be a world vector: y up, where the picture's is down)
    return ("start", "direction") if _pair_of_numbers(params.get("direction")) else ("start",)


def _same_container(value, items: list):
    """``items`` in a container of ``value``'s kind (a list, a tuple, a namedtuple)."""
    if isinstance(value, tuple):
        return type(value)(*items) if hasattr(value, "_fields") else tuple(items)
    return list(items)


def _pair_of_numbers(value, within_unit: bool = False) -> bool:
    """Whether a parameter's default is two real numbers (each in [0, 1] if asked)."""
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        return False
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
        return False
    return not within_unit or all(0.0 <= float(v) <= 1.0 for v in value)


def _has_numpy(value) -> bool:
    if isinstance(value, (list, tuple)):
        return any(_has_numpy(item) for item in value)
    return type(value).__module__ == "numpy"


def _without_numpy(value):
    """``value`` with its numpy numbers (and arrays) as Python's; lists and tuples kept."""
    if isinstance(value, (list, tuple)):
        return _same_container(value, [_without_numpy(item) for item in value])
    return plain_value(value)


def _like(value, default):
    """``value`` (checked by :func:`_check_param`) with the default's number types: an
    integer given for a real parameter (``direction=[0,-1]``) is stored as a float, so that
    a later change of it (a target's real start) is checked against a real, not an integer."""
    if isinstance(default, float) and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if isinstance(default, (list, tuple)) and isinstance(value, (list, tuple)):
        return type(value)(_like(v, d) for v, d in zip(value, default))
    return value


def _check_param(name: str, value, default, bounds=None) -> None:
    """Refuse ``value`` for parameter ``name`` unless it has the default's JSON type (and
    shape) and lies within ``bounds``; the message names the parameter (``size``,
    ``start[1]``)."""
    def fail(expected: str):
        raise InvalidArgumentError(f"parameter {name} must be {expected}, got {shown_value(value)}")

    if isinstance(default, bool):
        if not isinstance(value, bool):
            fail("true or false")
        return
    if isinstance(default, (int, float)):
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            fail("an integer" if isinstance(default, int) else "a number")
        if isinstance(default, int) and not isinstance(value, int):
            fail("an integer")
        if not math.isfinite(value):
            fail("a finite number")
        if bounds is not None and not bounds[0] <= value <= bounds[1]:
            fail(f"between {bounds[0]} and {bounds[1]}")
        return
    if isinstance(default, str):
        if not isinstance(value, str):
            fail("a string")
        return
    if isinstance(default, (list, tuple)):
        if not isinstance(value, (list, tuple)) or len(value) != len(default):
            fail(f"a list of {len(default)} items, e.g. {shown_value(list(default))}")
        for i, (item, item_default) in enumerate(zip(value, default)):
            _check_param(f"{name}[{i}]", item, item_default, bounds)


def check_model(model) -> None:
    """Refuse, in one line, what is not a procmod :class:`Model` (most often a model's
    name given where the model is wanted)."""
    if isinstance(model, type) and issubclass(model, Model):
        raise InvalidArgumentError(f"model must be a procmod Model, got the class {model.__name__} (give an "
                                   f"instance of it: {model.__name__}(...))")
    if not isinstance(model, Model):
        raise InvalidArgumentError(f"model must be a procmod Model, got {type(model).__name__} {model!r:.40}; "
                                   "get one with procmod.models.get_model(name) or procmod.learn.load_program(path)")
