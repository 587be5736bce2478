"""The ``procmod`` command.

Every error a user can cause prints one line on stderr and exits with status 2, leaving
no partial output file behind. Output folders follow :mod:`procmod.core.runfolder`:
checked before the work, replaced whole (an earlier run of the same command, or any
folder with ``--overwrite``) or refused, never mixed.
"""

from __future__ import annotations

import argparse
import codecs
import contextlib
import dataclasses
import errno
import json
import math
import os
import re
import shlex
import signal
import sys
import threading
import _thread
from pathlib import Path

import numpy as np

from . import __version__
from .core import InvalidArgumentError, ProcmodError, load_derivation, run_forward, save_derivation
from .core.errors import DerivationFormatError, UnknownModelError, cut_text, printable, spelled
from .core.paths import is_dir_quietly, is_file_quietly, output_path
from .models import MODELS, model_from_spec


class _Parser(argparse.ArgumentParser):
    """argparse that reports a usage error as one line (exit 2) instead of usage text."""

    def error(self, message):
        raise InvalidArgumentError(f"{message} (see '{self.prog} --help')")


def _shown(text: str, limit: int = 60) -> str:
    """``repr`` of a command-line string cut to a readable length."""
    shown = repr(text)
    return shown if len(shown) <= limit else shown[:limit - 3] + "..."


def _int_arg(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {_shown(text)}") from None


def _add_overwrite(parser) -> None:
    parser.add_argument("--overwrite", action="store_true",
                        help="replace --out whole even if it holds something other than an earlier run of "
                             "this command (an earlier run is replaced without it)")


def _build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="procmod", description="Probabilistic procedural modeling.")
    parser.add_argument("--version", action="version", version=f"procmod {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True

    sub.add_parser("models", help="list the built-in models")

    sample = sub.add_parser("sample", help="sample a model forward; write pictures (2D: PNG+SVG, "
                                           "3D: PNG+OBJ+GLB) and the derivation JSON per sample")
    sample.add_argument("model", metavar="MODEL")
    sample.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                        help="set a model parameter (repeatable), e.g. --param leaves=false")
    sample.add_argument("-n", type=_int_arg, default=16, help="number of samples (default 16)")
    sample.add_argument("--seed", type=_int_arg, default=0, help="random seed (default 0)")
    sample.add_argument("--out", required=True, help="output folder (created if missing)")
    sample.add_argument("--size", type=_int_arg, default=256, help="render width in pixels (default 256)")
    sample.add_argument("--format", default="pictures", choices=("pictures", "examples"),
                        help="pictures (default): a folder of renders + derivations; examples: one "
                             "procmod-examples/1 JSON file at --out (learned programs)")
    _add_overwrite(sample)

    infer = sub.add_parser("infer", help="control a model toward a target with an engine")
    infer.add_argument("model", metavar="MODEL")
    infer.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                       help="set a model parameter (repeatable), e.g. --param leaves=false")
    infer.add_argument("--target", required=True,
                       help="glyph:CHAR, glyph:FACE/CHAR, scribble:N, circuit, an image file, or a "
                            "3D target (a procmod-volume/1 or procmod-silhouette/1 JSON, or a folder "
                            "holding target.json)")
    infer.add_argument("--engine", default="smc", help="smc, sosmc, mcmc, ga or forward (default smc)")
    infer.add_argument("--particles", type=_int_arg, help="particles (smc, sosmc, forward)")
    infer.add_argument("--population", type=_int_arg, help="population (ga)")
    infer.add_argument("--chains", type=_int_arg, help="chains (mcmc)")
    infer.add_argument("--budget", help="30s, 2m, 5000evals or 100gens, or several joined with + (100gens+30s: "
                                        "the first reached ends the run) (default: one SMC run, one forward batch, "
                                        "1600 MCMC sweeps, 50 GA generations)")
    infer.add_argument("--seed", type=_int_arg, default=0, help="random seed (default 0)")
    infer.add_argument("--guide", help="a trained neural guide (GUIDE.json with its GUIDE.npz or .pt) for --engine smc "
                       "or sosmc")
    infer.add_argument("--workers", type=_int_arg,
                       help="processes that step the particles (smc, sosmc) or run the chains (mcmc: "
                            "one chain each unless --chains says otherwise); default 1: this one; more help "
                            "where the cores are real and idle (README, 'SMC on several cores')")
    infer.add_argument("--ess-threshold", metavar="FRACTION|every|auto",
                       help="smc, sosmc: resample when the effective sample size falls below this fraction "
                            "of the particles; 'every': at every emit; default auto: every emit without a "
                            "guide, below 0.5 with one")
    infer.add_argument("--init-particles", type=_int_arg,
                       help="mcmc: the chains start from the best derivations of an SMC run of this many "
                            "particles (default 100; its time counts against --budget); 0: from forward samples")
    infer.add_argument("--out", required=True, help="output folder")
    infer.add_argument("--size", type=_int_arg, default=512, help="render width in pixels (default 512)")
    _add_overwrite(infer)

    render = sub.add_parser("render", help="render a saved derivation (2D: .png/.svg; 3D: .png/.obj/.glb)")
    render.add_argument("derivation", metavar="DERIVATION.json")
    render.add_argument("--out", required=True, help="output file: .png or .svg (2D), .png, .obj or .glb (3D)")
    render.add_argument("--size", type=_int_arg, default=512, help="width in pixels (default 512)")
    render.add_argument("--overwrite", action="store_true", help="replace an existing --out file")
    render.add_argument("--model", help="the model that made it, when it is not the built-in or learned program "
                                        "its file names: a model of your own, FILE.py:NAME")

    # Command groups that live beside their subsystem; each parser sets ``handler``.
    from .guide.cli import register as register_guide
    from .learn.cli import register as register_learn
    from .strings.cli import register as register_strings
    for register in (register_guide, register_learn, register_strings):
        register(sub, _int_arg)
    return parser


