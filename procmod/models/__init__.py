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


def model_from_spec(spec: str) -> Model:
    """A built-in model by name, or a model of the user's own Python file (``FILE.py:NAME``
    or ``FILE.py``, :mod:`procmod.models.from_file`): what ``procmod guide`` takes."""
    if isinstance(spec, str) and spec not in MODELS:
        from .from_file import is_model_file_spec, load_model_file

        if is_model_file_spec(spec):
            return load_model_file(spec)
    return get_model(spec)


__all__ = ["MODELS", "get_model", "model_from_spec"]
