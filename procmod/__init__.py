"""procmod: probabilistic procedural modeling.

Write a procedural model once as plain Python rules, sample it, control it toward a goal
with any engine, and learn new models from examples. See README.md and DESIGN.md.
"""

from .core import *  # noqa: F401,F403  (the runtime is procmod's public core API)
from .core import __all__ as _core_all

__version__ = "0.1.0"
__all__ = list(_core_all) + ["__version__"]
