"""Output folders of commands (``--out``; ``out`` in the Python API): checked before the
work, written whole.

A command that writes a folder of results (``sample``, ``infer``, ``strings graph``,
``strings augment``, ``strings sample``) follows three rules:

**Checked first.** :class:`RunFolder` checks ``--out`` when the command starts, before
any expensive work: a file where a folder should be, a location that cannot be written
(``/proc/x``, a read-only disk), or a folder that may not be replaced is refused with
one line.

**Never mixed.** An existing ``--out`` folder is replaced *whole* or refused, never
written into: new results beside an earlier run's (``sample_004..015`` of a 16-sample
run beside 4 new ones, an old ``target.png`` in a new report) would be read as one
run. A non-empty folder is replaced only if it is an earlier run of the same command
(every entry is a file that command writes, and its marker file is there: see
:class:`RunKind`) or the user passed ``--overwrite``; otherwise the command refuses,
naming ``--overwrite``. Even ``--overwrite`` never replaces a folder holding the current
folder, the home folder, or one of the command's input files.

**Nothing half-written.** The files are written into a hidden temporary folder beside
``--out`` (``.NAME.XXXX.tmp``) that is renamed to ``--out`` when every file is written;
a failure removes it. A job killed outright (SIGKILL) can leave that hidden folder, never
a half-written ``--out``.

Resumable jobs (``guide traces``, ``strings train``, ``learn``) write into ``--out`` as
they go, so that a killed job keeps what it finished; :meth:`RunFolder.prepare_in_place`
applies the first two rules to them. A folder holding a symbolic link is never taken for
an earlier run (a job writing into it would write wherever the link points).

Messages name the API's arguments (``out``, ``overwrite=True``) through
:func:`procmod.core.errors.argument`, which the command line spells as its flags.
"""

from __future__ import annotations

import contextlib
import json
import os
import posixpath
import re
import shutil
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator
from urllib.parse import unquote

from .errors import InvalidArgumentError, argument, cut_text
from .io import hidden_temporary_prefix
from .paths import named_files_read, output_path


class OutputLocationError(InvalidArgumentError):
    """An output location that cannot be written, or a folder that may not be replaced."""


@dataclass(frozen=True)
class RunKind:
    """What an earlier run of one command leaves in its folder.

    Attributes
    ----------
    name : str
        For messages: ``"procmod infer run"``.
    marker : str
        A file every run of the kind writes (``settings.json``).
    patterns : tuple of str
        Regular expressions; every entry (file or folder) directly inside an earlier run's
        folder matches one of them.
    marker_key : str, optional
        The marker is a JSON object with this key (``"engine"``).
    """

    name: str
    marker: str
    patterns: tuple
    marker_key: str | None = None
    listed: "Callable[[Path], set] | None" = None
    """Entries a run of the kind lists in its own files (``listed(folder)``: names), also
    allowed: e.g. the mesh folders a collection's shapes file names."""
    resumes: bool = False
    """A job of this kind resumes an earlier run in its folder instead of replacing it."""
    shares_folder: bool = False
    """A resumable job whose folder may hold the user's files beside its own (a guide
    trained beside its traces, a notes file): it neither reads nor removes them. Only for
    a kind whose marker is checked (``marker_key``): a folder of another tool's that
    happens to hold a file of the marker's name must not be taken for a run."""

    def recognises(self, folder: str | os.PathLike) -> bool:
        """True when ``folder`` holds an earlier run of this kind and nothing else (for a
        kind that :attr:`shares_folder`: nothing else of the names it writes)."""
        folder = Path(folder)
        try:
            names = [p.name for p in folder.iterdir()]
        except OSError:
            return False
        if self.marker not in names:
            return False
        if self.shares_folder:
            names = [name for name in names if self.owns(name)]
        # (a link is foreign: a run writes none, and resuming must not write through one)
        if self.foreign(folder, names) is not None:
            return False
        if self.marker_key is None:
            return True
        try:
            data = json.loads((folder / self.marker).read_text(encoding="utf-8"))
        except (OSError, ValueError, RecursionError):
            return False
        return isinstance(data, dict) and self.marker_key in data

    def damaged_marker(self, folder: Path) -> bool:
        """True when ``folder`` holds only this kind's files but its marker does not read
        (cut off, edited): the folder is an earlier run whose settings are lost."""
        try:
            names = [p.name for p in folder.iterdir()]
        except OSError:
            return False
        return self.marker in names and self.foreign(folder, names) is None and not self.recognises(folder)

    def owns(self, name: str) -> bool:
        """Whether a run of this kind writes entries called ``name``."""
        return any(re.fullmatch(p, name) for p in self.patterns)

    def foreign(self, folder: Path, names=None) -> str | None:
        """The first entry of ``folder`` (sorted) that no run of this kind writes, or None."""
        if names is None:
            names = [p.name for p in folder.iterdir()]
        extra = self.listed(folder) if self.listed is not None else set()
        for name in sorted(names):
            if not (name in extra or any(re.fullmatch(p, name) for p in self.patterns)) \
                    or (folder / name).is_symlink():
                return name
        return None


