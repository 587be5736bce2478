"""Built-in models, by name."""

from __future__ import annotations

from ..core import Model, UnknownModelError
from . import chain, city, lightning, spaceship, tree, vines

MODELS: dict[str, Model] = {m.name: m for m in (chain.MODEL, vines.MODEL, lightning.MODEL, spaceship.MODEL, tree.MODEL, city.MODEL)}


def get_model(name: str) -> Model:
    """The built-in model called ``name``.

    Raises
    ------
    UnknownModelError
        With the list of known names.
    """
    try:
        return MODELS[name]
    except (KeyError, TypeError):
        raise UnknownModelError(
            f"unknown model {name!r}; known models: {', '.join(sorted(MODELS))} "
            "(run 'procmod models' to list them)") from None


__all__ = ["MODELS", "get_model"]
