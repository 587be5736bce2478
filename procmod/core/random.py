"""A numpy Generator whose scalar draws come from blocks: for engines' hot loops.

``numpy.random.Generator.random()`` costs about a microsecond per call, most of it call
overhead; SMC makes a few such draws per particle-step, so a tenth of its budget. A
:class:`BlockGenerator` draws ``block`` uniforms (or standard normals) at a time and hands
them out one by one. It is deterministic given the generator's seed, like the generator
itself, but its stream differs from the generator's own scalar calls (blocks of each kind
are drawn when first needed). Everything else (arrays, ``integers``, ``choice``, ...) is
passed to the wrapped generator.

:func:`resample` draws the ancestor indices of a particle population (systematic,
multinomial or residual), for every particle method: SMC and learn's structure search.

:func:`global_draws_note` says when a run moved Python's or numpy's global generators,
which procmod never draws from: a model's rule did.
"""

from __future__ import annotations

import random

import numpy as np

from .errors import InvalidArgumentError


def check_seed(seed, name: str = "seed") -> None:
    """Refuse, in one line, a seed numpy's generators do not take: they take a
    non-negative whole number, a sequence or array of them (a worker's ``(seed, index)``)
    and a SeedSequence."""
    if isinstance(seed, np.random.SeedSequence):
        return
    try:
        np.random.SeedSequence(seed)  # a 0-d array is refused: smc's workers index the seed
    except (TypeError, ValueError):
        shown = " ".join(repr(seed).split())[:40]
        raise InvalidArgumentError(f"{name} must be a non-negative whole number (or a sequence of them), got "
                                   f"{type(seed).__name__} {shown}") from None


def global_generator_states() -> tuple:
    """The states of Python's ``random`` module and of numpy's global (legacy) generator,
    to compare before and after a run (:func:`global_draws_note`): procmod draws from
    explicit generators only, so a change is a model's (or a user target's) doing."""
    legacy = np.random.get_state()  # ("MT19937", keys, position, has_gauss, cached_gaussian)
    return random.getstate(), legacy[1].tobytes(), legacy[2:]


def global_draws_note(before: tuple, who: str = "the model's rules (or the target's score)") -> str | None:
    """A note when Python's ``random`` or numpy's global generator has moved since
    ``before`` (:func:`global_generator_states`), else None; ``who`` is what drew.

    A rule that draws from them is not reproducible by seed, and its draws are not choices:
    engines can neither steer nor replay them, and SMC re-runs a call from its start when it
    resumes it after an emit, so it draws again and the geometry disagrees with the score.
    Seen in the process that runs the engine (whose own share of the particles or chains
    runs rules too); a rule that draws only in a worker process is not seen.
    """
    after = global_generator_states()
    moved = [name for name, a, b in (("Python's random module", before[0], after[0]),
                                     ("numpy's global generator (np.random.*)", before[1:], after[1:])) if a != b]
    if not moved:
        return None
    return (f"{who} drew from {' and '.join(moved)} during this run: those draws "
            "are not random choices, so the seed does not fix them, engines cannot steer them, and a call resumed "
            "after an emit draws them again (its drawing then disagrees with its score); draw every random value "
            "with ctx.sample")


class BlockGenerator:
    """``generator`` with block-buffered scalar ``random()`` and ``standard_normal()``.

    Blocks start at ``first`` numbers and double at each refill up to ``block``: a short
    run (an unguided 1-particle SMC run makes a few dozen draws in ~0.2 ms) does not pay
    for thousands it never uses (two 4096-number blocks cost ~0.1-0.15 ms), and a long
    run's draws still come in full blocks.
    """

    __slots__ = ("generator", "block", "_uniforms", "_normals", "_next_sizes")

    def __init__(self, generator: np.random.Generator, block: int = 4096, first: int = 32):
        self.generator = generator
        self.block = int(block)
        self._uniforms = []
        self._normals = []
        self._next_sizes = [min(int(first), self.block)] * 2  # uniforms', normals'

    def _refill_size(self, kind: int) -> int:
        size = self._next_sizes[kind]
        self._next_sizes[kind] = min(2 * size, self.block)
        return size

    def random(self, size=None, *args, **kwargs):
        """A uniform in [0, 1) (from the block), or ``generator.random(size, ...)``."""
        if size is not None or args or kwargs:
            return self.generator.random(size, *args, **kwargs)
        u = self._uniforms
        if not u:
            u.extend(self.generator.random(self._refill_size(0)).tolist())
        return u.pop()

    def standard_normal(self, size=None, *args, **kwargs):
        """A standard normal (from the block), or ``generator.standard_normal(size, ...)``."""
        if size is not None or args or kwargs:
            return self.generator.standard_normal(size, *args, **kwargs)
        z = self._normals
        if not z:
            z.extend(self.generator.standard_normal(self._refill_size(1)).tolist())
        return z.pop()

    def __getattr__(self, name):
        return getattr(self.generator, name)