def _nearest_existing(path: Path) -> Path:
    while not path.exists() and path.parent != path:
        path = path.parent
    return path


def _probe_writable(folder: Path, option: str, out: Path) -> None:
    """Refuse unless a file can be created in ``folder`` (tried, then removed)."""
    option = argument(option)
    if not folder.is_dir():
        raise OutputLocationError(f"cannot write {option} {cut_text(str(out))}: {cut_text(str(folder))} "
                                  "is not a folder")
    try:
        probe = tempfile.mkdtemp(prefix=".procmod-probe-", dir=folder)
        os.rmdir(probe)
    except OSError as exc:
        raise OutputLocationError(f"cannot write {option} {cut_text(str(out))}: cannot create files in "
                                  f"{cut_text(str(folder))} ({exc.strerror or exc}); make it writable or give "
                                  "another folder") from None


def check_output_file(path: str | os.PathLike, option: str = "out", make_parent: bool = False,
                      inputs=(), overwrite: bool = True) -> Path:
    """A single output file (``render --out x.png``): the path must not be a folder, nor
    one of the command's ``inputs`` or a file an input names, nor an existing file inside
    an input folder (a new file there is fine), nor, unless ``overwrite``, an existing
    file (a command's ``--out`` of a file of the user's had replaced it without a word),
    and its folder must exist
    (or, with ``make_parent``, be creatable: the command makes it when it writes) and be
    writable. Checks only, creates nothing; returns the path, its ``..`` resolved
    (:func:`~procmod.core.paths.output_path`). ``option`` is the API
    argument the path was given as, for messages."""
    path = output_path(path)  # the caller writes where this returns (see output_path)
    shown = argument(option)
    try:
        is_dir = path.is_dir()
    except (OSError, ValueError) as exc:  # a name too long for the file system
        raise OutputLocationError(f"cannot write {shown} {cut_text(str(path))}: "
                                  f"{getattr(exc, 'strerror', None) or exc}") \
            from None
    if is_dir:
        raise OutputLocationError(f"{shown} {cut_text(str(path))} is a folder; give a file name")
    for item in [*inputs, *named_files_read()]:
        if item is not None and Path(item).exists() and path.exists() and _holds(Path(item), path):
            raise OutputLocationError(f"{shown} {cut_text(str(path))} would overwrite the input "
                                      f"{cut_text(str(item))}{'' if _holds(path, Path(item)) else ' (a file in it)'}; "
                                      "give another file name")
    if not overwrite and (path.exists() or path.is_symlink()):
        raise OutputLocationError(f"{shown} {cut_text(str(path))} already exists; give {argument('overwrite=True')} "
                                  "to replace it, or another file name")
    parent = path.parent
    if not parent.exists() and not make_parent:
        raise OutputLocationError(f"cannot write {shown} {cut_text(str(path))}: the folder {cut_text(str(parent))} "
                                  "does not exist; create it first")
    _probe_writable(_nearest_existing(parent), option, path)
    return path


def _cwd() -> Path | None:
    """The current folder, or None when it was deleted under the process (nothing lies in it)."""
    try:
        return Path.cwd()
    except OSError:
        return None


def _holds(folder: Path, path: Path | None) -> bool:
    """True when ``path`` is ``folder`` or lies inside it (both resolved)."""
    if path is None:
        return False
    try:
        path.resolve().relative_to(folder.resolve())
        return True
    except (ValueError, OSError):
        return False


