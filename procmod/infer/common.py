"""What every engine shares: budgets, the anytime history, results, batched evaluation.

Engine contract (DESIGN.md "Engines")::

    result = engine(model, target, seed=0, budget=Budget(seconds=30), ...)
    result.best       # the best complete derivation found
    result.samples    # final particles / population / chain states
    result.history    # rows (seconds, evaluations, best score, mean score)

An *evaluation* is one scoring of an output by the target: one particle-step for SMC,
one individual for the GA, one proposal for MCMC, one forward sample for ``forward``.
"""

from __future__ import annotations

import functools
import math
import numbers
import pickle
import re
import time
from dataclasses import dataclass, field
from typing import Callable, NamedTuple

import numpy as np

from ..core import Derivation, InvalidArgumentError, Model, replay
from ..core.errors import shown_value, whole_number
from ..core.protocols import Output, Target, check_declared
from ..core.random import LazyGenerator, check_seed, global_draws_note, global_generator_states


@dataclass(frozen=True)
class Budget:
    """How much an engine may spend: wall seconds, target evaluations, and/or generations.

    The engine stops at the first limit reached. A generation is one SMC run, one GA
    generation, or one MCMC sweep over the chains.
    """

    seconds: float | None = None
    evaluations: int | None = None
    generations: int | None = None

    def __post_init__(self):
        for name in ("seconds", "evaluations", "generations"):
            value = getattr(self, name)
            if value is None:
                continue
            if isinstance(value, bool) or not isinstance(value, numbers.Real):
                raise InvalidArgumentError(f"budget {name} must be a number, got {value!r}")
            if not 0 < value < math.inf:
                raise InvalidArgumentError(f"budget {name} must be positive and finite (for no limit, give no "
                                           f"budget), got {value:g}")
            if name != "seconds" and value != int(value):
                raise InvalidArgumentError(f"budget {name} must be a whole number, got {value:g}")

    @property
    def unlimited(self) -> bool:
        return self.seconds is None and self.evaluations is None and self.generations is None

    def describe(self) -> str:
        parts = []
        if self.seconds is not None:
            parts.append(f"{self.seconds:g}s")
        if self.evaluations is not None:
            parts.append(f"{self.evaluations}evals")
        if self.generations is not None:
            parts.append(f"{self.generations}gens")
        return "+".join(parts) or "unlimited"


_BUDGET = re.compile(r"^\s*(\d+(?:\.\d+)?)\s*(s|sec|seconds|m|min|evals?|evaluations|gens?|generations)\s*$")


_BUDGET_KINDS = {"time": "time", "eva": "evaluations", "gen": "generations"}


def parse_budget(text: str) -> Budget:
    """Parse ``30s``, ``2m``, ``5000evals`` or ``100gens``; several limits joined with
    ``+`` (``100gens+30s``) end the run at whichever is reached first."""
    seconds = evaluations = generations = None
    given = set()
    for part in str(text).split("+"):
        match = _BUDGET.match(part.lower())
        if not match and _BUDGET.match(part.lower().strip().lstrip("-")):
            raise InvalidArgumentError(f"cannot read budget {text!r}: a budget is positive (e.g. 30s, 2m, 5000evals "
                                       "or 100gens)")
        if not match:
            raise InvalidArgumentError(
                f"cannot read budget {text!r}: use e.g. 30s, 2m, 5000evals or 100gens")
        value, unit = float(match.group(1)), match.group(2)
        kind = "time" if unit in ("s", "sec", "seconds", "m", "min") else unit[:3]
        if kind in given:  # "5gens+5gens" read as 5gens, "0.02m+0.5s" as 0.5s
            raise InvalidArgumentError(f"cannot read budget {text!r}: it limits the {_BUDGET_KINDS[kind]} twice; "
                                       "limits joined with + end the run at the first one reached, so give each "
                                       "kind once (e.g. 100gens+30s)")
        given.add(kind)
        if unit in ("s", "sec", "seconds"):
            seconds = value
        elif unit in ("m", "min"):
            seconds = 60 * value
        else:
            what = "evaluations" if unit.startswith("eval") else "generations"
            if not value.is_integer():  # int() made 0.5evals "got 0", 2.7evals 2
                raise InvalidArgumentError(f"cannot read budget {text!r}: a count of {what} is a whole number "
                                           "(e.g. 5000evals or 100gens)")
            if what == "evaluations":
                evaluations = int(value)
            else:
                generations = int(value)
    return Budget(seconds, evaluations, generations)


