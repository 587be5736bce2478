"""procmod's file I/O recipes, each written once: atomic writes, JSON reading, tensors.

**Atomic writes.** Every file procmod writes goes through :func:`open_atomic`: a temporary
file beside the target (``.NAME.XXXX.tmp``, in the same folder so the rename never crosses
file systems), renamed over the target with :func:`os.replace` once it is whole. A reader
(or a kill mid-write) sees the old file or the new one, never half of one; a writer that
raises leaves the old file and no temporary behind. :func:`write_bytes_atomic`,
:func:`write_text_atomic`, :func:`save_image_atomic`, :func:`save_figure_atomic` and
:func:`save_tensors` are built on it.

**JSON.** :func:`read_json` and :func:`read_versioned_json` turn every way a file fails
(missing, unreadable, not UTF-8, bad syntax, nested deeper than Python's stack, the wrong
``"format"``) into one line of the caller's :class:`ProcmodError` subclass naming the file.

**Tensors.** :func:`load_tensors` is the only place procmod calls ``torch.load``: always
with ``weights_only=True`` (a file holding Python objects, which could run code when
unpickled, is refused), every refusal one line. torch is imported inside the tensor
functions, so importing this module (and ``procmod``) stays light.

This module imports nothing of procmod but :mod:`procmod.core.errors`.
"""

from __future__ import annotations

import codecs
import contextlib
import hashlib
import io
import json
import math
import os
import re
import tempfile
from pathlib import Path
from typing import Iterator

from .errors import DerivationFormatError, ProcmodError, cut_text, shown_value
from .limits import format_bytes


MAX_JSON_BYTES = 10 ** 9  # a JSON file procmod reads (a .gltf with embedded buffers is the largest kind)


def _current_umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


# Read once at import: os.umask can only be read by setting it, which is not thread-safe.
_UMASK = _current_umask()


# ---- atomic writes -----------------------------------------------------------------------------

# what tempfile adds to a prefix: 8 random characters, then the suffix (".tmp", ".old")
_TEMPORARY_EXTRA = 8 + len(".tmp")
_NAME_MAX_FALLBACK = 255  # bytes a file name may hold on the common file systems


def hidden_temporary_prefix(path: Path) -> str:
    """The prefix of a hidden temporary beside ``path`` (``.NAME.``, for ``tempfile``'s
    ``prefix=``), with NAME shortened where the whole temporary name would be longer
    than the file system allows: a name a few characters under the limit is the user's
    to give, and had been refused because of a file they never asked for."""
    try:
        name_max = os.pathconf(path.parent, "PC_NAME_MAX")
    except (OSError, ValueError, AttributeError):  # a folder not made yet, or no pathconf (Windows)
        name_max = _NAME_MAX_FALLBACK
    room = name_max - len(b"..") - _TEMPORARY_EXTRA
    # counted in bytes, as the file system counts; a cut through a character leaves bytes a
    # file name may hold all the same (os.fsdecode keeps them as they are)
    return f".{os.fsdecode(os.fsencode(path.name)[:max(room, 1)])}."


@contextlib.contextmanager
def open_atomic(path: str | os.PathLike, mode: str = "wb", fsync: bool = False) -> Iterator:
    """A file handle whose contents replace ``path`` when the ``with`` block ends.

    Parameters
    ----------
    path : str or os.PathLike
        The file to write; its folder must exist.
    mode : {"wb", "w"}
        Binary, or text (UTF-8, the platform's newlines).
    fsync : bool
        Flush the file (and then its folder) to disk before returning, for files that must
        survive a power cut, not only a killed process.

    The data go to a temporary file in ``path``'s folder that is renamed over ``path``
    (:func:`os.replace`) once the block ends normally; if the block raises, the temporary
    file is removed and ``path`` is left as it was. The file gets the usual permissions
    (``0666`` less the umask), not :func:`tempfile.mkstemp`'s ``0600``.
    """
    if mode not in ("wb", "w"):
        raise ValueError(f"open_atomic writes in mode 'wb' or 'w', not {mode!r}")
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=hidden_temporary_prefix(path), suffix=".tmp", dir=path.parent)
    try:
        # a file name of bytes that are not UTF-8 (b"\xff") reaches text as a lone surrogate;
        # written back as those bytes, not a UnicodeEncodeError traceback
        text = {"encoding": "utf-8", "errors": "surrogateescape"}
        with os.fdopen(fd, mode, **(text if mode == "w" else {})) as handle:
            yield handle
            if fsync:
                handle.flush()
                os.fsync(handle.fileno())
        os.chmod(tmp, 0o666 & ~_UMASK)
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise
    if fsync:
        _fsync_folder(path.parent)


