"""The GA's variation operators (seed 002, section 5), each a function of a parent's
:class:`~.genome.Genome` and a random generator that returns an
:class:`~.genome.Offspring` (None when the parent offers it nothing to do):

* :func:`grow` — express a ``maybe`` child that is off, chosen with probability
  proportional to its spawn probability ``p``; the new call's own parameters are drawn
  from the prior and its own ``maybe`` children start unexpressed (one gene is added);
* :func:`cut` — unexpress a ``maybe`` child that is on, chosen proportionally to ``1 - p``
  (children spawned with probability 1 are never cut), removing its subtree;
* :func:`alter` — pick a call uniformly and redraw all its parameters (its non-structural
  choices) from the prior;
* :func:`nudge` (not in seed 002) — pick a call with continuous choices uniformly and move
  each of them by a Gaussian step of ``step`` x the distribution's scale, reflected into
  its bounds: the GA analogue of an MCMC diffusion move (seed 002, section 7, describes
  diffusion as alter mutations). Alter redraws a call from the prior, so it rarely
  improves a fitted individual; a nudge fine-tunes one;
* :func:`crossover` — pick a connection of the first parent uniformly, a compatible one of
  the second, and swap the subtrees below them, giving two offspring (up to
  ``max_retries`` tries when no compatible connection exists). Connections are compatible
  when they are of one type, an edge of the generator graph: the same parent rule and the
  same child rule, whatever the spawn sites are called (seed 002, section 5: "those that
  describe the same edge in the generator graph"). So sibling sites that spawn one rule
  from one rule pair — the tree's ``b0``/``b1``/``b2`` — and a crossover can copy a
  branch's partial solution onto another branch, which seed 002 (section 8) credits for
  the GA's result on the tree (on procmod's tree scenes it changed nothing measurable:
  bench/shapegenetics.py ``--evaluations``, README). Addresses are structural, so the
  donor's subtree is re-addressed under the receiving site and replayed there: its own
  choices (for the tree, angles, scales and offsets relative to its parent) are kept, the
  arguments it is called with are the receiving parent's, so its geometry is recomputed
  from the new position; choices that the new context no longer reaches are dropped and
  missing ones drawn, as in any replay, so the children are valid derivations. When the
  two subtrees are equal (same rule and arguments at the top, same choices below) the
  children would be copies of their parents: :func:`crossover` returns :data:`COPIES`,
  and the parents join the next generation without an evaluation (in a converging
  population that is a quarter of all crossovers; retrying for a different subtree
  instead was no better: 3960 vs 4092 after 8 CPU-s on spaceship_volume, 16 seeds).

:func:`mutate` picks one of grow, cut, alter and nudge by weight, falling back to the
others when the picked one has nothing to do.

Every offspring is an edit of a parent's choice map; replayed under the model it is a
valid derivation by construction (choices a new context no longer reaches are dropped,
missing ones drawn from the prior). ``Offspring.changed`` names the calls whose choices
differ from the parent's.
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from ...core import InvalidArgumentError
from ...core.errors import argument, shown_value, whole_number
from ...core.runtime import check_rng, same_args
from .genome import DROP, Genome, Offspring

COPIES = "copies"  # what crossover returns when the swap changes nothing


def _genome(g, operator: str) -> Genome:
    """``g`` if it is a :class:`Genome`, else an InvalidArgumentError (a Derivation passed
    as it is had raised an AttributeError inside the operator)."""
    if not isinstance(g, Genome):
        raise InvalidArgumentError(f"{operator} takes a Genome (procmod.infer.ga.genome.Genome(derivation): a "
                                   f"derivation with what the operators read off it), got {type(g).__name__}")
    return g


def check_split(split) -> tuple:
    """``split`` as four weights (grow, cut, alter, nudge), or an InvalidArgumentError."""
    try:
        weights = [float(w) for w in split]
    except (TypeError, ValueError):
        weights = None
    if (weights is None or len(weights) not in (3, 4) or not all(math.isfinite(w) and w >= 0 for w in weights)
            or sum(weights) <= 0):
        raise InvalidArgumentError("split must be three or four finite non-negative weights (grow, cut, alter"
                                   f"[, nudge]) that are not all zero, got {split!r}")
    return tuple(weights) + (0.0,) * (4 - len(weights))


def weighted_pick(items, weights, rng):
    """One of ``items``, with probability proportional to its weight (None when there are
    no items or no positive weight; then ``rng`` is not drawn from)."""
    total = float(sum(weights))
    if not items or total <= 0:
        return None
    u = rng.random() * total
    acc = 0.0
    for item, w in zip(items, weights):
        acc += w
        if u < acc:
            return item
    return items[-1]


def grow(g: Genome, rng, count: int = 1) -> Offspring | None:
    """Turn on unexpressed ``maybe`` children, each picked with probability proportional
    to its spawn probability (None if there is none). ``count`` > 1 turns on that many at
    once (successive picks without replacement), used to build the initial population
    without one replay per added call."""
    _genome(g, "grow")
    check_rng(rng, "grow")
    if whole_number(count) is None or count < 1:
        raise InvalidArgumentError(f"grow turns on {argument('count')} children, one or more, got {shown_value(count)}")
    count = int(count)
    sites = g.grow_sites()
    if count == 1:
        picks = [weighted_pick(sites, [p for _, _, p in sites], rng)]
    else:  # successive picks without replacement, proportional to p (numpy: not quadratic)
        weights = np.array([p for _, _, p in sites], dtype=np.float64)
        live = np.flatnonzero(weights > 0)
        k = min(count, len(live))
        picks = ([sites[i] for i in rng.choice(live, size=k, replace=False, p=weights[live] / weights[live].sum())]
                 if k else [])
    changes, changed = {}, set()
    for pick in picks:
        if pick is not None:
            changes[(pick[0], pick[1])] = True
            changed.add(pick[0])
    return Offspring(g, changes, changed) if changes else None


def cut(g: Genome, rng) -> Offspring | None:
    """Turn off one expressed ``maybe`` child, picked with probability proportional to
    ``1 - p``, and drop its subtree (None if nothing can be cut)."""
    _genome(g, "cut")
    check_rng(rng, "cut")
    sites = g.cut_sites()
    pick = weighted_pick(sites, [1.0 - p for _, _, p in sites], rng)
    if pick is None:
        return None
    return Offspring(g, {(pick[0], pick[1]): False}, {pick[0]}, at=pick[0] + (pick[1],))


def alter(g: Genome, rng) -> Offspring | None:
    """Remove all parameters of one call, picked uniformly, so that replay redraws them
    from the prior (None if no call has parameters)."""
    _genome(g, "alter")
    check_rng(rng, "alter")
    candidates = g.alter_sites()
    if not candidates:
        return None
    address, names = candidates[int(rng.random() * len(candidates))]
    return Offspring(g, {(address, name): DROP for name in names}, {address})


def reflect(x: float, low: float, high: float) -> float:
    """``x`` folded into ``[low, high]`` by reflection at the bounds; an infinite bound
    reflects nothing (a TruncatedNormal may have one: the fold of width infinity had made
    every nudged value NaN or infinite, which the replay then redrew from the prior)."""
    low_finite, high_finite = math.isfinite(low), math.isfinite(high)
    if not low_finite and not high_finite:
        return x
    if not high_finite:
        return low + abs(x - low)
    if not low_finite:
        return high - abs(high - x)
    width = high - low
    if width <= 0:
        return low
    y = (x - low) % (2.0 * width)
    return low + (y if y <= width else 2.0 * width - y)


def nudge(g: Genome, rng, step: float = 0.1) -> Offspring | None:
    """Move each continuous parameter of one call, picked uniformly, by a Gaussian step of
    ``step`` x its distribution's scale, reflected into its bounds (None if no call has
    continuous parameters)."""
    _genome(g, "nudge")
    check_rng(rng, "nudge")
    if isinstance(step, bool) or not isinstance(step, numbers.Real) or not (math.isfinite(step) and step >= 0):
        raise InvalidArgumentError(f"{argument('step')} of a nudge must be a finite number of scales, 0 or more, "
                                   f"got {shown_value(step)}")
    candidates = g.nudge_sites()
    if not candidates:
        return None
    address, choices = candidates[int(rng.random() * len(candidates))]
    changes = {}
    for name, value, scale, low, high in choices:
        x = value + step * scale * rng.standard_normal()
        if low is not None and high is not None:
            x = reflect(x, low, high)
        changes[(address, name)] = x
    return Offspring(g, changes, {address})


def mutate(g: Genome, rng, split, step: float = 0.1) -> Offspring | None:
    """One mutation of ``g``: grow, cut, alter or nudge, picked with probability
    proportional to ``split`` (four weights, in that order); when the picked one has
    nothing to do, the others with a positive weight are tried in that order. None when
    none applies."""
    check_rng(rng, "mutate")
    split = check_split(split)  # (three weights, as ga() takes: no nudge)
    operators = (grow, cut, alter, lambda g, rng: nudge(g, rng, step))
    first = weighted_pick([0, 1, 2, 3], split, rng)
    for k in [first] + [k for k in (0, 1, 2, 3) if k != first and split[k] > 0]:
        child = operators[k](g, rng)
        if child is not None:
            return child
    return None


def same_subtree(g1: Genome, a1: tuple, g2: Genome, a2: tuple) -> bool:
    """Whether the subtree of ``g1`` at ``a1`` equals that of ``g2`` at ``a2`` (same rule and
    arguments at the top, same rules and choice values below): swapping them changes nothing."""
    i1, i2 = g1.index(), g2.index()
    x, y = i1[a1], i2[a2]
    if x.rule is not y.rule or not same_args(x.args, y.args):
        return False
    stack = [(x, y)]
    while stack:
        x, y = stack.pop()
        if x.rule is not y.rule or len(x.choices) != len(y.choices):
            return False
        yc = y.choices
        for name, c in x.choices.items():
            d = yc.get(name)
            if d is None or d.value != c.value:
                return False
        for spawn in x.spawns:
            if spawn.on:
                cx, cy = i1.get(x.address + (spawn.site,)), i2.get(y.address + (spawn.site,))
                if cx is None or cy is None:  # a call that never ran (a stopped derivation)
                    return False
                stack.append((cx, cy))
    return True


def crossover(g1: Genome, g2: Genome, rng, max_retries: int = 10):
    """Two offspring by swapping the subtrees below a connection of ``g1`` and one of the
    same type (generator-graph edge) of ``g2``: ``(child of g1, child of g2)``, each its
    parent but below the swapped connection. :data:`COPIES` when the two subtrees are
    equal (the children would be the parents), None when ``max_retries`` random
    connections of ``g1`` found no match in ``g2``."""
    _genome(g1, "crossover")
    _genome(g2, "crossover")
    check_rng(rng, "crossover")
    c1 = [(key, a) for key, addresses in g1.connections().items() for a in addresses]
    if not c1:
        return None
    c2 = g2.connections()
    for _ in range(max_retries):
        key, a1 = c1[int(rng.random() * len(c1))]
        matches = c2.get(key)
        if not matches:
            continue
        a2 = matches[int(rng.random() * len(matches))]
        if same_subtree(g1, a1, g2, a2):  # the children are copies of the parents
            return COPIES
        n1, n2 = len(a1), len(a2)
        # Child i differs from parent i only below the swapped connection.
        return (Offspring(g1, changed={a for a in g1.index() if a[:n1] == a1}, at=a1, donor=g2, source=a2),
                Offspring(g2, changed={a for a in g2.index() if a[:n2] == a2}, at=a2, donor=g1, source=a1))
    return None