class HistoryRow(NamedTuple):
    """One point of an engine's anytime curve. ``seconds`` is the wall time since the
    engine started: the one field that differs between two runs of one seeded job."""

    seconds: float
    evaluations: int
    best_score: float
    mean_score: float


ROWS_PER_DOUBLING = 16


def best_first(score: float, log_likelihood: float) -> tuple:
    """The key that ranks complete derivations, best last: by score, after every one the
    target allows (one it rules out, log-likelihood -inf, such as a proxy target's ship
    whose parts intersect, which its score does not see). Tracker.offer, the SMC worker
    shards and the GA's ranking all rank so."""
    return (log_likelihood != -math.inf, score)


class Tracker:
    """Keeps time, counts evaluations, remembers the best complete derivation, and records
    the anytime history.

    History rows are due at points fixed by the work done, never by the clock, so that a
    seeded run with a budget in evaluations or generations writes the same rows every
    time (only their ``seconds`` differ): a row is due once the evaluations reach the next
    point of a geometric schedule, ``rows_per_doubling`` points per doubling of the
    evaluations (every evaluation at first, then every 4.4%: about 320 rows for a million
    evaluations). Engines call :meth:`due` often (it is cheap) and :meth:`record` when it
    says so, plus wherever their own work-based points are (every generation, the end).

    ``progress`` (a progress bar) is called about every ``progress_interval`` seconds of
    :meth:`due` calls and at every row; it reads the tracker and writes no file.
    """

    def __init__(self, budget: Budget | None, progress: Callable | None = None,
                 rows_per_doubling: int = ROWS_PER_DOUBLING, progress_interval: float = 0.1):
        self.budget = budget or Budget()
        self.stop_requested = False
        if progress is not None and not callable(progress):
            raise InvalidArgumentError(f"progress must be a function, called with the run's Tracker as it goes, or "
                                       f"None, got {type(progress).__name__} {progress!r:.40}")
        self.progress = progress
        self.progress_interval = progress_interval
        self._ratio = 2.0 ** (1.0 / check_positive("rows_per_doubling", rows_per_doubling))
        # the global generators' states, read before the clock starts: ~0.1 ms of copying
        # that is no part of the run (a guided 1-particle SMC run takes ~1.5 ms)
        self._global_states = global_generator_states()  # see notes()
        self.t0 = time.perf_counter()
        self.evaluations = 0
        self.generations = 0
        self.best = None
        self.best_score = -math.inf
        self.best_ruled_out = True  # (until a best is found) see offer()
        self.best_allowed_score = -math.inf  # the history's best: one a later allowed best cannot undercut
        self.rows: list[HistoryRow] = []
        self._next_row = 1  # evaluations at which the next row is due
        self._last_progress = -math.inf
        self.offered = False  # whether any complete derivation was offered (a best of score -inf is none)

    @property
    def seconds(self) -> float:
        return time.perf_counter() - self.t0

    def request_stop(self) -> None:
        """End the run at the engine's next budget check, keeping what it has found (e.g. a
        Stop button, from the progress callback)."""
        self.stop_requested = True

    def spent(self) -> bool:
        """True once any limit of the budget is reached, or a stop was requested."""
        b = self.budget
        return (self.stop_requested
                or (b.seconds is not None and self.seconds >= b.seconds)
                or (b.evaluations is not None and self.evaluations >= b.evaluations)
                or (b.generations is not None and self.generations >= b.generations))

    def out_of_time(self) -> bool:
        """True once the budget's seconds are used up or a stop was requested: the limits an
        engine also checks inside a unit of work (a GA generation can take minutes on a large
        volume target, and a Stop button must not wait for it)."""
        b = self.budget
        return self.stop_requested or (b.seconds is not None and self.seconds >= b.seconds)

    def fraction(self) -> float:
        """How much of the budget is used, in [0, 1] (for progress bars)."""
        b = self.budget
        parts = [0.0]
        if b.seconds is not None:
            parts.append(self.seconds / b.seconds)
        if b.evaluations is not None:
            parts.append(self.evaluations / b.evaluations)
        if b.generations is not None:
            parts.append(self.generations / b.generations)
        return min(1.0, max(parts))

    def offer(self, derivation: Derivation, score: float, log_likelihood: float = 0.0) -> None:
        """Consider a complete derivation for ``best``: the highest score, except that one
        the target rules out (``log_likelihood`` -inf: parts that intersect, which a proxy
        target's score does not see) is best only while no other has been found."""
        self.offered = True
        if log_likelihood != -math.inf and score > self.best_allowed_score:
            self.best_allowed_score = score
        # a score of -inf is no best, whatever the log-likelihood (a target whose score
        # failed where its likelihood did not had its first derivation kept as "best"
        # without a word, h149): none, and the result says why (NO_FINITE_SCORE_NOTE)
        if score != -math.inf and self.better(score, log_likelihood):
            self.best_score, self.best = score, derivation
            self.best_ruled_out = log_likelihood == -math.inf

    def better(self, score: float, log_likelihood: float = 0.0) -> bool:
        """Whether :meth:`offer` would take a derivation of this score and log-likelihood."""
        return best_first(score, log_likelihood) > (not self.best_ruled_out, self.best_score)

    def notes(self) -> list:
        """What a result should say of its best (:data:`RULED_OUT_NOTE`), and of draws from
        the global generators since the tracker was made (:func:`global_draws_note`)."""
        notes = [RULED_OUT_NOTE] if self.best is not None and self.best_ruled_out else []
        if notes and far_outside(getattr(self.best, "output", None)):
            notes.append(FAR_OUTSIDE_NOTE)
        if self.best is None and self.offered:
            notes.append(NO_FINITE_SCORE_NOTE)
        drew = global_draws_note(self._global_states)
        return notes + ([drew] if drew is not None else [])

    def due(self) -> bool:
        """Whether a history row is due (cheap; engines compute mean scores only then)."""
        if self.progress is not None:
            now = time.perf_counter()
            if now - self._last_progress >= self.progress_interval:
                self._last_progress = now
                self.progress(self)
        return self.evaluations >= self._next_row

    def record(self, mean_score: float) -> None:
        """Append a row now (the wall time goes in its ``seconds`` field only)."""
        # the best the target allows: a ruled-out best replaced by a lower allowed one had
        # made the best so far fall
        row = HistoryRow(self.seconds, self.evaluations, self.best_allowed_score, float(mean_score))
        if self.rows and self.rows[-1].evaluations == self.evaluations:
            self.rows[-1] = row  # nothing evaluated since: one row a count (MCMC's final row came twice)
        else:
            self.rows.append(row)
        self._next_row = max(self.evaluations + 1, math.ceil(self.evaluations * self._ratio))
        if self.progress is not None:
            self._last_progress = time.perf_counter()
            self.progress(self)


