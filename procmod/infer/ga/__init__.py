"""``ga``: the genetic algorithm of ShapeGenetics (seed 002, sections 4-6).

The genome is the derivation tree itself (:mod:`.genome`): an individual is a complete
derivation, and every genetic operation edits its choice map and replays it under the
model, so every offspring is a valid derivation by construction. The algorithm is three
kinds of named functions composed by a short generational loop (:func:`ga`, in
:mod:`.engine`):

* **selection** (:mod:`.selection`) — one parent by :func:`roulette` wheel on fitness
  shifted to be non-negative (``score - min score``), the other by k-:func:`tournament`
  (k = 10); the best fifth of the population is kept unchanged (:func:`elite_count`);
* **variation** (:mod:`.variation`) — with probability 30% both parents are mutated
  (:func:`mutate`: :func:`grow`, :func:`cut`, :func:`alter` split 13.5 / 13.5 / 3.0, and
  :func:`nudge`, weight 0 unless ``split`` has a fourth entry), otherwise they are
  crossed over (:func:`crossover` at connections of one generator-graph edge);
* **evaluation** (:mod:`.evaluation`) — offspring are replayed and scored, incrementally
  from their parent (:func:`evaluate_from`) where the target's score survives removing
  parts exactly and no executor is given, else by full replays through the executor.

The initial population (:func:`initial_population`) starts from minimal derivations
(every ``maybe`` off) grown repeatedly to random sizes.
"""

from .engine import breed, default_initial_size, ga, initial_population
from .evaluation import Evaluator, LazyRng, evaluate_from, reusable
from .genome import DROP, Genome, Genomes, Offspring
from .selection import elite_count, roulette, roulette_wheel, tournament
from .variation import (COPIES, alter, crossover, cut, grow, mutate, nudge, reflect, same_subtree,
                        weighted_pick)

__all__ = ["COPIES", "DROP", "Evaluator", "Genome", "Genomes", "LazyRng", "Offspring", "alter",
           "breed", "crossover", "cut", "default_initial_size", "elite_count", "evaluate_from", "ga", "grow",
           "initial_population", "mutate", "nudge", "reflect", "reusable", "roulette", "roulette_wheel",
           "same_subtree", "tournament", "weighted_pick"]
