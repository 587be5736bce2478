"""Symmetries of typed shape graphs: the automorphisms that keep node types."""

from __future__ import annotations

import networkx as nx


def type_automorphisms(g: nx.Graph, limit: int = 64) -> list[dict]:
    """The automorphisms of ``g`` that keep node types (``{node: node}``), the identity
    first, at most ``limit`` of them.

    A string names its graph only up to these: a ring's parts look alike to it, so which of
    them the shape's corners are is arbitrary. Two edge labellings related by one describe
    the same shape (each part where its image was), and the tagger's targets and accuracy
    count them as equal. ``limit`` bounds the cost where many parts are interchangeable
    (a part with k alike leaves alone has k! of them); the first ones found are kept."""
    identity = {v: v for v in g.nodes}
    out = [identity]
    matcher = nx.algorithms.isomorphism.GraphMatcher(g, g, node_match=lambda a, b: a["type"] == b["type"])
    for mapping in matcher.isomorphisms_iter():
        if len(out) >= limit:
            break
        if mapping != identity:
            out.append(mapping)
    return out