# A lower bound of what one particle, individual or chain state costs beside its output:
# its derivation's nodes, choices and contexts (a few small Python objects each).
MEMBER_OVERHEAD = 2048


def output_bytes(output: Output) -> int:
    """A lower bound of the memory one more copy of ``output`` takes: the numpy arrays
    its ``copy()`` does not share with it (a canvas's pixels, not its target's gains)."""
    copy = output.copy()
    # the fields of the copy: its __dict__ and, for a class with __slots__ (a Canvas),
    # the slots of every class it derives from
    names = set(vars(copy)) if hasattr(copy, "__dict__") else set()
    for cls in type(copy).__mro__:
        slots = cls.__dict__.get("__slots__", ())
        names.update((slots,) if isinstance(slots, str) else slots)
    total = 0
    for name in names:
        value = getattr(copy, name, None)
        if isinstance(value, np.ndarray) and value is not getattr(output, name, None):
            total += value.nbytes
    return total


def check_population(option: str, count, output: Output, copies: int = 1, another: Output | None = None) -> int:
    """Refuse a population (``particles``, ``population``, ``chains``) that cannot
    fit in memory, before an engine allocates it; returns ``count``.

    Refused too, in one line: an output whose ``copy()`` is the output itself, and a
    target whose ``new_output`` gave ``another`` (a second call's output, where the
    engine draws each member from ``new_output``) as the same object: every member would
    draw into one canvas, and the engines had reported as best a derivation whose replay
    scored otherwise, without a word (h149).

    ``output`` is an empty output of the configured model (``target.new_output(model)``):
    each member holds ``copies`` copies of it at least (incremental MCMC: a chain's state,
    its first checkpoint and the proposal's output). It must declare its capabilities
    (:func:`procmod.core.protocols.check_declared`): engines read them later. Engines can
    call this on their own population argument
    (``check_population("particles", particles, target.new_output(model))``).
    """
    from ..core.limits import check_memory

    check_positive(option, count)
    check_declared(output, Output, "the target's output")
    if another is output:
        raise InvalidArgumentError(f"the target's new_output() returned the same {type(output).__name__} object twice: "
                                   "every member of the population would draw into it; return a new, empty output "
                                   "each call")
    if output.copy() is output:
        raise InvalidArgumentError(f"{type(output).__name__}.copy() returned the output itself: a copy must be a new "
                                   "output that later drawing into either leaves the other as it was")
    per_member = copies * output_bytes(output) + MEMBER_OVERHEAD
    check_memory(f"{option} {count:,}", float(count) * per_member,
                 f"each of them holds at least {per_member:,} bytes; use fewer")
    return count


