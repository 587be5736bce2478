"""The GA's genome: an individual's derivation as the operators read it, and an
offspring as a few edits of its parent's choice map.

The genome is the derivation tree itself (seed 002, section 4): every call is a gene,
its choices are the gene's parameters, and a spawned call's link to its parent is a
*connection*, typed by its edge of the generator graph (parent rule, child rule).
Operators never copy choice maps: an :class:`Offspring` is its parent's map plus a few
edits, looked up lazily and materialized only for a full replay.
"""

from __future__ import annotations

from ...core import InvalidArgumentError
from ...core.runtime import Derivation

DROP = object()  # an Offspring edit that removes a choice (replay draws it afresh)
_MISSING = object()


class Genome:
    """What the operators read off one individual, computed once: its nodes, choice map
    (a dict the operators copy, never change), connections and mutation sites. The GA
    keeps one per individual (:class:`Genomes`), so a parent selected several times is
    indexed once."""

    __slots__ = ("d", "_nodes", "_raw", "_index", "_connections", "_grow", "_cut", "_alter", "_nudge")

    def __init__(self, d):
        if not isinstance(d, Derivation):  # (h82: an AttributeError inside the first operator)
            raise InvalidArgumentError(f"a Genome wraps a derivation (procmod.core.Derivation), got "
                                       f"{type(d).__name__}")
        self.d = d
        self._nodes = self._raw = self._index = self._connections = self._grow = self._cut = self._alter = None
        self._nudge = None

    def nodes(self) -> list:
        if self._nodes is None:
            self._nodes = self.d.nodes()
        return self._nodes

    def index(self) -> dict:
        """``node address -> node``, in program order."""
        if self._index is None:
            self._index = {n.address: n for n in self.nodes()}
        return self._index

    def get(self, key, default=None):
        """The value of choice ``key`` (a choice-map lookup without building the map)."""
        node = self.index().get(key[0])
        if node is None:
            return default
        choice = node.choices.get(key[1])
        return default if choice is None else choice.value

    def raw(self) -> dict:
        """The choice map ``(address, name) -> value``, built once."""
        if self._raw is None:
            self._raw = {(n.address, name): c.value for n in self.nodes() for name, c in n.choices.items()}
        return self._raw

    def connections(self) -> dict:
        """``(parent rule, child rule) -> [child addresses]``: the connections grouped by
        type (generator-graph edge, whatever the spawn site is called), the sets crossover
        pairs within."""
        if self._connections is None:
            rules = {n.address: n.rule for n in self.nodes()}
            out = {}
            for n in self.nodes():
                if n.address:  # the type of a connection: its generator-graph edge, not its site
                    out.setdefault((rules[n.address[:-1]], n.rule), []).append(n.address)
            self._connections = out
        return self._connections

    def grow_sites(self) -> list:
        """``(address, site, p)`` of the ``maybe`` children that are off."""
        if self._grow is None:
            self._grow = [(n.address, s.site, s.probability) for n in self.nodes() for s in n.spawns if not s.on]
        return self._grow

    def cut_sites(self) -> list:
        """``(address, site, p)`` of the ``maybe`` children that are on and could be off (p < 1)."""
        if self._cut is None:
            self._cut = [(n.address, s.site, s.probability) for n in self.nodes() for s in n.spawns
                         if s.on and s.probability < 1.0]
        return self._cut

    def alter_sites(self) -> list:
        """``(address, [choice names])`` of the calls with non-structural choices."""
        if self._alter is None:
            out = []
            for n in self.nodes():
                structural = {s.site for s in n.spawns}
                names = [name for name in n.choices if name not in structural]
                if names:
                    out.append((n.address, names))
            self._alter = out
        return self._alter

    def nudge_sites(self) -> list:
        """``(address, [(name, value, scale, low, high)])`` of the calls with continuous
        choices (float values of non-discrete distributions that have a scale; ``low`` and
        ``high`` are the bounds, None when the distribution has none)."""
        if self._nudge is None:
            out = []
            for n in self.nodes():
                structural = {s.site for s in n.spawns}
                cont = []
                for name, c in n.choices.items():
                    dist = c.dist
                    if name in structural or dist.discrete or not isinstance(c.value, float):
                        continue
                    try:
                        scale = float(dist.scale)
                    except NotImplementedError:
                        continue
                    cont.append((name, c.value, scale, dist.low, dist.high))
                if cont:
                    out.append((n.address, cont))
            self._nudge = out
        return self._nudge


class Genomes:
    """The :class:`Genome` of each individual of the current population, by derivation."""

    def __init__(self):
        self._by_id = {}

    def of(self, d) -> Genome:
        g = self._by_id.get(id(d))
        if g is None or g.d is not d:  # an id reused by a new derivation
            g = self._by_id[id(d)] = Genome(d)
        return g

    def keep(self, derivations) -> None:
        """Forget the genomes of all but ``derivations`` (the next population)."""
        self._by_id = {id(d): self._by_id[id(d)] for d in derivations if id(d) in self._by_id}


class Offspring:
    """An offspring's choice map as edits of its parent's, built lazily.

    Lookups go to ``changes`` (a value, or ``DROP`` for a removed choice), then — for
    addresses below ``at`` — to ``donor`` (a Genome) at ``source`` (a crossover graft; no
    donor: the subtree is cut), then to ``base`` (the parent's Genome). So an operator costs
    O(edits), not O(choice map). ``changed`` lists the calls whose choices differ from the
    parent's (what an incremental evaluation runs again). :meth:`materialize` builds the
    full dict (what full replays use).
    """

    __slots__ = ("base", "changes", "at", "donor", "source", "changed")

    def __init__(self, base: Genome, changes=None, changed=(), at=None, donor=None, source=None):
        self.base, self.changes, self.at, self.donor, self.source = base, changes or {}, at, donor, source
        self.changed = changed

    def get(self, key, default=None):
        value = self.changes.get(key, _MISSING)
        if value is not _MISSING:
            return default if value is DROP else value
        at = self.at
        if at is not None and key[0][:len(at)] == at:
            if self.donor is None:
                return default
            return self.donor.get((self.source + key[0][len(at):], key[1]), default)
        return self.base.get(key, default)

    def __contains__(self, key) -> bool:
        return self.get(key, _MISSING) is not _MISSING

    def __setitem__(self, key, value) -> None:
        self.changes[key] = value

    def materialize(self) -> dict:
        """The offspring's full choice map."""
        at = self.at
        if at is None:
            out = dict(self.base.raw())
        else:
            m = len(at)
            out = {k: v for k, v in self.base.raw().items() if k[0][:m] != at}
            if self.donor is not None:
                source, n = self.source, len(self.source)
                for (address, name), value in self.donor.raw().items():
                    if address[:n] == source:
                        out[(at + address[n:], name)] = value
        for key, value in self.changes.items():
            if value is DROP:
                out.pop(key, None)
            else:
                out[key] = value
        return out