class RunFolder:
    """The output folder of one command, checked at construction (see the module docstring).

    Parameters
    ----------
    path : path-like
        The folder the user named.
    kind : RunKind
        What the command writes, to recognise an earlier run.
    overwrite : bool
        Replace a non-empty folder that is not an earlier run of ``kind`` (``--overwrite``).
    inputs : iterable of path-like
        The command's input files; a folder holding one is never replaced.
    option : str
        The API argument that named the folder, for messages (default ``out``; shown
        through :func:`procmod.core.errors.argument`, so ``--out`` on the command line).

    Use::

        folder = RunFolder(args.out, INFER_RUN, args.overwrite, inputs=[args.target])
        ...                                   # the expensive work
        with folder.writing() as tmp:         # a new, empty folder beside --out
            write_files(tmp)                  # replaces --out whole when the block ends
    """

    def __init__(self, path: str | os.PathLike, kind: RunKind, overwrite: bool = False, inputs=(),
                 option: str = "out"):
        self.option = option = argument(option)
        self.path = output_path(path)  # "a/b/../../R" is R: no folders a/b made on the way
        self.kind = kind
        shown = cut_text(str(self.path))
        self._inputs = [item for item in inputs if item is not None]
        try:
            exists, is_dir = self.path.exists(), self.path.is_dir()
        except (OSError, ValueError) as exc:  # a name too long for the file system
            raise OutputLocationError(f"cannot write {option} {shown}: {getattr(exc, 'strerror', None) or exc}") \
                from None
        if exists and not is_dir:
            raise OutputLocationError(f"{option} {shown} exists and is not a folder")
        if not exists and self.path.is_symlink():  # a link to nothing: the run's last rename failed on it
            raise OutputLocationError(f"{option} {shown} is a symbolic link to {cut_text(os.readlink(self.path), 80)}, "
                                      "which does not exist; remove the link, make its folder, or give another folder")
        for parent in self.path.parents:  # a folder to make that is a link to nothing failed after the work
            if parent.exists():
                break
            if parent.is_symlink():
                raise OutputLocationError(f"{option} {shown} lies under {cut_text(str(parent), 80)}, a symbolic link to "
                                          f"{cut_text(os.readlink(parent), 80)}, which does not exist (or a loop of "
                                          "links); remove the link, make its folder, or give another folder")
        self.replaces = is_dir and any(self.path.iterdir())
        if self.replaces:
            if not (overwrite or kind.recognises(self.path)):
                if kind.damaged_marker(self.path):
                    raise OutputLocationError(
                        f"{option} {shown} is an earlier {kind.name} whose {kind.marker} is damaged (it does not "
                        f"read as JSON{'' if kind.marker_key is None else ' with ' + repr(kind.marker_key)}); "
                        f"restore it{' to resume' if kind.resumes else ''}, or pass "
                        f"{argument('overwrite=True')} to start over")
                example = kind.foreign(self.path) or sorted(p.name for p in self.path.iterdir())[0]
                if _holds(self.path, _cwd()):  # --overwrite cannot replace it: say only what works
                    raise OutputLocationError(
                        f"{option} {shown} is not empty and not an earlier {kind.name} (it holds "
                        f"{cut_text(example, 60)!r}), and it holds the current folder, which cannot be replaced: "
                        "give a new folder")
                raise OutputLocationError(
                    f"{option} {shown} is not empty and not an earlier {kind.name} (it holds {cut_text(example, 60)!r}); "
                    f"give a new or empty folder, or pass {argument('overwrite=True')} to replace it whole")
            # an earlier run a job resumes is kept: the files named by inputs are checked
            # when (and if) the folder is removed
            self._check_replaceable(named=not (kind.resumes and kind.recognises(self.path)))
        self.in_place = self.path.exists() and _holds(self.path, _cwd())
        _probe_writable(_nearest_existing(self.path if self.in_place else self.path.parent), option, self.path)
        # a link is replaced, not its target, unless a resumable job writes through it
        through_link = self.path.is_symlink() and kind.resumes and kind.recognises(self.path)
        if exists and not self.in_place and (through_link or not self.path.is_symlink()):
            # an existing folder is written into (resumable jobs) or moved aside and deleted
            # when the new run replaces it: both need it writable, and moving a folder to
            # another parent needs that too (its ".." changes). Found out only at the end,
            # a whole run was lost to a read-only earlier run.
            _probe_writable(self.path, option, self.path)

    def _check_replaceable(self, named: bool = True) -> None:
        shown = cut_text(str(self.path))
        for protected, what in ((_cwd(), "the current folder"), (Path.home(), "your home folder")):
            if _holds(self.path, protected):
                raise OutputLocationError(f"{self.option} {shown} holds {what}; it cannot be replaced: give "
                                          "a new or empty folder")
        self._check_inputs(named)

    def _check_inputs(self, named: bool = True) -> None:
        """Refuse to remove a folder holding one of the command's inputs: those it was
        given, and (``named``) every file an input file has named so far
        (:func:`named_files_read`), which may have been read after the folder was first checked."""
        shown = cut_text(str(self.path))
        for item in [*self._inputs, *(named_files_read() if named else ())]:
            if Path(item).exists() and _holds(self.path, Path(item)):
                raise OutputLocationError(f"{self.option} {shown} holds the input {cut_text(str(item))}; replacing "
                                          "the folder would delete it: give another folder")

    @contextlib.contextmanager
    def writing(self) -> Iterator[Path]:
        """A new, empty folder to write every file into; it becomes ``path`` (replacing what
        was there) when the block ends without an exception, and is removed otherwise."""
        if self.in_place:  # --out is (or holds) the current folder: written there directly (files
            # that name others relatively, a learned program's derivations, are written where they
            # stay), and what the run added is removed if it fails (Ctrl-C had left a half run)
            before = set(os.listdir(self.path))
            try:
                yield self.path
            except BaseException:
                for name in set(os.listdir(self.path)) - before:
                    entry = self.path / name
                    if entry.is_dir() and not entry.is_symlink():
                        shutil.rmtree(entry, ignore_errors=True)
                    else:
                        with contextlib.suppress(OSError):
                            entry.unlink()
                raise
            return
        created = self._make_parents()
        tmp = Path(tempfile.mkdtemp(prefix=hidden_temporary_prefix(self.path), suffix=".tmp", dir=self.path.parent))
        try:
            os.chmod(tmp, 0o777 & ~_umask())  # mkdtemp makes 0700 folders
            yield tmp
            self._replace_with(tmp)
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            for folder in reversed(created):  # parents made for this run, if still empty
                with contextlib.suppress(OSError):
                    folder.rmdir()
            raise

    def prepare_in_place(self, keep: bool = True) -> Path:
        """For a resumable job: the folder, created, written into directly. An earlier run
        is kept to resume when ``keep``; anything else there (allowed by ``--overwrite``)
        is removed first."""
        recognised = self.replaces and self.kind.recognises(self.path)
        if self.replaces and not (keep and recognised):
            self._check_inputs()
            if self.path.is_symlink():  # replace the link, never what it points to
                self.path.unlink()
            elif recognised:  # an earlier job with other settings (--overwrite): its own files only
                # (with the entries its own files list: a model's copied meshes had been left
                # behind, and the folder then refused to resume as a stranger's)
                listed = self.kind.listed(self.path) if self.kind.listed is not None else set()
                for entry in self.path.iterdir():
                    if self.kind.owns(entry.name) or entry.name in listed:
                        shutil.rmtree(entry) if entry.is_dir() and not entry.is_symlink() else entry.unlink()
            else:
                shutil.rmtree(self.path)
        self.path.mkdir(parents=True, exist_ok=True)
        return self.path

    def _make_parents(self) -> list[Path]:
        missing = []
        parent = self.path.parent
        while not parent.exists():
            missing.append(parent)
            parent = parent.parent
        self.path.parent.mkdir(parents=True, exist_ok=True)
        return list(reversed(missing))

    def _replace_with(self, tmp: Path) -> None:
        if self.replaces:
            self._check_inputs()  # the work may have read more inputs since the first check
        if not self.path.exists():
            os.rename(tmp, self.path)
            return
        old = Path(tempfile.mkdtemp(prefix=hidden_temporary_prefix(self.path), suffix=".old", dir=self.path.parent))
        try:
            os.rename(self.path, old / "run")
        except OSError as exc:  # made read-only since the check at the start
            old.rmdir()
            raise OutputLocationError(f"cannot replace {self.option} {cut_text(str(self.path))}: "
                                      f"{exc.strerror or exc}; make it writable or give another folder") from None
        try:
            os.rename(tmp, self.path)
        except BaseException:
            os.rename(old / "run", self.path)  # put the earlier run back
            old.rmdir()
            raise
        shutil.rmtree(old, ignore_errors=True)


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