@dataclass
class Result:
    """What an engine returns (see the module docstring)."""

    engine: str
    best: Derivation | None
    best_score: float
    samples: list
    history: list
    seconds: float
    evaluations: int
    settings: dict = field(default_factory=dict)
    log_weights: list | None = None
    log_marginal_likelihood: float | None = None
    notes: list = field(default_factory=list)

    def history_csv(self) -> str:
        """The anytime history as CSV text."""
        lines = ["seconds,evaluations,best_score,mean_score"]
        lines += [f"{r.seconds:.6f},{r.evaluations},{r.best_score:.9g},{r.mean_score:.9g}" for r in self.history]
        return "\n".join(lines) + "\n"

    def score_at(self, seconds: float) -> float:
        """Best score reached by ``seconds`` (-inf if nothing complete yet)."""
        best = -math.inf
        for row in self.history:
            if row.seconds > seconds:
                break
            best = row.best_score
        return best


class Evaluation(NamedTuple):
    """A replayed, scored derivation."""

    derivation: Derivation
    log_likelihood: float
    score: float
    log_reused: float
    log_fresh: float
    unused: list


@dataclass
class Scored:
    """A complete derivation with its log-prior, log-likelihood and score (a chain state,
    a GA individual)."""

    derivation: Derivation
    log_prior: float
    log_likelihood: float
    score: float

    @classmethod
    def from_evaluation(cls, ev: "Evaluation") -> "Scored":
        return cls(ev.derivation, ev.derivation.log_prior, ev.log_likelihood, ev.score)