def _ess_threshold_arg(text: str):
    """``--ess-threshold``: a fraction in (0, 1], ``every`` (None) or ``auto``."""
    if text in ("every", "auto"):
        return None if text == "every" else "auto"
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not 0 < value <= 1:
        raise InvalidArgumentError(f"--ess-threshold takes a fraction in (0, 1], 'every' or 'auto', got {_shown(text)}")
    return value


def _cmd_models(args) -> None:
    width = max(len(name) for name in MODELS)
    for name in sorted(MODELS):
        print(f"{name:<{width}}  {MODELS[name].description}")



def _model(spec: str, params=(), typed: bool = True):
    """A built-in model by name, a learned program by path (program.json or its folder), or
    a model of the user's own Python file (``FILE.py:NAME``, :mod:`procmod.models.from_file`),
    with the ``--param NAME=VALUE`` settings applied (values read as JSON: ``false``, ``64``,
    ``[0.5, 0.9]``; anything else is a string). ``typed``: the user typed ``spec`` (it may
    be a file's stem: ``mine`` for ``mine.py``), not a file named it."""
    path = Path(spec)
    if spec not in MODELS and (path.suffix.lower() == ".json" or is_dir_quietly(path)):
        from .learn import load_program
        model = load_program(path)
    else:
        try:
            model = model_from_spec(spec)  # a built-in model, or FILE.py:NAME
        except UnknownModelError as exc:
            if typed and isinstance(spec, str) and not spec.endswith(".py") and is_file_quietly(Path(spec + ".py")):
                raise UnknownModelError(f"{exc}; for the model in {spec}.py give {spec}.py") from None
            raise
    if not params:
        return model
    return model.configure(**param_settings(model, params))


def param_settings(model, params) -> dict:
    """The ``--param NAME=VALUE`` settings as ``model.configure`` takes them (each value read
    as JSON, and the way its parameter's default is typed)."""
    settings = {}
    for item in params:
        name, sep, text = item.partition("=")
        if not sep or not name:
            raise InvalidArgumentError(f"--param takes NAME=VALUE, got {_shown(item)}")
        settings[name] = _as_param(_read_param(text), text, model.params.get(name))
    return settings


_TRUE, _FALSE = ("true", "1"), ("false", "0")  # any case: Python's True, JSON's true


def _read_param(text: str):
    """A ``--param`` value as JSON (``false``, ``64``, ``[0.5, 0.9]``), else as a number
    Python reads (``.5``), else the text itself."""
    try:
        return json.loads(text)
    except ValueError:  # not JSON (also an integer of more than 4300 digits)
        pass
    try:
        return float(text)
    except ValueError:
        return text


def _as_param(value, text: str, default):
    """A ``--param`` value read the way its parameter's default is typed, where a shell
    user's spelling leaves no doubt: ``leaves=False`` or ``0`` for a flag, ``size=50.0``
    for a count, ``start=0.5,0.9`` or ``.5 .9`` for a pair, ``label=1`` for a string.
    Anything else goes to the model's own check, whose message names what the parameter
    takes."""
    if isinstance(default, bool):
        word = text.strip().lower()
        return True if word in _TRUE else False if word in _FALSE else value
    if isinstance(default, str):
        return value if isinstance(value, str) else text
    if isinstance(default, int) and isinstance(value, float) and value.is_integer():
        return int(value)
    if isinstance(default, (list, tuple)):
        if isinstance(value, list):
            texts = [json.dumps(item) for item in value]
        else:  # 0.5,0.9 or "0.5 0.9" or (0.5; 0.9): the text within its quotes or brackets
            inner = value if isinstance(value, str) else text
            texts = [t for t in re.split(r"[,;\s]+", inner.strip().strip("()[]")) if t]
            value = [_read_param(t) for t in texts]
        if len(value) != len(default):
            return value  # the model's check names the length it takes
        return [_as_param(item, t, d) for item, t, d in zip(value, texts, default)]
    return value


