"""Package attributes imported on first use (PEP 562), so the command line starts fast.

``procmod --help`` must not wait for torch, scipy, trimesh or numba kernels; the
subsystem packages (``procmod.geometry``, ``guide``, ``learn``, ``strings``) therefore
name their public attributes in a table and import the submodule that holds one only
when it is first looked up.
"""

from __future__ import annotations

import importlib


def lazy_getattr(package: str, table: dict, namespace: dict):
    """A module ``__getattr__`` serving ``table`` (attribute name -> submodule name).

    The value is cached in ``namespace`` (the package's ``globals()``), so later lookups
    skip the hook. No submodule may share a name with an attribute of ``table``: importing
    it would rebind the package attribute to the module.
    """
    def __getattr__(name):
        module = table.get(name)
        if module is None:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(f".{module}", package), name)
        namespace[name] = value
        return value

    return __getattr__