def checked_value(value, target, method: str) -> float:
    """``value``, what ``target.<method>(output)`` returned, as a float: a real number, or
    -inf for an output that cannot be. Anything else (NaN, +inf, None, a string, an array)
    is an InvalidArgumentError naming the target's method: a NaN weight used to collapse
    every SMC particle onto the outputs that gave it, without a word."""
    if isinstance(value, float) or (isinstance(value, numbers.Real) and not isinstance(value, bool)):
        try:
            number = float(value)
        except OverflowError:  # a Python int past the float range (10**400): a traceback had ended the run
            number = math.nan
        if number == number and number != math.inf:
            return number
    shown = " ".join(repr(value).split())[:60]
    raise InvalidArgumentError(f"the target's {method}() returned {shown}: it must return a real number (or -inf for "
                               f"an output that cannot be); check {type(target).__name__}.{method}")


def mean_of(scores) -> float:
    """The mean of a population's scores (real numbers or -inf) for its history row:
    ``math.fsum`` (no numpy call overhead on a short list), or, where scores near the end
    of the float range overflow the sum (a target's ``-sys.float_info.max`` for "ruled
    out"), the mean of the scores measured against the largest of them, scaled back
    (``fsum`` had raised an OverflowError, and numpy's mean of such finite scores read
    -inf)."""
    count = len(scores)
    try:
        return math.fsum(scores) / count
    except OverflowError:  # measured against the largest magnitude, the sum stays in range
        if -math.inf in scores:
            return -math.inf
        scale = max(abs(score) for score in scores)
        return scale * (math.fsum(score / scale for score in scores) / count)


def scored(target: Target, output) -> tuple[float, float]:
    """``(target.log_likelihood(output), target.score(output))``, each checked by
    :func:`checked_value`."""
    return (checked_value(target.log_likelihood(output), target, "log_likelihood"),
            checked_value(target.score(output), target, "score"))


def configured_model(target: Target, model: Model) -> Model:
    """``target.configure(model)``, refused in one line unless it is a procmod Model."""
    configured = target.configure(model)
    if not isinstance(configured, Model):
        shown = " ".join(repr(configured).split())[:60]
        raise InvalidArgumentError(f"the target's configure(model) returned {shown}, not a procmod Model: it must "
                                   f"return the model (or a configured copy); check {type(target).__name__}.configure")
    return configured


def evaluate(model: Model, target: Target, job) -> Evaluation:
    """Replay ``job = (choices, seed, maybe_default)`` into the target's output and score it.

    Module-level (and fed only picklable arguments) so process pools and dask can run it.
    """
    choices, seed, maybe_default = job
    output = target.new_output(model)
    if output.supports_part_cache:  # full replays re-add mostly the same parts
        output.use_part_cache()
    result = replay(model, choices, LazyGenerator(seed), output=output, maybe_default=maybe_default)
    d = result.derivation
    return Evaluation(d, *scored(target, d.output), result.log_reused, result.log_fresh, result.unused)


def evaluate_all(executor, model: Model, target: Target, jobs: list, lazy: bool = False):
    """Evaluate jobs through ``executor`` (in order): a list, or with ``lazy`` a generator
    whose ``close()`` leaves the rest unevaluated."""
    results = _evaluations(executor, model, target, jobs)
    return results if lazy else list(results)


def _evaluations(executor, model: Model, target: Target, jobs: list):
    if executor is None:  # one at a time (an Executor's map submits every job at once)
        for job in jobs:
            yield evaluate(model, target, job)
        return
    if not callable(getattr(executor, "map", None)):
        raise InvalidArgumentError(f"executor must be a concurrent.futures.Executor (its map runs the evaluations) "
                                   f"or None, got {type(executor).__name__}")
    try:
        yield from executor.map(functools.partial(evaluate, model, target), jobs)
    except (pickle.PicklingError, AttributeError, TypeError) as exc:
        if "pickle" not in str(exc).lower():
            raise
        # a process pool sends the model, the target and the derivations (which name the
        # rules) to its workers by pickling: lambdas and functions defined inside others do
        # not pickle
        raise InvalidArgumentError(f"the executor's processes cannot be sent the model {model.name!r} or its "
                                   f"target ({str(exc)[:160]}): a process pool needs the model's rules, root_args "
                                   "and new_output_from, and the target, defined at module level (no lambdas or nested "
                                   "functions); define them so, or run without an executor") from exc