def _count(n: int, noun: str) -> str:
    """``1 sample``, ``2 samples``."""
    return f"{n:,} {noun}" + ("" if n == 1 else "s")


CONTACT_SHEET_TILES = 64  # the first samples shown on a sample folder's contact sheet


def _model_inputs(name: str) -> list:
    """The files a model argument names: a learned program's ``program.json`` and what learn
    wrote beside it (its tensors and meshes are files it names, protected as such:
    core.paths.named_files_read), and the examples it was learned from, which ``sample --format examples --out`` could
    otherwise write over; nothing for a built-in model's name."""
    path = Path(name)
    try:
        if path.is_dir():
            path = path / "program.json"
        if not path.is_file():
            return []
    except (OSError, ValueError):
        return []
    # and what learn wrote beside it (report.json, the checkpoint were written over); other
    # files there (the user's own samples file) are not the program's
    from .core.runfolder import LEARN_RUN
    try:
        written = [entry for entry in path.parent.iterdir() if LEARN_RUN.owns(entry.name)]
    except OSError:
        written = []
    return [path, *written, *_learned_from(path)]


def _learned_from(program_json: Path) -> list:
    """The example files or folders a learned program records it was learned from
    (``info.example_files``, relative to its folder; a program of an earlier version: its
    ``info.examples`` where that is one existing path), as far as they exist; nothing from
    a file that says otherwise."""
    try:
        info = json.loads(program_json.read_text(encoding="utf-8")).get("info")
    except (OSError, ValueError, AttributeError):
        return []
    if not isinstance(info, dict):
        return []
    named = info.get("example_files")
    if isinstance(named, list):
        named = [program_json.parent / item for item in named if isinstance(item, str) and item]
    else:
        named = [Path(info["examples"])] if isinstance(info.get("examples"), str) and info["examples"] else []
    found = []
    for item in named:
        try:
            if item.exists():
                found.append(item)
        except (OSError, ValueError):
            continue
    return found


def _cmd_sample(args) -> None:
    import json

    from .core.limits import check_disk, check_memory
    from .core.random import global_draws_note, global_generator_states
    from .core.runfolder import SAMPLE_RUN, RunFolder, check_output_file
    from .core.serialize import derivation_to_dict
    from .render import check_size, is_2d, output_formats, write_contact_page, write_contact_sheet, write_derivation

    model = _model(args.model, args.param)
    if args.n < 1:
        raise InvalidArgumentError(f"-n must be a positive number of samples, got {args.n}")
    if args.seed < 0:
        raise InvalidArgumentError(f"--seed must be a non-negative integer, got {args.seed}")
    size = check_size(args.size)
    out = output_path(args.out)
    inputs = _model_inputs(args.model)

    drew = []  # global_draws_note's, once

    def sample(i: int):
        # Sample i depends only on (seed, i), so asking for more samples keeps the first ones.
        before = global_generator_states()
        derivation = run_forward(model, np.random.default_rng([args.seed, i]))
        if not drew:
            note = global_draws_note(before, "the model's rules")
            if note is not None:
                drew.append(note)
                print(f"note: {note}", file=sys.stderr)
        return derivation

    if args.format == "examples":
        from .learn import NotALearnedProgramError, is_learned, write_examples
        if not is_learned(model):
            raise NotALearnedProgramError(
                f"model {model.name!r} is not a learned program; '--format examples' writes samples of "
                "programs made by 'procmod learn' (give the program.json path or its folder)")
        check_output_file(out, inputs=inputs, overwrite=args.overwrite or _examples_file(out))
        first = sample(0)
        check_memory(f"-n {args.n:,} samples", args.n * len(json.dumps(derivation_to_dict(first))),
                     "ask for fewer samples")
        with spelled({"path": "--out"}):  # write_examples names its file argument
            write_examples(model, [first] + [sample(i) for i in range(1, args.n)], out)
        print(f"wrote {_count(args.n, 'sample')} of {model.name} to {out} (procmod-examples/1)")
        return
    folder = RunFolder(out, SAMPLE_RUN, args.overwrite, inputs=inputs)
    digits = max(3, len(str(args.n - 1)))
    shown = []  # the first samples, for the contact sheet: the rest are written and dropped
    with folder.writing() as tmp:
        for i in range(args.n):
            derivation = sample(i)
            stem = tmp / f"sample_{i:0{digits}d}"
            save_derivation(derivation, stem.with_suffix(".json"))
            for suffix in output_formats(derivation):
                write_derivation(derivation, stem.with_suffix(suffix), size)
            if i == 0:  # the first sample's files tell what all of them need on disk
                each = sum(p.stat().st_size for p in tmp.iterdir())
                check_disk(f"-n {args.n:,} samples", float(args.n) * each, tmp.parent,
                           f"each takes about {each:,} bytes; ask for fewer samples or a smaller --size")
            if i < CONTACT_SHEET_TILES:
                shown.append(derivation)
        write_contact_sheet(shown, tmp / "contact_sheet.png", labels=[str(i) for i in range(len(shown))])
        if not is_2d(shown[0]):  # 3D: also a page of samples to turn in a browser
            write_contact_page(shown, tmp / "contact_sheet.html", labels=[str(i) for i in range(len(shown))],
                               links=[f"sample_{i:0{digits}d}.glb" for i in range(len(shown))],
                               title=f"{_page_name(model.name)}: {_count(args.n, 'sample')}, seed {args.seed}"
                               + (f" (the first {len(shown)} shown)" if len(shown) < args.n else ""))
    more = f"; the first {len(shown)} on" if len(shown) < args.n else "; contact sheet:"
    page = "" if is_2d(shown[0]) else f" and {out / 'contact_sheet.html'} (turn them in a browser)"
    print(f"wrote {_count(args.n, 'sample')} of {model.name} to {out}/{more} {out / 'contact_sheet.png'}{page}")