def _fsync_folder(folder: Path) -> None:
    # the rename is durable only once the folder's entry is on disk; not every system
    # lets a folder be opened for this (Windows), and there the rename is all we can do
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def write_bytes_atomic(path: str | os.PathLike, data: bytes, fsync: bool = False) -> None:
    """Write ``data`` to ``path`` atomically (see :func:`open_atomic`)."""
    with open_atomic(path, "wb", fsync) as handle:
        handle.write(data)


def write_text_atomic(path: str | os.PathLike, text: str, fsync: bool = False) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically (see :func:`open_atomic`)."""
    with open_atomic(path, "w", fsync) as handle:
        handle.write(text)


def save_image_atomic(image, path: str | os.PathLike) -> None:
    """Save a PIL image as PNG, atomically; the same image gives the same bytes."""
    buffer = io.BytesIO()
    image.save(buffer, format="PNG", optimize=False)
    write_bytes_atomic(path, buffer.getvalue())


def save_figure_atomic(fig, path: str | os.PathLike, dpi: int = 110) -> None:
    """Save a matplotlib figure as PNG, atomically (no timestamp or software tag in the
    file, so the same figure gives the same bytes)."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi, metadata={"Software": None})
    write_bytes_atomic(path, buffer.getvalue())


def fingerprint(data: bytes | str) -> str:
    """A short content digest (16 hex digits of SHA-256): a checkpoint stores the one of its
    training data, so a resume on other data is refused instead of silently mixed."""
    return hashlib.sha256(data.encode() if isinstance(data, str) else data).hexdigest()[:16]


# ---- JSON --------------------------------------------------------------------------------------