class LazyGenerator:
    """``numpy.random.default_rng(seed)``, built when first used.

    Building a generator costs about 8 us, as much as a tenth of an MCMC move, and most
    moves replay a derivation without drawing anything fresh. The draws, when there are
    any, are the generator's own: the same stream as ``default_rng(seed)``.
    """

    def __init__(self, seed):
        self._seed = seed
        self._generator = None

    def __getattr__(self, name):  # only for what is not bound on the instance yet
        if name.startswith("__"):  # copy / pickle probes: not the generator's business
            raise AttributeError(name)
        generator = self._generator
        if generator is None:
            generator = self._generator = np.random.default_rng(self._seed)
        value = getattr(generator, name)
        self.__dict__[name] = value  # later look-ups find the bound method at once
        return value


RESAMPLING = ("systematic", "multinomial", "residual")


def normalised_weights(log_weights: np.ndarray) -> np.ndarray:
    """``exp(log_weights)`` scaled to sum to one (computed from the largest, so large
    log-weights do not overflow)."""
    top = log_weights.max()
    w = np.exp(log_weights - top)
    return w / w.sum()


def resample(log_weights: np.ndarray, rng: np.random.Generator, method: str = "systematic",
             count: int | None = None) -> np.ndarray:
    """Ancestor indices for ``count`` offspring (default ``len(log_weights)``), sorted.

    ``systematic`` uses one uniform for evenly spaced pointers (lower variance);
    ``multinomial`` draws every offspring independently; ``residual`` keeps
    ``floor(count w_i)`` copies of each and draws the rest multinomially from what is left
    (WebPPL's scheme).
    """
    n = len(log_weights)
    m = n if count is None else count
    w = normalised_weights(np.asarray(log_weights, dtype=np.float64))
    if method == "systematic":
        pointers = (rng.random() + np.arange(m)) / m
    elif method == "multinomial":
        pointers = np.sort(rng.random(m))
    elif method == "residual":
        # Liu (2008) 3.4.4, as WebPPL: floor(m w_i) copies of each particle, the rest
        # drawn multinomially from the residual weights.
        kept = np.floor(m * w).astype(np.int64)
        rest = m - int(kept.sum())
        out = np.repeat(np.arange(n), kept)
        if rest > 0:
            residual = m * w - kept
            cum = np.cumsum(residual / residual.sum())
            cum[-1] = 1.0
            extra = np.minimum(np.searchsorted(cum, rng.random(rest), side="right"), n - 1)
            out = np.sort(np.concatenate([out, extra]))
        return out
    else:
        raise InvalidArgumentError(f"resampling must be one of {', '.join(RESAMPLING)}, got {method!r}")
    cumulative = np.cumsum(w)
    cumulative[-1] = 1.0
    return np.minimum(np.searchsorted(cumulative, pointers, side="right"), n - 1)


def systematic_small(weights: list, total: float, rng) -> list:
    """Systematic resampling of a short list of (unnormalised) weights: the ancestors
    :func:`resample` picks for them, from the same single uniform."""
    n = len(weights)
    u = rng.random()
    cumulative = []
    acc = 0.0
    for w in weights:
        acc += w / total
        cumulative.append(acc)
    cumulative[-1] = 1.0
    out = []
    j = 0
    for k in range(n):
        pointer = (u + k) / n
        while j < n - 1 and cumulative[j] <= pointer:
            j += 1
        out.append(j)
    return out