def _page_name(name: str) -> str:
    """A model's name as a page shows it: a learned program by its folder and file
    (``castles/program.json``), not the absolute path it is known by, which a page sent
    to someone would show them."""
    path = Path(name)
    if name in MODELS or path.suffix.lower() != ".json" or not path.is_absolute():
        return name
    return f"{path.parent.name}/{path.name}" if path.parent.name else path.name


def _examples_file(path: Path) -> bool:
    """Whether ``path`` is a samples file ``sample --format examples`` wrote (replaced
    without ``--overwrite``, as an earlier run folder of the same command is): one that
    says which program it was ``sampled_from``; an example set of the user's (the same
    format, the input of ``learn``) does not."""
    from .core.io import read_json
    from .core.errors import ProcmodError
    from .learn.examples import FORMAT as EXAMPLES_FORMAT

    if not path.is_file() or path.stat().st_size > (1 << 30):
        return False
    try:
        data = read_json(path, ProcmodError, "file")
    except ProcmodError:
        return False
    return isinstance(data, dict) and data.get("format") == EXAMPLES_FORMAT and isinstance(data.get("sampled_from"), str)


def _cmd_render(args) -> None:
    from .core.runfolder import check_output_file
    from .render import check_format, check_size, output_formats, write_derivation

    check_format(args.out)
    out = check_output_file(args.out, inputs=[args.derivation])  # an existing file: once its inputs are known
    size = check_size(args.size)
    # --model must be the model the file names: a derivation of another model of the same
    # root rule was drawn with it, where the library refuses it ("give its model"); a file
    # that names a Python file, or a learned program, is the user's to pair with --model
    given = None if args.model is None else _model(args.model)

    def the_given_model(name: str):
        from .models.from_file import is_model_file_spec
        if name != given.name and not is_model_file_spec(name) and not name.lower().endswith(".json"):
            raise DerivationFormatError(f"it is a derivation of model {name!r}, not {given.name!r}: give its model")
        return given  # (another learned program than the one it names: refused by derivation_from_dict)

    try:
        derivation = load_derivation(args.derivation, _model_a_file_names if given is None else the_given_model)
    except UnknownModelError as exc:
        if args.model is not None:
            raise
        raise UnknownModelError(f"{exc}; for a model of your own, give it: --model FILE.py:NAME") from None
    check_format(args.out, output_formats(derivation))
    # the files of the program it names, read only now (a part's mesh was written over)
    check_output_file(out, inputs=[args.derivation, *_model_inputs(derivation.model.name)], overwrite=args.overwrite)
    write_derivation(derivation, out, size)
    print(f"wrote {out}")


def _target_inputs(spec: str) -> list:
    """The file a target spec reads, for --out's protection of its inputs, also under its
    ``:mirrored`` suffix (as given, that spec names no file, so the folder holding the
    picture was replaced, the picture with it). (A sidecar lies beside its picture.)"""
    from .data import MIRROR_SUFFIX

    return [spec[: -len(MIRROR_SUFFIX)] if spec.endswith(MIRROR_SUFFIX) else spec]