def standard_json(value):
    """``value`` with every infinite or NaN number as ``None`` (JSON's ``null``), for the
    files people read with other tools: Python writes ``-Infinity``, which JSON has not,
    so a run report's ``settings.json`` (log marginal-likelihood ``-inf``) failed in
    JavaScript's ``JSON.parse`` and read as ``-1.8e308`` in ``jq``. Numpy scalars become
    Python numbers; dicts, lists and tuples are walked; anything else is left as it is."""
    if isinstance(value, dict):
        return {key: standard_json(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [standard_json(item) for item in value]
    if type(value).__module__ == "numpy" and getattr(value, "ndim", None) == 0:
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


class _DuplicateKey(Exception):
    def __init__(self, key: str, values: list):
        super().__init__(key)
        self.key, self.values = key, values


def _unique_keys(pairs: list) -> dict:
    """A JSON object's dict, refusing a key given twice: Python's reader keeps the last one
    silently, so a hand-edited file with two ``"wing"`` parts learned from one of them."""
    out = dict(pairs)
    if len(out) != len(pairs):
        seen = set()
        for key, _ in pairs:
            if key in seen:
                raise _DuplicateKey(key, [v for k, v in pairs if k == key])
            seen.add(key)
    return out


# a \uD800-\uDFFF escape: JSON may spell half of a UTF-16 pair alone, which is no text
_SURROGATE_ESCAPE = re.compile(r"\\u[dD][89a-fA-F][0-9a-fA-F]{2}")


def lone_surrogate_at(value, text: str, where: str = "") -> str | None:
    """Where in parsed JSON ``value`` (``"nodes[3].name"``) a string or key holds a lone
    UTF-16 surrogate (``"\\ud800"`` not followed by its low half), or None; ``text`` is
    the JSON it was parsed from, looked at first (a file without such an escape is not
    walked). Such a name cannot be written to a file or a terminal: procmod had printed a
    traceback, or crashed after a whole learn search, on a part named so."""
    if not _SURROGATE_ESCAPE.search(text):
        return None
    stack = [(value, where)]
    while stack:
        item, at = stack.pop()
        if isinstance(item, str):
            try:
                item.encode("utf-8")
            except UnicodeEncodeError:
                return at or "the top level"
        elif isinstance(item, dict):
            for key, inner in item.items():
                try:
                    key.encode("utf-8")
                except UnicodeEncodeError:
                    return f"{at + '.' if at else ''}{key.encode('ascii', 'backslashreplace').decode()}"
                stack.append((inner, f"{at}.{key}" if at else key))
        elif isinstance(item, list):
            stack.extend((inner, f"{at}[{i}]") for i, inner in enumerate(item))
    return None


def lone_surrogate_text(at: str) -> str:
    """The end of a refusal of a file :func:`lone_surrogate_at` found at ``at``."""
    return (f"{at} holds a lone UTF-16 surrogate escape (a \\uD800-\\uDFFF without its pair), which is no "
            "text: re-save the file from its tool, or correct that name")


def parse_json(text: str, source: str, error: type = DerivationFormatError):
    """``json.loads(text)``, with every way it fails (bad syntax, nesting deeper than
    Python's stack: a file of 100,000 ``[``, a key twice in one object) raised as
    ``error(f"{source}: ...")``, one line."""
    try:
        value = json.loads(text, object_pairs_hook=_unique_keys)
    except _DuplicateKey as exc:
        # the values say where: a file has many "part" keys, and the reader has no positions
        shown = " and ".join(cut_text(json.dumps(v), 40) for v in exc.values[:2])
        raise error(f"{source}: the key {cut_text(repr(exc.key), 80)} appears twice in one object (values {shown}); "
                    "keep one of them (which one was meant is not clear, so neither is used)") from None
    except json.JSONDecodeError as exc:
        raise error(f"{source}: not valid JSON ({exc.msg} at line {exc.lineno})") from None
    except RecursionError:
        raise error(f"{source}: JSON nested too deeply (procmod's files nest a few levels; this one nests "
                    "more than Python can read)") from None
    except MemoryError:
        raise error(f"{source}: its JSON does not fit in this machine's memory") from None
    except ValueError as exc:  # e.g. an integer of more digits than Python converts (4300)
        if "digits" in str(exc):  # Python's own advice (sys.set_int_max_str_digits) is not the user's to follow
            raise error(f"{source}: not valid JSON for procmod: it holds an integer of more than 4300 digits, more "
                        "than any of procmod's files needs; check the file") from None
        raise error(f"{source}: not valid JSON ({cut_text(str(exc), 100)})") from None
    lone = lone_surrogate_at(value, text)
    if lone is not None:
        raise error(f"{source}: {lone_surrogate_text(lone)}")
    return value


# byte-order marks of the wider Unicode encodings, UTF-32's first (its little-endian mark
# begins with UTF-16's); Python's codecs named here drop the mark
_WIDE_BOMS = ((codecs.BOM_UTF32_LE, "utf-32"), (codecs.BOM_UTF32_BE, "utf-32"),
              (codecs.BOM_UTF16_LE, "utf-16"), (codecs.BOM_UTF16_BE, "utf-16"))


def read_json(path: str | os.PathLike, error: type = DerivationFormatError, what: str = "file"):
    """The parsed JSON of ``path``; a missing, unreadable or malformed file is ``error``
    with one line naming the file (see :func:`parse_json`)."""
    if not isinstance(path, (str, os.PathLike)):
        raise error(f"{what} must be given as a path (a str or pathlib.Path), got {type(path).__name__} {path!r:.40}")
    if "\0" in os.fsdecode(os.fspath(path)):  # (Path.exists raised ValueError on it: h82)
        raise error(f"{what} {cut_text(repr(os.fspath(path)))} has a NUL character in its name; give the file's path")
    try:
        if Path(path).exists() and not Path(path).is_file():  # a folder, a FIFO, /dev/zero: never ends or fits
            raise error(f"{what} {cut_text(str(path))} is not a regular file")
        size = os.path.getsize(path)
        if size > MAX_JSON_BYTES:  # read whole, and parsed to several times its size
            raise error(f"{what} {cut_text(str(path))} is {format_bytes(size)}, more than procmod reads as JSON "
                        f"({format_bytes(MAX_JSON_BYTES)}); is it the file you meant?")
        # utf-8-sig: a byte-order mark, which Windows editors write, is not part of the JSON;
        # one of UTF-16 or UTF-32 says the file's encoding (Windows PowerShell's `>` and
        # Out-File write UTF-16: such a sidecar had been refused as "a picture or another binary file?")
        raw = Path(path).read_bytes()
        text = raw.decode(next((name for bom, name in _WIDE_BOMS if raw.startswith(bom)), "utf-8-sig"))
        # line ends as read_text read them (json counts lines by "\n": a CR-only file's
        # errors had all been "at line 1")
        text = text.replace("\r\n", "\n").replace("\r", "\n")
        if not text.strip():  # (json says "Expecting value at line 1")
            raise error(f"{what} {cut_text(str(path))} is empty; was it written to the end?")
    except FileNotFoundError:
        raise error(f"{what} {cut_text(str(path))} does not exist") from None
    except UnicodeDecodeError:
        raise error(f"{what} {cut_text(str(path))} is not a JSON text file (its bytes are not UTF-8 text: a picture "
                    "or another binary file?)") from None
    except OSError as exc:
        raise error(f"cannot read {what} {cut_text(str(path))}: {getattr(exc, 'strerror', None) or exc}") from None
    return parse_json(text, f"{what} {cut_text(str(path))}" if what != "file" else cut_text(str(path)), error)


def check_format(data, fmt: str, source: str, error: type = DerivationFormatError, advice: str = "") -> dict:
    """``data`` if it is a JSON object whose ``"format"`` is ``fmt``, else ``error`` in one
    line naming ``source``, what the file says (or that it says nothing) and ``fmt``
    (``advice``, starting with ``"; "``, is appended)."""
    if not isinstance(data, dict):
        raise error(f"{source}: expected a JSON object with \"format\": \"{fmt}\", got {shown_value(data)}{advice}")
    found = data.get("format")
    if found != fmt:
        said = "has no \"format\"" if found is None else f"format is {shown_value(found, 80)}"
        raise error(f"{source}: {said}, expected \"{fmt}\"{advice}")
    return data


def read_versioned_json(path: str | os.PathLike, fmt: str, error: type = DerivationFormatError,
                        what: str = "file", advice: str = "") -> dict:
    """The JSON object of ``path``, checked to say ``"format": fmt``; every failure (see
    :func:`read_json`, :func:`check_format`) is one line of ``error`` ending in ``advice``."""
    try:
        data = read_json(path, error, what)
    except error as exc:
        raise error(f"{exc}{advice}") from None
    return check_format(data, fmt, cut_text(str(path)), error, advice)


# ---- tensors -----------------------------------------------------------------------------------

def save_tensors(obj, path: str | os.PathLike, fsync: bool = False) -> None:
    """``torch.save(obj, path)`` atomically: a kill mid-write leaves the previous file whole.

    ``obj`` should hold only tensors, numbers, strings and containers of them, so that
    :func:`load_tensors` (``weights_only=True``) reads it back.
    """
    import torch  # only the commands that save tensors pay for importing torch

    with open_atomic(path, "wb", fsync) as handle:
        torch.save(obj, handle)


def load_tensors(path: str | os.PathLike, error: type = ProcmodError, what: str = "tensors", advice: str = "",
                 source: str | None = None):
    """``torch.load(path, weights_only=True, map_location="cpu")`` with every refusal one
    line of ``error``: ``"{source}: ... the {what} ...{advice}"``, where ``source`` defaults
    to ``path`` and ``advice`` starts with ``"; "``.

    A file that holds Python objects besides tensors (which may run code when unpickled) is
    refused, without torch's several lines of advice on loading it unsafely; a missing,
    truncated or foreign file "cannot be read". Tensors come back on the CPU (procmod saves
    CPU tensors, and its readers use numpy).
    """
    import pickle
    import re
    import warnings

    import torch

    source = cut_text(str(path) if source is None else source)
    try:
        with warnings.catch_warnings():  # torch warns (two lines) about a plain pickle before refusing it
            warnings.simplefilter("ignore")
            return torch.load(path, weights_only=True, map_location="cpu")
    except pickle.UnpicklingError as exc:
        operand = re.search(r"Unsupported operand (\d+)", str(exc))
        if operand:  # not a pickle torch's safe reader knows: text, JSON, a newer pickle protocol
            raise error(f"{source}: cannot read the {what} (not a file of tensors torch wrote: unsupported "
                        f"pickle operand {operand.group(1)}){advice}") from None
        found = re.search(r"GLOBAL [\w.]+", str(exc))  # the Python name the file would load
        detail = f" ({cut_text(found.group(0), 120)})" if found else ""
        raise error(f"{source}: refused to load the {what}: the file holds Python objects, not only tensors"
                    f"{detail}; procmod never writes such a file and loading it could run its code{advice}") from None
    except FileNotFoundError:  # (not "damaged": a model folder missing its weights, h95)
        raise error(f"{source}: cannot read the {what}: the file does not exist{advice}") from None
    except Exception as exc:  # torch raises several types for truncated or foreign files
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise error(f"{source}: cannot read the {what}: the file is damaged (cut short?) or not one torch wrote "
                    f"({cut_text(first, 160)}){advice}") from None
