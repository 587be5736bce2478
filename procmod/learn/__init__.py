"""Program induction from part-based examples (seed 000): a learned program is a model.

Public API:

* :func:`read_examples` / :func:`write_examples_file` — the ``procmod-examples/1`` format;
* :func:`preprocess` — symmetry groups, slots, slot groups;
* :func:`learn` — the whole pipeline (structure search, checkpoints, files);
* :func:`load_program` — a saved program as a :class:`procmod.core.Model`;
* :func:`write_examples` — derivations of a learned program as ``procmod-examples/1``.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

from ..core import Derivation, Model
from ..core.errors import ProcmodError, argument
from ..core.lazy import lazy_getattr
from ..core.serialize import write_text_atomic

# Imported on first use (scipy, trimesh and numba kernels are slow to import; the command
# line's parser registers ``procmod learn`` without them). No submodule may share a name
# with one of these: importing it would rebind the package attribute to the module.
_LAZY = {**dict.fromkeys(("FORMAT", "ExampleNode", "ExampleSet", "ExamplesError", "examples_from_dict",
                          "examples_to_dict", "read_examples", "write_examples_file"), "examples"),
         **dict.fromkeys(("Dataset", "preprocess"), "preprocessing"),
         **dict.fromkeys(("Program", "ProgramError", "derivation_hierarchies", "is_learned", "program_model",
                          "read_program"), "program")}

__getattr__ = lazy_getattr(__name__, _LAZY, globals())


class NotALearnedProgramError(ProcmodError):
    """A model that cannot be written as procmod-examples/1 (only learned programs can)."""


def load_program(path: str | os.PathLike) -> Model:
    """A learned program (``program.json`` or its folder) as a procmod model.

    The model's name is the absolute path of ``program.json``, so saved derivations of it
    load again through ``procmod render`` and :func:`procmod.core.load_derivation`.
    """
    from .program import ProgramError, program_model, read_program

    if not isinstance(path, (str, os.PathLike)):
        raise ProgramError(f"a learned program is given by its path, got {type(path).__name__} {path!r:.40}")
    path = Path(path)
    if path.is_dir():
        path = path / "program.json"
    program = read_program(path)
    return program_model(program, str(path.resolve()))


def write_examples(model: Model, derivations, path: str | os.PathLike) -> None:
    """Write derivations of a learned program as one ``procmod-examples/1`` file, atomically.

    Mesh parts are referenced relative to ``path`` (pointing at the program's ``parts/``).

    Raises
    ------
    NotALearnedProgramError
        If ``model`` is not a learned program.
    """
    from .examples import FORMAT, ExamplesError
    from .program import derivation_hierarchies, is_learned

    if not is_learned(model):
        raise NotALearnedProgramError(
            f"model {model.name!r} is not a learned program; write_examples writes samples of programs "
            "learned from examples (procmod.learn.learn; read one with procmod.learn.load_program)")
    path = Path(path)
    if path.exists() and path.is_dir():
        raise ExamplesError(f"{argument('path')} {path} is a folder; give a file name ending in .json")
    if path.suffix.lower() != ".json":
        raise ExamplesError(f"{argument('path')} {path}: name the examples file with a .json suffix")
    program = model.root_args.args[0]
    examples = []
    for d in derivations:
        if not isinstance(d, Derivation) or not d.done:
            raise ExamplesError("write_examples needs complete derivations")
        examples.extend(derivation_hierarchies(d))
    source = Path(model.name).parent
    parts = {}
    out_dir = (path.parent if str(path.parent) else Path(".")).resolve()
    for name, spec in program.parts_json.items():
        if "mesh" in spec:
            parts[name] = {"mesh": os.path.relpath((source / spec["mesh"]).resolve(), out_dir)}
        else:
            parts[name] = dict(spec)
    path.parent.mkdir(parents=True, exist_ok=True)
    # which program drew them: procmod sample replaces such a file of its own without --overwrite
    sampled_from = Path(os.path.relpath(Path(model.name).resolve(), out_dir)).as_posix()
    write_text_atomic(path, json.dumps({"format": FORMAT, "sampled_from": sampled_from, "parts": parts,
                                        "examples": examples}) + "\n")


def learn(examples, out, particles: int = 4, workers: int | None = None, scheduler: str | None = None,
          seed: int = 0, options=None, samples: int = 10, progress=None, command: str = "",
          overwrite: bool = False, note=None) -> dict:
    """Learn a program from examples into the folder ``out``, as ``procmod learn`` does:
    the arguments and result of :func:`procmod.learn.pipeline.learn` (imported on call:
    the search needs torch)."""
    from .pipeline import learn as _learn
    return _learn(examples, out, particles=particles, workers=workers, scheduler=scheduler, seed=seed,
                  options=options, samples=samples, progress=progress, command=command, overwrite=overwrite,
                  note=note)


__all__ = ["FORMAT", "Dataset", "ExampleNode", "ExampleSet", "ExamplesError", "NotALearnedProgramError",
           "Program", "ProgramError", "examples_from_dict", "examples_to_dict", "learn", "load_program",
           "preprocess", "read_examples", "write_examples", "write_examples_file"]
