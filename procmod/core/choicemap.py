"""Choice maps: the random choices of a derivation keyed by structural address.

An address is ``(node_address, choice_name)`` where ``node_address`` is the tuple of
spawn-site names leading from the root rule call to the call that made the choice. The
root call's address is ``()``. Because addresses are structural, a choice keeps its
address when another subtree of the derivation changes, so replay lines choices up.
"""

from __future__ import annotations

from typing import Any, Iterator, Mapping

NodeAddress = tuple
ChoiceAddress = tuple  # (NodeAddress, str)


def format_address(node_address: NodeAddress, name: str | None = None) -> str:
    """Human-readable form ``/site/site#choice`` used in messages."""
    path = "/" + "/".join(node_address)
    return path if name is None else f"{path}#{name}"


def is_within(node_address: NodeAddress, subtree: NodeAddress) -> bool:
    """True if ``node_address`` is ``subtree`` itself or lies below it."""
    return node_address[: len(subtree)] == subtree


class ChoiceMap(Mapping):
    """An immutable-by-convention mapping ``(node_address, name) -> value``."""

    __slots__ = ("_values",)

    def __init__(self, values: Mapping[ChoiceAddress, Any] | None = None):
        self._values = dict(values or {})

    def __getitem__(self, key):
        return self._values[key]

    def __iter__(self) -> Iterator[ChoiceAddress]:
        return iter(self._values)

    def __len__(self) -> int:
        return len(self._values)

    def __repr__(self) -> str:
        items = ", ".join(f"{format_address(a, n)}={v!r}" for (a, n), v in self._values.items())
        return f"ChoiceMap({items})"

    @property
    def raw(self) -> dict:
        """The underlying dict (read it, do not modify it)."""
        return self._values

    def with_value(self, node_address: NodeAddress, name: str, value) -> "ChoiceMap":
        """A copy with one choice set (added or replaced)."""
        values = dict(self._values)
        values[(tuple(node_address), name)] = value
        return ChoiceMap(values)

    def without_subtree(self, subtree: NodeAddress) -> "ChoiceMap":
        """A copy without the choices made at ``subtree`` or anywhere below it."""
        subtree = tuple(subtree)
        return ChoiceMap({k: v for k, v in self._values.items() if not is_within(k[0], subtree)})
