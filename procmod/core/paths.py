"""Names and paths that come from input files.

Input files name things procmod turns into paths: a part name of an examples file becomes
a mesh file of the learned program, a ``"mesh"`` field names the mesh to read, a program's
``"tensors"`` field its parameter file. An input file may have been written by anyone, so
two rules hold everywhere:

**Writing.** Nothing procmod writes lands outside the folder the user named. A name from
an input file becomes a file name only through :class:`FileNames`, which keeps a plain name
(``wing``, ``body-2``) as it is and maps anything else — path separators, ``..``, an
absolute path, NUL, a name Windows reserves (``CON``, ``nul.txt``), a very long name — to
a plain name plus a digest of the original, so that the result is always one component
inside the folder. Two names that would land on one file (also on a case-insensitive
file system: ``Wing`` and ``wing``) get distinct files; none silently overwrites another.
A relative path from an input file that procmod reproduces under an output folder goes
through :func:`contained_path`, which refuses one that would leave the folder.

**Reading.** A file named by an input file is a relative path, resolved against the
folder of the file that names it (``..`` may climb out of that folder: a file set may
share meshes); absolute paths are refused, so that a file set stays valid when it is
moved. :func:`named_file` resolves such a name and refuses, in one line naming the file
and the field, anything that is not an existing regular file with an expected suffix (an
empty name, ``.``, a folder, a missing file, a file of another kind).
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import re
from pathlib import Path, PurePosixPath, PureWindowsPath

from .errors import ProcmodError, argument, cut_text, shown_value
from .file_formats import conversion_hint


class UnsafePathError(ProcmodError):
    """A name or path from an input file that cannot be used as one (the message says where)."""


# A name kept as it is: ASCII letters, digits, "_", "-" and inner dots; short enough for
# any file system once a suffix is added; not starting with a dot (hidden, "." and "..").
_PLAIN = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9._-]*")
MAX_STEM = 64
# Device names Windows reserves, with or without an extension (``nul.obj`` is NUL too).
_RESERVED = {"con", "prn", "aux", "nul", *(f"com{i}" for i in range(10)), *(f"lpt{i}" for i in range(10))}


def is_plain_name(name: str) -> bool:
    """True when ``name`` is used unchanged as a file stem (see :class:`FileNames`)."""
    return (isinstance(name, str) and len(name) <= MAX_STEM and _PLAIN.fullmatch(name) is not None
            and not name.endswith(".") and name.split(".", 1)[0].lower() not in _RESERVED)


def _mapped_stem(name: str) -> str:
    """A plain stem for any string: its plain characters (at most 40) and 12 hex digits of
    its SHA-256, so distinct names give distinct stems (up to a 2^-48 coincidence, which
    :class:`FileNames` still detects)."""
    digest = hashlib.sha256(name.encode("utf-8", "surrogatepass")).hexdigest()[:12]
    readable = re.sub(r"[^A-Za-z0-9_-]+", "_", name).strip("_")[:40]
    return f"{readable}-{digest}" if readable else digest


class FileNames:
    """Allocates one file name per untrusted name, all inside one folder.

    ``FileNames(".obj").name_for("wing")`` is ``"wing.obj"``;
    ``name_for("../../etc/x")`` is ``"etc_x-<12 hex>.obj"``. Asking twice for one name gives
    the same file; two names never share one, even where the file system ignores case. The
    result depends only on the name and the names allocated before it.

    Parameters
    ----------
    suffix : str
        Appended to every name (``".obj"``).
    source, field : str
        The input file and the field the names come from, for the error message.
    """

    def __init__(self, suffix: str = "", source: str = "input", field: str = "name"):
        self.suffix = suffix
        self.source, self.field = source, field
        self._by_name: dict[str, str] = {}
        self._taken: dict[str, str] = {}  # case-folded file name -> the name it holds

    def name_for(self, name: str) -> str:
        """The file name (one path component, with the suffix) for ``name``."""
        if name in self._by_name:
            return self._by_name[name]
        if not isinstance(name, str):
            raise UnsafePathError(f"{self.source}: {self.field} must be a string, got {shown_value(name)}")
        stem = name if is_plain_name(name) else _mapped_stem(name)
        file = stem + self.suffix
        if file.casefold() in self._taken:
            # ``Wing`` after ``wing``, or ``a_b`` after a name mapped to ``a_b``: the later
            # one gets its digest, which no plain name ends with a suffix-free collision on
            file = _mapped_stem(name) + self.suffix
        if file.casefold() in self._taken:
            raise UnsafePathError(f"{self.source}: {self.field} {shown_value(name)} and "
                                  f"{shown_value(self._taken[file.casefold()])} map to one file name {file!r}; "
                                  "rename one of them")
        self._taken[file.casefold()] = name
        self._by_name[name] = file
        return file


def _relative_parts(value, where: str) -> tuple[str, ...]:
    """The components of a relative path from an input file, or UnsafePathError."""
    if not isinstance(value, str) or not value.strip():
        raise UnsafePathError(f"{where}: expected a relative file path (a non-empty string), got {shown_value(value)}")
    if "\0" in value:
        raise UnsafePathError(f"{where}: the path {shown_value(value)} contains a NUL character")
    # absolute on any system: "/x", "\\x", "C:x", "C:\\x", "\\\\server\\share"
    if PurePosixPath(value).is_absolute() or PureWindowsPath(value).drive or PureWindowsPath(value).root:
        raise UnsafePathError(f"{where}: {shown_value(value)} is an absolute path; write it relative to "
                              "the folder of the file that names it")
    parts = tuple(p for p in re.split(r"[/\\]", value) if p not in ("", "."))
    if not parts:
        raise UnsafePathError(f"{where}: {shown_value(value)} names a folder, not a file")
    return parts


def contained_path(folder: str | os.PathLike, relative, where: str) -> Path:
    """``folder / relative`` for a relative path from an input file that must stay inside
    ``folder`` (no ``..``, not absolute, not empty); UnsafePathError otherwise.

    Used where procmod reproduces a path it read (a mesh copied beside a new file)."""
    parts = _relative_parts(relative, where)
    if ".." in parts:
        # (``folder`` is not named: it is often a run's temporary folder, a name the user never gave)
        raise UnsafePathError(f"{where}: {shown_value(relative)} leads out of its folder, so it cannot be "
                              "reproduced inside the output folder; keep the file in (a subfolder of) the "
                              "folder of the file that names it")
    return Path(folder).joinpath(*parts)


def named_file(base_dir: str | os.PathLike, value, where: str, suffixes=None, kind: str = "file",
               same_folder: bool = False) -> Path:
    """The existing regular file an input file names (``value``, relative to ``base_dir``,
    the naming file's folder).

    Parameters
    ----------
    where : str
        The naming file and field (``"examples.json: parts.wing.mesh"``), for the message.
    suffixes : iterable of str, optional
        Accepted suffixes, lower case with the dot (``{".obj", ".stl"}``).
    kind : str
        What the file should be (``"mesh"``), for the message.
    same_folder : bool
        Require a bare file name beside the naming file (for files procmod itself writes
        there, such as a program's tensors).

    Raises
    ------
    UnsafePathError
        For an empty name, ``.``, an absolute path, a NUL, a missing file, a folder, a
        suffix not in ``suffixes``, or (``same_folder``) a name with folders in it.
    """
    parts = _relative_parts(value, where)
    if same_folder and (len(parts) != 1 or parts[0] == ".."):
        raise UnsafePathError(f"{where}: expected the name of a file beside it (no folders), got {shown_value(value)}")
    path = Path(base_dir).joinpath(*parts)
    shown = cut_text(str(path), 200)
    if suffixes is not None and path.suffix.lower() not in suffixes:
        hint = conversion_hint(path)
        raise UnsafePathError(f"{where}: {shown_value(value)} is not a {kind} file (expected a name ending in "
                              f"{', '.join(sorted(suffixes))})" + (f"; {hint}" if hint else ""))
    try:
        if path.is_dir():
            raise UnsafePathError(f"{where}: {shown} is a folder, not a {kind} file")
        if not path.exists():
            raise UnsafePathError(f"{where}: {kind} file {shown} does not exist (paths are relative to the "
                                  "folder of the file that names them)")
        if not path.is_file():
            raise UnsafePathError(f"{where}: {shown} is not a regular file")
    except OSError as exc:  # a name too long for the file system, a folder we may not enter
        raise UnsafePathError(f"{where}: cannot use {shown_value(value)} as a {kind} file ({exc.strerror})") from None
    _NAMED_FILES_READ.add(path)
    return path


# Every file an input file has named in this process: an output folder that holds one is
# never replaced (procmod.core.runfolder), so that ``--overwrite`` cannot delete a mesh, a
# layer or a picture the command's own input names, wherever it lies.
_NAMED_FILES_READ: set = set()


def named_files_read() -> list:
    """The files :func:`named_file` has resolved in this process, and those
    :func:`remember_file_read` was told of (that still exist)."""
    return [p for p in list(_NAMED_FILES_READ) if p.exists()]


def remember_file_read(path: str | os.PathLike) -> None:
    """Protect ``path``, a file this process has read as an input (a user's model file),
    as :func:`named_file`'s are: no output folder that holds it is replaced."""
    _NAMED_FILES_READ.add(Path(path).resolve())


@contextlib.contextmanager
def reading_an_outputs_own_files():
    """Files named while the block runs are an output folder's own (an earlier run's, read
    to decide whether to resume it or replace it), not the command's inputs: they are not
    protected from that replacement (``strings train --overwrite`` refused to replace the
    model folder whose own collection it had checked)."""
    before = set(_NAMED_FILES_READ)
    try:
        yield
    finally:
        _NAMED_FILES_READ.intersection_update(before)


__all__ = ["FileNames", "MAX_STEM", "UnsafePathError", "contained_path", "is_plain_name", "named_file",
           "named_files_read", "reading_an_outputs_own_files", "remember_file_read", "is_file_quietly",
           "is_link_quietly"]


def output_path(path: str | os.PathLike) -> Path:
    """An output path (``out``) with its ``..`` components resolved as the system resolves
    them (symbolic links before a ``..`` followed, missing folders dropped with their
    ``..``), relative when it was given relative: ``r1/r2/../../R`` is ``R``. The folders
    made for ``R`` are then ``R``'s own, never a stray ``r1/r2`` left outside it; a path
    without ``..`` is returned as it is. An empty one (``--out "$UNSET"``, which wrote into the
    current folder) is refused."""
    if not str(path).strip():
        raise UnsafePathError(f"{argument('out')} is empty; give the folder or file to write")
    path = Path(path)
    if ".." not in path.parts:
        return path
    last = len(path.parts) - 1 - path.parts[::-1].index("..")
    head = os.path.realpath(Path(*path.parts[:last + 1]))
    if not path.is_absolute():
        head = os.path.relpath(head, os.getcwd())
    return Path(head, *path.parts[last + 1:])


def is_dir_quietly(path: Path) -> bool:
    """``path.is_dir()``, False for a name the system cannot even look up (too long)."""
    try:
        return path.is_dir()
    except (OSError, ValueError):
        return False


def is_link_quietly(path: Path) -> bool:
    """``path.is_symlink()``, False for a name the system cannot even look up (too long)."""
    try:
        return path.is_symlink()
    except (OSError, ValueError):
        return False


def is_file_quietly(path: Path) -> bool:
    """``path.is_file()``, False for a name the system cannot even look up (too long)."""
    try:
        return path.is_file()
    except (OSError, ValueError):
        return False