# ---- the folders procmod's commands write ----------------------------------------------

SAMPLE_RUN = RunKind("procmod sample folder", "contact_sheet.png",
                     (r"contact_sheet\.(png|html)", r"sample_\d+\.(json|png|svg|obj|glb)"))
INFER_RUN = RunKind("procmod infer run", "settings.json",
                    (r"best\.(png|svg|obj|glb|json)", r"target\.png", r"history\.csv", r"convergence\.(svg|png)",
                     r"samples\.png", r"settings\.json", r"report\.html"), marker_key="engine")
TRACES_JOB = RunKind("procmod guide traces folder", "traces.json",
                     (r"traces\.json", r"trace_\d+\.json", r"\.trace_\d+\.json\..*", r"\.traces\.json\..*"),
                     marker_key="format", resumes=True, shares_folder=True)
GRAPHS_FOLDER = RunKind("procmod strings graph folder", "shape_000.json", (r"shape_\d+\.json",))


def _mesh_entries(shapes_file: str):
    """``listed`` of a folder that copies the mesh files its shapes file (``shapes_file``)
    names beside it (any relative path inside the folder): the first component of each."""
    return lambda folder: _mesh_entries_of(folder / shapes_file)


def _mesh_entries_of(shapes: Path) -> set:
    try:
        data = json.loads(shapes.read_text(encoding="utf-8"))
        parts = data["parts"].values()
        meshes = [part["mesh"] for part in parts if isinstance(part, dict) and isinstance(part.get("mesh"), str)]
    except (OSError, ValueError, RecursionError, KeyError, TypeError, AttributeError):
        return set()
    paths = list(meshes)
    for mesh in meshes:  # a .gltf is copied with the buffers and images it names
        if mesh.lower().endswith(".gltf"):
            folder = re.split(r"[\\/]", mesh)[:-1]
            # normalised: meshes/m.gltf naming ../textures/wood.png is copied to textures/wood.png
            paths += [posixpath.normpath("/".join(folder + [unquote(uri).replace("\\", "/")]))
                      for uri in _gltf_uris(shapes.parent / mesh)]
    return {_first_component(p) for p in paths} - {"", ".."}