def _placed_by_params(target, model, params):
    """``target`` with the start and direction given as ``--param start=X,Y`` /
    ``direction=DX,DY`` where it places the model (a picture: it sets them, from its
    sidecar or its drawing): the user's word wins over the picture's guess, as a sidecar's
    does (a start alone grows up the picture). They were silently replaced."""
    from .targets import TargetImage

    given = {item.partition("=")[0] for item in params or ()} & {"start", "direction"}
    image = getattr(target, "image", None)
    if not given or not isinstance(image, TargetImage) or not given <= set(model.params):
        return target
    placed = {name: tuple(float(v) for v in model.params[name]) for name in given}
    if "direction" not in placed:
        placed["direction"] = (0.0, -1.0)
    if "start" in placed and image.picture is not None and image.picture[2:] != image.mask.shape:
        # normalised coordinates of the picture, as a sidecar's: mapped into the square it is
        # padded to (a 400 x 200 picture's bottom middle was the padding below it); a square
        # picture is its own square, its start kept exactly
        from .targets.image import point_in_square
        placed["start"] = point_in_square(placed["start"], *image.picture[2:])
    target.image = dataclasses.replace(image, **placed)
    return target


def _model_a_file_names(name: str):
    """The model a derivation file names: a built-in model or a learned program, never a
    Python file's (``FILE.py:NAME``): a file read is data, and running code it names would
    let a downloaded derivation run anything. procmod writes a model of the user's own
    file under its model's name, which ``--model FILE.py:NAME`` then gives."""
    from .models.from_file import is_model_file_spec

    if name not in MODELS and is_model_file_spec(name):
        raise UnknownModelError(f"it names the Python file {cut_text(name, 120)!r} as its model; procmod does not "
                                "run code a file names (procmod never writes one there)")
    return _model(name, typed=False)


_POPULATION_OPTION = {"smc": "particles", "sosmc": "particles", "forward": "particles",
                      "ga": "population", "mcmc": "chains"}


def _cmd_infer(args) -> None:
    from .core.runfolder import INFER_RUN, RunFolder
    from .infer import ENGINES, parse_budget
    from .infer.common import check_population
    from .render import check_size
    from .report import write_run

    model = _model(args.model, args.param)
    if args.engine not in ENGINES:
        raise InvalidArgumentError(f"unknown engine {_shown(args.engine)}; choose one of {', '.join(ENGINES)}")
    wanted = _POPULATION_OPTION[args.engine]
    kwargs = {}
    for option in ("particles", "population", "chains"):
        value = getattr(args, option)
        if value is None:
            continue
        if option != wanted:
            raise InvalidArgumentError(f"--{option} does not apply to --engine {args.engine}; use --{wanted}")
        if value < 1:
            raise InvalidArgumentError(f"--{option} must be a positive integer, got {value}")
        kwargs[option] = value
    if args.seed < 0:
        raise InvalidArgumentError(f"--seed must be a non-negative integer, got {args.seed}")
    if args.engine in ("smc", "sosmc", "mcmc"):
        if args.workers is not None and args.workers < 1:
            raise InvalidArgumentError(f"--workers must be a positive integer, got {args.workers}")
        if args.workers is not None:
            from .parallel import check_worker_limit
            check_worker_limit(args.workers)
        kwargs["workers"] = 1 if args.workers is None else args.workers
        if args.engine == "mcmc" and "chains" not in kwargs:
            kwargs["chains"] = kwargs["workers"]  # one chain per worker
    elif args.workers is not None:
        raise InvalidArgumentError(f"--workers applies to --engine smc, sosmc or mcmc, not {args.engine}")
    if args.ess_threshold is not None:
        if args.engine not in ("smc", "sosmc"):
            raise InvalidArgumentError(f"--ess-threshold applies to --engine smc or sosmc, not {args.engine}")
        kwargs["ess_threshold"] = _ess_threshold_arg(args.ess_threshold)
    if args.init_particles is not None:
        if args.engine != "mcmc":
            raise InvalidArgumentError(f"--init-particles applies to --engine mcmc, not {args.engine}")
        if args.init_particles < 0:
            raise InvalidArgumentError(f"--init-particles must be 0 or more, got {args.init_particles}")
        kwargs["init_particles"] = args.init_particles
    size = check_size(args.size)
    budget = parse_budget(args.budget) if args.budget is not None else None
    shadowed = None
    if args.guide is not None:
        if args.engine not in ("smc", "sosmc"):
            raise InvalidArgumentError(f"--guide works with --engine smc or sosmc, not {args.engine}")
        from .guide import Guide
        from .guide.guide import shadowing_note
        guide = Guide.load(args.guide)
        guide.check_model(model)
        kwargs["guide"] = guide
        shadowed = shadowing_note(args.guide)
        if shadowed is not None:
            print(f"note: {shadowed}", file=sys.stderr)
    from .data import target_from_spec

    target = _placed_by_params(target_from_spec(args.target), model, args.param)
    inputs = [*_target_inputs(args.target), *_model_inputs(args.model)]
    if args.guide is not None:
        from .guide import guide_paths
        inputs += guide_paths(args.guide)  # a guide given as a stem is its .pt and .json
    folder = RunFolder(args.out, INFER_RUN, args.overwrite, inputs=inputs)
    empty = target.new_output(target.configure(model))  # fail early if the target does not fit the model
    if wanted in kwargs:
        # an incremental MCMC chain holds three outputs at least (procmod.infer.mcmc)
        check_population(f"--{wanted}", kwargs[wanted], empty, copies=3 if wanted == "chains" else 1)
    if kwargs.get("init_particles"):
        check_population("--init-particles", kwargs["init_particles"], empty)
    from .targets.placement import placement_note
    note = placement_note(model, target, np.random.default_rng(args.seed))  # its own stream: the run's is untouched
    if note is not None:
        print(f"note: {one_line(note)}", file=sys.stderr)
    with _progress_bar(budget) as progress:
        result = ENGINES[args.engine](model, target, seed=args.seed, budget=budget, progress=progress, **kwargs)
    if result.best is None:
        from .infer.common import no_result_error
        raise no_result_error(result)
    for engine_note in result.notes:  # what the engine says of its run (in the report too)
        print(f"note: {one_line(engine_note)}", file=sys.stderr)
    used = result.settings.get("workers")
    if args.workers is not None and isinstance(used, int) and used < args.workers:
        # a worker per particle or chain at most: the rest would have had nothing to step
        shared = kwargs.get(wanted)
        why = (f": a worker steps {wanted} of its own, and there {'was' if shared == 1 else 'were'} {shared}"
               if isinstance(shared, int) and shared <= used else "")
        workers_note = f"--workers {args.workers} ran on {used}{why}"
        print(f"note: {workers_note}", file=sys.stderr)
        result.notes.append(workers_note)  # in settings.json and the report, beside the command that asked more
    if note is not None:
        result.notes.append(note)  # in the report too, beside the result it explains
    if shadowed is not None:  # recorded: the same command gives another result in another folder
        result.notes.append(shadowed)
    with folder.writing() as tmp:
        write_run(result, target, tmp, size, args.command_line)
    report = Path(args.out) / "report.html"
    print(f"{result.engine}: best score {result.best_score:.4f} after {result.evaluations} evaluations "
          f"in {result.seconds:.3g} s; report: {report}")