def new_seed(rng: np.random.Generator) -> int:
    """A seed for a sub-task, drawn from the engine's generator (keeps runs reproducible)."""
    return int(rng.integers(0, 2 ** 63 - 1))


_TARGET_METHODS = ("configure", "new_output", "score", "log_likelihood")


def check_run(model, target, seed, budget) -> None:
    """Refuse, in one line each, what an engine cannot run: a model that is not a procmod
    Model (a model's name: ``procmod.models.get_model(name)``), a target that is not a
    Target, a seed that is not a non-negative whole number, a budget that is not a
    :class:`Budget` (``parse_budget("30s")`` reads the command line's)."""
    from ..core.model import check_model

    check_model(model)
    check_target(target)
    check_seed(seed)
    if budget is not None and not isinstance(budget, Budget):
        raise InvalidArgumentError(f"budget must be a Budget (e.g. Budget(seconds=30), or "
                                   f"procmod.infer.parse_budget('30s')) or None, got {budget!r:.40}")
    if budget is not None and budget.unlimited:  # the engine would never stop
        raise InvalidArgumentError("Budget() sets no limit: give seconds=, evaluations= or generations=, or pass "
                                   "budget=None for the engine's default")


def recorded_seed(seed):
    """``seed`` as a run's settings record it, in JSON's terms: numpy's integers as ints, a
    sequence of them as a list, a SeedSequence by its entropy (settings.json, reports)."""
    if isinstance(seed, np.random.SeedSequence):
        return recorded_seed(seed.entropy)
    if isinstance(seed, numbers.Integral):
        return int(seed)
    try:
        return [recorded_seed(s) for s in seed]
    except TypeError:
        return seed


def check_target(target) -> None:
    """Refuse, in one line, what is not a target (a picture, a spec string, a mask):
    engines take a :class:`procmod.core.protocols.Target`."""
    if isinstance(target, type):  # the class's methods are there, unbound: configure(model) lacked self
        raise InvalidArgumentError(f"target must be a procmod Target, got the class {target.__name__} (give an "
                                   f"instance of it: {target.__name__}(...))")
    lacking = [m for m in _TARGET_METHODS if not callable(getattr(target, m, None))]
    if lacking:
        raise InvalidArgumentError(
            f"target must be a procmod Target (with {', '.join(_TARGET_METHODS)}), got {type(target).__name__} "
            f"without {', '.join(lacking)}; make one with procmod.data.target_from_spec('glyph:a') or a class of "
            "procmod.targets (ShapeMatch(image), Volume, Silhouette, ...)")
    check_declared(target, Target, "the target")  # every engine, as the GA did alone


def check_positive(name: str, value) -> int:
    """``value`` if it is a positive integer, else an InvalidArgumentError naming ``name``."""
    count = whole_number(value)  # numpy's integers too, as a plain int
    if count is None or count < 1:
        # an argument of the Python API: None as Python writes it, not as JSON's null
        shown = repr(value) if value is None or isinstance(value, bool) else shown_value(value)
        raise InvalidArgumentError(f"{name} must be a positive integer, got {shown}")
    return count


# The note of a run whose best derivation the target rules out (no other was found)
RULED_OUT_NOTE = ("the best derivation found is one the target rules out (zero likelihood: e.g. parts that "
                  "intersect, which a proxy target forbids, though its score does not count them, or parts so far "
                  "outside an image target's canvas that its out-of-bounds penalty is infinite); no derivation it "
                  "allows was found: give the engine more budget, or check the target and the model")