def _first_component(path: str) -> str:
    parts = [p for p in re.split(r"[\\/]", path) if p not in ("", ".")]
    return parts[0] if parts else ""


def _gltf_uris(path: Path) -> list:
    """The relative file names a .gltf's buffers and images give (not data: URIs)."""
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
        items = [*(data.get("buffers") or []), *(data.get("images") or [])]
        return [i["uri"] for i in items if isinstance(i, dict) and isinstance(i.get("uri"), str)
                and not i["uri"].startswith("data:")]
    except (OSError, ValueError, RecursionError, TypeError, AttributeError):
        return []


COLLECTION = RunKind("procmod strings augment collection", "growth.json",
                     (r"shapes\.json", r"graphs", r"strings\.txt", r"growth\.json", r"contact_sheet\.png"),
                     marker_key="rounds", listed=_mesh_entries("shapes.json"))
_ATOMIC_TEMPORARY = r"\..+\.tmp"  # a file being written (core.io.open_atomic) when a job was killed
STRINGS_MODEL = RunKind("procmod strings train folder", "collection.json",
                        (r"model\.json", r"collection\.json", r"strings\.txt", r"categories\.json",
                         r"(vae|tagger)\.(json|pt)", _ATOMIC_TEMPORARY), listed=_mesh_entries("collection.json"),
                        resumes=True)
LEARN_RUN = RunKind("procmod learn folder", "checkpoint",
                    (r"program\.(json|pt)", r"parts", r"checkpoint", r"contact_sheet\.png",
                     r"search\.(svg|png)",  # png: an earlier version's search plot
                     r"report\.(json|html)", _ATOMIC_TEMPORARY), resumes=True)
STRING_SAMPLES = RunKind("procmod strings sample folder", "summary.json",
                         (r"samples\.txt", r"summary\.json", r"contact_sheet\.png",
                          r"sample_\d+\.(json|glb|png)"), marker_key="samples")

__all__ = ["COLLECTION", "GRAPHS_FOLDER", "INFER_RUN", "LEARN_RUN", "OutputLocationError", "RunFolder", "RunKind",
           "SAMPLE_RUN", "STRINGS_MODEL", "STRING_SAMPLES", "TRACES_JOB", "check_output_file"]