class _progress_bar:
    """A progress bar on stderr (:func:`procmod.progress.progress_bar`), fed by the engine."""

    def __init__(self, budget):
        self.budget = budget

    def __enter__(self):
        from .progress import progress_bar
        self.bar = progress_bar(total=100 if self.budget is not None else None,
                                unit="%" if self.budget else " evals")

        def update(tracker):
            if self.budget is not None:
                self.bar.n = round(100 * tracker.fraction(), 1)
            else:
                self.bar.n = tracker.evaluations
            self.bar.set_postfix(best=f"{tracker.best_score:.3f}", refresh=False)
            self.bar.refresh()

        return update

    def __exit__(self, *exc):
        self.bar.close()
        return False


# How the command line spells the API arguments that library messages name (see
# procmod.core.errors.argument): every command's output is --out (the functions' ``out``).
# Each flag here means the same argument in every command that has it (guide, learn and
# strings subcommands run under main too). The last three keys are written out, not
# imported, so that the command line loads no torch to start: guide.train.LOCAL_FEATURES,
# strings.torch_utils.CPU_DEVICE and strings.pipeline.TRAIN_MODEL.
CLI_SPELLING = {
    "out": "--out", "overwrite=True": "--overwrite", "scheduler": "--scheduler", "seed": "--seed", "workers=1": "--workers 1",
    "particles": "--particles", "targets": "--targets", "device": "--device", "workers": "--workers",
    "count": "--count", "samples": "--samples", "size": "--size", "population": "--population",
    "strings_per_shape": "--strings-per-shape", "tagger_strings_per_shape": "--tagger-strings-per-shape",
    "held_out": "--held-out", "params": "--param", "init_particles": "--init-particles",
    "settings=FeatureSettings.condition('local')": "--features local",
    "device='cpu'": "--device cpu",
    "train_model(COLLECTION, out=MODEL)": "'procmod strings train COLLECTION --out MODEL'",
}

_COMMANDS = {"models": _cmd_models, "sample": _cmd_sample, "render": _cmd_render, "infer": _cmd_infer}