# Said with RULED_OUT_NOTE when the best's parts lie so far outside its canvas that the
# out-of-bounds penalty is infinite (:func:`far_outside`): which of its causes it is (a
# model drawing at 1e300 was told of intersecting parts and a proxy target)
FAR_OUTSIDE_NOTE = ("the best derivation draws parts so far outside the canvas (beyond about 1e151 times its size, "
                    "e.g. a coordinate of 1e300) that the target's out-of-bounds penalty is infinite: its likelihood "
                    "is zero; find the rule's arithmetic that places them there")

# SMC's note when every particle's likelihood went to zero (its log Z is -inf)
ZERO_LIKELIHOOD_NOTE = "every particle reached zero likelihood; the log marginal-likelihood is -inf"

# a run whose complete derivations all scored -inf: none can be its best
NO_FINITE_SCORE_NOTE = ("every complete derivation the engine made scored -inf, so none is a best: the target rules "
                        "out all that the model makes; check the target's score, or that the model can make what it "
                        "asks for")


# the squared distance beyond a canvas from which ShapeMatch's out-of-bounds penalty, that
# square over oob_sigma^2 (0.001^2 by default), is infinite: about 1.3e151
FAR_OUTSIDE_SQUARED = 1.7976931348623157e308 * 1e-6


def far_outside(output) -> bool:
    """Whether ``output`` (a canvas: its ``out_of_bounds()``) draws so far beyond its
    viewport that the out-of-bounds penalty is infinite (a part at 1e300; from about
    1.3e151 at the default oob_sigma, :data:`FAR_OUTSIDE_SQUARED`): a likelihood of zero
    the geometry alone causes."""
    out_of_bounds = getattr(output, "out_of_bounds", None)
    if not callable(out_of_bounds):  # (a volume's scene: no viewport)
        return False
    try:
        ex, ey = (float(e) for e in out_of_bounds())
    except Exception:  # noqa: BLE001 - a note's check must never fail the run
        return False
    # (the penalty divides the square by oob_sigma^2: infinite well before the square is, h158)
    return not ex * ex + ey * ey <= FAR_OUTSIDE_SQUARED


def no_result_error(result: Result) -> InvalidArgumentError:
    """The error for a run that returned no complete derivation: too small a budget, or
    (SMC) every particle ruled out by the target before one was complete, which more of
    the same rarely mends."""
    if ZERO_LIKELIHOOD_NOTE in result.notes:
        return InvalidArgumentError(
            "every particle reached zero likelihood before a derivation was complete: the target rules out what the "
            "model makes at some step (e.g. parts that intersect, which a proxy target forbids, or parts so far "
            "outside an image target's canvas that its out-of-bounds penalty is infinite, as coordinates like 1e300 "
            "are), so more particles or budget rarely help; check the target and the model's arithmetic, or use an "
            "engine that searches on from such states (mcmc, ga)")
    if NO_FINITE_SCORE_NOTE in result.notes:
        return InvalidArgumentError(NO_FINITE_SCORE_NOTE)
    return InvalidArgumentError("the engine found no complete derivation within the budget; give it more")


# Up to this many values log_mean_exp works on Python floats: numpy's per-call overhead
# (~30 us over its four calls, more in a fresh process) is most of a one-particle run's
# end, and short guided runs are timed whole (bench/vs_webppl.py).
SMALL_LOG_MEAN_EXP = 32


def log_mean_exp(values) -> float:
    """log(mean(exp(values))) computed stably; -inf when every value is -inf."""
    if isinstance(values, (list, tuple)) and 0 < len(values) <= SMALL_LOG_MEAN_EXP:
        top = max(values)
        if top == -math.inf:
            return -math.inf
        return float(top + math.log(math.fsum([math.exp(v - top) for v in values]) / len(values)))
    values = np.asarray(values, dtype=np.float64)
    top = values.max()
    if top == -math.inf:
        return -math.inf
    return float(top + math.log(np.mean(np.exp(values - top))))


