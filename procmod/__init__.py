"""procmod: probabilistic procedural modeling.

Write a procedural model once as plain Python rules, sample it, control it toward a goal
with any engine, and learn new models from examples. See README.md and DESIGN.md.
"""

import os as _os
import sys as _sys
import tempfile as _tempfile


def _writable_folder(folder: str) -> bool:
    """Whether files can be made in ``folder`` (made if missing), tested as numba tests it."""
    try:
        _os.makedirs(folder, exist_ok=True)
        _tempfile.TemporaryFile(dir=folder).close()
        return True
    except OSError:
        return False


def _numba_cache_fallback() -> None:
    """Give numba a private cache folder where it would find none.

    procmod's kernels are ``numba.njit(cache=True)``; numba keeps their machine code in the
    ``__pycache__`` beside each module, else in the user's cache folder (``~/.cache/numba``),
    and where neither can be written (a read-only install run with an unwritable or missing
    home folder: a service account, a container run as another user) it raised a RuntimeError
    when procmod was imported, a traceback for every command. Then the kernels are cached
    in a temporary folder of this process's (removed at exit), handed on to worker processes
    through ``NUMBA_CACHE_DIR``."""
    if _os.environ.get("NUMBA_CACHE_DIR") or _writable_folder(
            _os.path.join(_os.path.dirname(_os.path.abspath(__file__)), "geometry", "__pycache__")):
        return
    if _sys.platform.startswith("linux"):  # numba's user cache folder (numba.misc.appdirs: importing it loads numba)
        user_wide = _os.path.join(_os.getenv("XDG_CACHE_HOME", _os.path.expanduser("~/.cache")), "numba")
    elif _sys.platform == "darwin":
        user_wide = _os.path.expanduser("~/Library/Caches/numba")
    else:  # (Windows: a folder of the user's profile, as writable as the user)
        return
    if _os.path.isabs(user_wide) and _writable_folder(user_wide):  # (not "~/.cache" without a home)
        return
    import atexit
    import shutil

    folder = _tempfile.mkdtemp(prefix="procmod-numba-")
    atexit.register(shutil.rmtree, folder, ignore_errors=True)
    _os.environ["NUMBA_CACHE_DIR"] = folder
    if "numba.core.config" in _sys.modules:  # numba already read its settings: tell it too
        _sys.modules["numba.core.config"].CACHE_DIR = folder


_numba_cache_fallback()

from .core import *  # noqa: F401,F403,E402  (the runtime is procmod's public core API)
from .core import __all__ as _core_all

__version__ = "0.1.0"
__all__ = list(_core_all) + ["__version__"]