def one_line(message: str, limit: int = 600) -> str:
    """An error message as one readable line: line breaks (a library's multi-line advice)
    become spaces, other control characters escapes (``\\x1b``), and a message longer
    than ``limit`` keeps its start and its end (the advice) around a cut."""
    text = re.sub(r"\s*\n\s*", " ", str(message)).strip()
    # other control characters from an input (a terminal's escape codes, a CR that would
    # overwrite the line) are shown as escapes, not acted on by the terminal
    text = printable(text)
    if len(text) > limit:
        text = text[:limit // 2 - 3] + " ... " + text[-(limit // 2 - 3):]
    return text


class Terminated(KeyboardInterrupt):
    """SIGTERM (``kill``, ``timeout``, a job scheduler) turned into an interrupt, so that a
    command stops as it does on Ctrl-C: temporary files and folders removed, nothing
    half-written left (killed outright, a run left its hidden ``.OUT.*.tmp`` folder)."""


# The stops (Terminated, KeyboardInterrupt) the signal handlers below raised during the
# command. One raised inside a ctypes callback is printed and dropped by ctypes ("Exception
# ignored on calling ctypes callback function"), as when it came while numba compiled a
# kernel (a first run, no cached machine code): the command went on to the end of its
# budget, or numba's compile failed with a RuntimeError of its own ("no compiled object
# yet"), a 60-line traceback and status 1 for a Ctrl-C. Such a stop is raised again.
_RAISED_STOPS: list = []


def _terminate(signum, frame):
    _RAISED_STOPS.append(Terminated())
    raise _RAISED_STOPS[-1]


def _interrupt(signum, frame):
    """Python's own Ctrl-C handler, noting the interrupt in :data:`_RAISED_STOPS`."""
    _RAISED_STOPS.append(KeyboardInterrupt())
    raise _RAISED_STOPS[-1]


@contextlib.contextmanager
def _sigterm_as_interrupt():
    """Install :func:`_terminate` for SIGTERM and :func:`_interrupt` for SIGINT while a
    command runs, where nobody else handles them (an application that embeds procmod keeps
    its own handlers). Only on the main thread, which signals reach: a command run in another
    thread changes nothing global (two overlapping had left one's hook installed)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _RAISED_STOPS.clear()
    previous = {}
    for signum, ours, default in ((signal.SIGTERM, _terminate, signal.SIG_DFL),
                                  (signal.SIGINT, _interrupt, signal.default_int_handler)):
        try:
            if signal.getsignal(signum) == default:
                signal.signal(signum, ours)
                previous[signum] = default
        except ValueError:  # (an interpreter's other than the main one)
            pass
    unraisable_hook = sys.unraisablehook
    again = []

    def dropped(unraisable):
        stop = next((stop for stop in _RAISED_STOPS if unraisable.exc_value is stop), None)
        if stop is None:
            unraisable_hook(unraisable)
            return
        # a stop of ours that a library dropped: signalled again a moment later, from another
        # thread (signalled now, it would be raised in this hook, and dropped again), once the
        # main thread has left the callback; said once, by main
        timer = threading.Timer(0.05, _thread.interrupt_main,
                                (signal.SIGTERM if isinstance(stop, Terminated) else signal.SIGINT,))
        timer.daemon = True
        again.append(timer)
        timer.start()

    sys.unraisablehook = dropped
    try:
        yield
    finally:
        sys.unraisablehook = unraisable_hook
        for timer in again:  # the command ended first (a library's error that followed the stop)
            timer.cancel()
        for signum, handler in previous.items():
            signal.signal(signum, handler)


_FULL = {code for code in (getattr(errno, "ENOSPC", None), getattr(errno, "EDQUOT", None)) if code is not None}


def _stopped_by(exc: BaseException):
    """The Ctrl-C or SIGTERM an exception was raised while handling, if any: a library's
    clean-up that failed as the stop passed through it (``torch.save``'s zip writer,
    "unexpected pos") had printed a 40-line traceback in place of one line."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        seen.add(id(exc))
        if isinstance(exc, (Terminated, KeyboardInterrupt)):
            return exc
        exc = exc.__context__
    return None


def _negative_values_joined(argv: list) -> list:
    """``--budget -1s`` as ``--budget=-1s``: argparse takes a value that starts with a minus
    and is no plain number for an option of its own, and said "expected one argument",
    where the option's own check says what is wrong with the value."""
    out = []
    for token in argv:
        # a number with a unit (-1s, -2m+5evals): a plain negative number argparse reads itself
        # (and may be a positional after a flag); nothing after "--" is an option's
        if out and "--" not in out and re.match(r"-\.?\d[\d.]*[a-zA-Z+]", token) and out[-1].startswith("--") \
                and "=" not in out[-1]:
            out[-1] = f"{out[-1]}={token}"
        else:
            out.append(token)
    return out


def _printable(exc: UnicodeError):
    """The terminal streams' encoding error handler: a file name's undecodable bytes
    (Python's surrogate escapes, U+DC80-U+DCFF) printed as the bytes they were, anything
    else the stream cannot encode as a backslash escape. ``surrogateescape`` alone failed
    on a lone surrogate a JSON file spelled ("\\ud800" in a part name): the one-line
    refusal quoting it became a traceback ("lost sys.stderr")."""
    if not isinstance(exc, UnicodeEncodeError):
        raise exc
    out = bytearray()
    for c in exc.object[exc.start:exc.end]:
        code = ord(c)
        if 0xDC80 <= code <= 0xDCFF:
            out.append(code - 0xDC00)
        else:
            out += (f"\\u{code:04x}" if code <= 0xFFFF else f"\\U{code:08x}").encode("ascii")
    return bytes(out), exc.end


codecs.register_error("procmod-printable", _printable)


def main(argv=None) -> int:
    """Entry point of the ``procmod`` console script; returns the exit status."""
    argv = _negative_values_joined(sys.argv[1:] if argv is None else [str(a) for a in argv])
    for stream in (sys.stdout, sys.stderr):  # a file name's non-UTF-8 bytes printed as they are, not a traceback
        try:
            stream.reconfigure(errors="procmod-printable")
        except (AttributeError, ValueError, OSError):  # a stream that is no text file (a test's capture)
            pass
    try:
        with _sigterm_as_interrupt():
            args = _build_parser().parse_args(argv)
            args.command_line = "procmod " + shlex.join(argv)  # recorded in reports
            handler = getattr(args, "handler", None) or _COMMANDS[args.command]
            with spelled(CLI_SPELLING):  # library messages name API arguments; here they read as flags
                handler(args)
    except ProcmodError as exc:
        print(f"procmod: error: {one_line(exc)}", file=sys.stderr)
        return 2
    except Terminated:
        print("procmod: terminated", file=sys.stderr)
        return 143
    except KeyboardInterrupt:
        print("procmod: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # the reader of stdout went away (``procmod strings encode ... | head -1``): what it
        # wanted it has; end quietly, as a Unix filter does, and keep Python's exit-time
        # flush of stdout from failing again
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except (OSError, ValueError):
            pass
        return 141  # 128 + SIGPIPE, what a shell reports for a filter ended by it
    except BaseException as exc:  # (a model's rule may raise sys.exit() or its own BaseException: its error too)
        dropped = _RAISED_STOPS[-1] if _RAISED_STOPS and threading.current_thread() is threading.main_thread() \
            else None  # (one a library dropped; recorded for the main thread's command only)
        stop = _stopped_by(exc) or dropped
        if stop is not None:  # a library's clean-up failed on the way out of a stop (torch's zip writer)
            print("procmod: terminated" if isinstance(stop, Terminated) else "procmod: interrupted", file=sys.stderr)
            return 143 if isinstance(stop, Terminated) else 130
        # an error in a model file of the user's own (FILE.py:NAME): their code, one line
        # naming where (sys.exit() in a rule included: it had ended every engine with status
        # 0 and no word); a name too long for the file system, the user's too (every check of
        # a path given on the command line would otherwise have to expect it); anything else
        # is procmod's bug, or argparse's own exit, and goes on as it is
        from .models.from_file import user_code_error
        line = user_code_error(exc)
        if line is None and isinstance(exc, OSError) and exc.errno == errno.ENAMETOOLONG:
            named = f" ({cut_text(str(exc.filename), 80)})" if exc.filename else ""
            line = f"a file name is too long for the file system{named}; give a shorter path"
        if line is None and isinstance(exc, OSError) and exc.errno in _FULL:  # the run folder is left as it was
            named = f" {cut_text(str(exc.filename), 80)}" if exc.filename else ""
            gave_out = any(a == "--out" or a.startswith("--out=") for a in argv)
            if exc.filename:  # a file of the run's
                where = ", or give --out elsewhere" if gave_out else ""
            else:  # a handle's write: a file of the run's, or what the command prints (> /dev/full)
                where = (" where it is written (the --out folder, or where the printed output goes)" if gave_out
                         else ", or send the printed output elsewhere")
            line = f"cannot write{named}: {exc.strerror or 'the disk is full'}; free some space{where}"
        if line is None and isinstance(exc, OSError) and exc.errno == getattr(errno, "EFBIG", None):
            # a file-size limit (ulimit -f) or a file system's largest file (FAT32's 4 GiB)
            named = f" {cut_text(str(exc.filename), 80)}" if exc.filename else ""
            line = (f"cannot write{named}: {exc.strerror or 'file too large'} (a file-size limit, ulimit -f, or the "
                    "file system's largest file); raise the limit, or give --out on another file system")
        if line is None:
            raise
        print(f"procmod: error: {one_line(line)}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
