"""Training traces: SMC samples from the constrained model (seed 004 eq. 1).

Each trace is one final particle of an SMC run (600 particles by default) on a target
drawn from a training set (scribbles, or the circuit score), picked with probability
proportional to its weight. A trace file (``procmod-trace/1``) holds the target spec and
the particle's derivation (``procmod-derivation/2``): enough to recompute every feature
the networks are trained on.

Generation is embarrassingly parallel and goes through a ``concurrent.futures.Executor``
(:func:`procmod.parallel.open_executor`: inline, a local process pool, or dask). Trace i
depends only on (seed, i), so it does not matter where or in which order traces run.
Each finished trace is written at once, atomically; a rerun of the same job skips the
traces already on disk, so a killed job loses nothing it had finished. A folder of
another job (or holding anything else) is refused unless ``overwrite``, which replaces it
whole; a job that fails before its first trace leaves nothing behind.
"""

from __future__ import annotations

import concurrent.futures
import json
import os
import re
import shutil
import sys
import time
from pathlib import Path

import numpy as np

from ..core import InvalidArgumentError, ProcmodError
from ..core.errors import argument, plain_value, shown_value, whole_number
from ..core.runfolder import TRACES_JOB, RunFolder
from ..core.io import fingerprint, read_json, read_versioned_json, write_text_atomic
from ..core.serialize import derivation_to_dict
from .features import GuideError

TRACE_FORMAT = "procmod-trace/1"
JOB_FORMAT = "procmod-traces/1"
TARGET_SETS = ("scribble", "circuit")
SCRIBBLE_SET_SIZE = 49  # seed 004's 49 hand-drawn scribbles, each also mirrored
_TRACE_NAME = re.compile(r"^trace_(\d{5,})\.json$")


def trace_target_spec(targets: str, seed: int, index: int, set_size: int = SCRIBBLE_SET_SIZE) -> str:
    """The target of trace ``index``: drawn uniformly from the training set."""
    if targets == "circuit":
        return "circuit"
    if targets == "scribble":
        rng = np.random.default_rng([seed, index, 2])
        j = int(rng.integers(set_size))
        return f"scribble:{j}" + (":mirrored" if rng.random() < 0.5 else "")
    raise InvalidArgumentError(f"{argument('targets')} must be one of {', '.join(TARGET_SETS)}, got {targets!r}")


def job_code(model, model_file: str | None) -> tuple:
    """``(model code digest, procmod code digest)``: the code a trace is made with."""
    from ..parallel import procmod_code_digest

    return model_code_digest(model, model_file), procmod_code_digest()


def generate_trace(model_spec: str, target_spec: str, particles: int, seed: int, index: int,
                   code: tuple | None = None, params: dict | None = None) -> dict:
    """Run SMC on one target and keep one final particle, picked by weight.

    Module-level and fed plain values, so process pools and dask workers can run it
    (``model_spec``: a built-in model's name, or a model file's absolute ``FILE.py:NAME``,
    which a worker on another machine finds at the same path; ``params``: the job's model
    parameters, defaults where absent). ``code``: the job's
    :func:`job_code`; a worker that runs other code (another procmod, an edited model file)
    refuses to make the trace: a dask worker of an older checkout had made traces unlike
    the job's, recorded under the job's digest without a word. ``code`` is given only where
    the trace is made in another process than the job's: there an exception the model's own
    code raised that pickle cannot send back (its class's ``__init__`` takes other arguments,
    it holds a lambda) comes back as the one line a run in one process gives for it
    (:func:`procmod.parallel.portable_model_error`); it had ended the job in a
    BrokenProcessPool or PicklingError traceback.
    """
    try:
        return _generate_trace(model_spec, target_spec, particles, seed, index, code, params)
    except BaseException as exc:
        if code is None:  # made in the job's own process: its error as it is
            raise
        from ..parallel import portable_model_error

        portable = portable_model_error(exc, f"the worker making trace {index}")
        if portable is exc:
            raise
    # raised here, not in the except block: with no context, which a pickler of exceptions'
    # contexts (tblib's, as dask installs it for the classes defined then) would send along
    raise portable


def _generate_trace(model_spec: str, target_spec: str, particles: int, seed: int, index: int,
                    code: tuple | None, params: dict | None) -> dict:
    """:func:`generate_trace`'s work."""
    from ..data import target_from_spec
    from ..infer import smc
    from ..models import MODELS, model_from_spec

    began = time.perf_counter()
    model = model_from_spec(model_spec)
    if code is not None and job_code(model, None if model_spec in MODELS else model_spec) != tuple(code):
        import socket
        raise GuideError(f"a worker (on {socket.gethostname()}, procmod at {Path(__file__).resolve().parents[1]}) "
                         "runs other code than this traces job: another version of procmod or of the model's "
                         "files; give the workers the same procmod and model files (their PYTHONPATH) and rerun")
    if params:
        model = model.configure(**params)
    target = target_from_spec(target_spec)
    from ..core.random import global_draws_note, global_generator_states

    before = global_generator_states()
    result = smc(model, target, particles=particles, seed=int(np.random.SeedSequence([seed, index]).generate_state(1)[0]))
    # a model drawing from Python's or numpy's global generators makes traces the job's
    # seed does not fix (h145): said once by the job (generate_traces takes the key out).
    # Not on a dask worker: its own threads draw from Python's random while the trace runs
    # (every trace of the built-in chain model got the note, h146)
    drew = None if _on_dask_worker() else global_draws_note(before, "the model's rules")
    weights = np.asarray(result.log_weights, dtype=np.float64)
    rng = np.random.default_rng([seed, index, 1])
    if np.all(weights == -np.inf):
        chosen = int(rng.integers(len(weights)))
    else:
        p = np.exp(weights - weights.max())
        chosen = int(rng.choice(len(weights), p=p / p.sum()))
    particle = result.samples[chosen]
    return {"format": TRACE_FORMAT, "index": index, "target": target_spec, "particles": particles,
            "seed": seed, "score": float(target.score(particle.output)),
            "seconds": time.perf_counter() - began, "derivation": derivation_to_dict(particle),
            **({GLOBAL_DRAWS_KEY: drew} if drew else {})}


def _on_dask_worker() -> bool:
    """Whether this process is a dask.distributed worker (running a task)."""
    distributed = sys.modules.get("distributed")  # (never imported for it: a worker has it already)
    if distributed is None:
        return False
    try:
        distributed.get_worker()
    except (ValueError, AttributeError):
        return False
    return True


GLOBAL_DRAWS_KEY = "_global_draws"
"""The key of :func:`generate_trace`'s result that carries its global-draws note back to
the job (never written into the trace file)."""


def is_trace_name(name: str) -> bool:
    """Whether a file name is a trace's (``trace_00042.json``)."""
    return _TRACE_NAME.match(name) is not None


def trace_path(out: Path, index: int) -> Path:
    return out / f"trace_{index:05d}.json"


def _finished_traces(out: Path, count: int) -> tuple[set, list]:
    """``(indices of the whole traces in out, indices of damaged ones)`` for a resumed job.

    Traces are written whole (atomically), so a trace file that does not parse, or is not
    the trace of its number, was damaged or copied in from outside: a resumed job makes it
    again (it had counted any file of a trace's name as done, and training failed on it
    later). A JSON file of another format under a trace's name (a guide written there) is
    the user's: refused, naming it."""
    whole, damaged = set(), []
    for i in range(count):
        path = trace_path(out, i)
        if not path.exists():
            continue
        try:
            trace = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError, RecursionError):
            damaged.append(i)
            continue
        found = trace.get("format") if isinstance(trace, dict) else None
        if isinstance(found, str) and found != TRACE_FORMAT:
            raise GuideError(f"{path} is not a trace (its format is {shown_value(found)}) but has a trace's name, "
                             "so the job cannot make that trace: move the file out of the traces folder and rerun")
        if found == TRACE_FORMAT and trace.get("index") == i and isinstance(trace.get("target"), str) \
                and isinstance(trace.get("derivation"), dict):
            whole.add(i)
        else:
            damaged.append(i)
    return whole, damaged


def _job_settings(model, model_file, targets, particles, seed, set_size, params=None) -> dict:
    settings = {"format": JOB_FORMAT, "model": model.name, "targets": targets, "particles": particles,
                "seed": seed, "set_size": set_size}
    if params:  # (absent at the model's defaults: a job of before, which had none, is the same job)
        settings["params"] = {name: params[name] for name in sorted(params)}
    if model_file is not None:  # a model of the user's own file: which file (a job resumes only with it)
        settings["model_file"] = model_file
    settings["model_code"] = model_code_digest(model, model_file)
    return settings


def model_file_path(spec: str) -> Path:
    """The file of a model file spec (``FILE.py:NAME`` or ``FILE.py``)."""
    return Path(spec if spec.endswith(".py") else spec.rsplit(":", 1)[0])


def model_code_digest(model, model_file: str | None = None) -> str:
    """A digest of the code of ``model``'s rules (and of its model file), with the files
    beside them their import statements name (:func:`_imports_beside`): a traces job
    resumes only on the code it began with. A resumed job had mixed traces of an edited
    model with new ones, which training then refused one by one (or, after an edit of a
    helper module the choices still replayed under, took in silently). Comments, blank
    lines and trailing spaces are not code (:func:`code_text`): a comment added to the
    model file had stopped its job resuming, and the advice (``overwrite``) threw away
    every finished trace."""
    return _digest_of(_model_code_files(model, model_file), code_text)


def model_code_digests(model, model_file: str | None = None) -> tuple[str, str]:
    """``(digest, digest of the files' bytes)``: the second is the one jobs recorded
    before comments were left out of it (their folders still resume, their guides still
    compare)."""
    files = _model_code_files(model, model_file)
    return _digest_of(files, code_text), _digest_of(files, lambda data: data)


def _digest_of(files: list, text_of) -> str:
    digest = []
    for path in files:
        try:
            digest.append(fingerprint(text_of(path.read_bytes())))
        except OSError:
            digest.append("unreadable")
    return fingerprint(" ".join(digest))


def code_text(source: bytes) -> bytes:
    """``source`` without its comments, blank lines and trailing spaces: two files of one
    program with other comments give one text. Lines inside a string are kept as they are
    (they are the string's value). A file that does not tokenise is taken as it is."""
    import io
    import tokenize

    try:
        tokens = list(tokenize.tokenize(io.BytesIO(source).readline))
    except (tokenize.TokenError, SyntaxError, ValueError):
        return source
    layout = {tokenize.COMMENT, tokenize.NL, tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT,
              tokenize.ENCODING, tokenize.ENDMARKER}
    code_rows, comment_at, in_string = set(), {}, set()
    for token in tokens:
        if token.type == tokenize.COMMENT:
            comment_at[token.start[0]] = token.start[1]
        elif token.type not in layout:
            code_rows.update(range(token.start[0], token.end[0] + 1))
            in_string.update(range(token.start[0], token.end[0]))  # rows a string goes on past
    lines = source.decode(tokens[0].string if tokens and tokens[0].type == tokenize.ENCODING else "utf-8",
                          errors="replace").split("\n")  # rows as tokenize counts them
    kept = []
    for row in sorted(code_rows):
        line = lines[row - 1] if row <= len(lines) else ""
        if row in comment_at:  # token columns count characters of the decoded line
            line = line[:comment_at[row]]
        kept.append(line if row in in_string else line.rstrip())
    return "\n".join(kept).encode()


def _model_code_files(model, model_file: str | None) -> list:
    """The source files of ``model``'s rules and model file, and the files beside them
    that they import, sorted."""
    import inspect

    files = set()
    if model_file is not None:
        files.add(str(model_file_path(model_file)))
    for rule in (model.root, *model.rules):
        try:
            files.add(inspect.getsourcefile(inspect.unwrap(rule)))
        except (TypeError, OSError):  # a rule with no Python source (a builtin, a C function)
            pass
    # and the modules beside them that they import (a helper module of constants, the
    # built-in models' shared frame), read from their import statements: the modules a
    # process happens to have loaded would make the digest depend on the process
    pending = [(Path(f).resolve(), Path(f).resolve().parent) for f in files if f]
    files = set()
    while pending:
        path, root = pending.pop()
        if path in files:
            continue
        files.add(path)
        pending.extend((found, root) for found in _imports_beside(path, root))
    return sorted(files)


def _imports_beside(path: Path, root: Path) -> list:
    """The Python files under ``root`` (the folder of the model file or rule that began the
    search) that ``path``'s import statements name, found as Python finds them: absolute
    imports from ``root`` (``import helper``, ``from helpers.consts import X``), relative
    ones from ``path``'s own folder (``from .frame import Y``, ``from ..util import Z``);
    a package (with or without ``__init__.py``) before a module of its name, and the
    submodules a ``from`` names. Nothing for a file that does not parse; files outside
    ``root`` (procmod's own, the standard library) are not followed."""
    import ast

    try:
        tree = ast.parse(path.read_bytes())
    except (OSError, SyntaxError, ValueError):
        return []
    wanted = []  # (folder the name is looked up from, dotted name)
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            wanted += [(root, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = root if node.level == 0 else path.parents[node.level - 1] if node.level <= len(path.parents) \
                else None
            if base is None:
                continue
            module = node.module or ""
            if module:
                wanted.append((base, module))
            # a name imported from a package may be a submodule of it
            wanted += [(base, f"{module}.{alias.name}" if module else alias.name) for alias in node.names
                       if alias.name != "*"]
    found = []
    for base, name in wanted:
        folder = base
        for part in name.split("."):
            try:
                if (folder / part).is_dir():  # a package, as Python prefers it to a module of its name
                    folder = folder / part
                    if (folder / "__init__.py").is_file():
                        found.append(folder / "__init__.py")
                    continue
                if (folder / f"{part}.py").is_file():
                    found.append(folder / f"{part}.py")
            except OSError:  # a name too long to look up, a folder that cannot be read
                pass
            break
    return [f for f in found if f.is_relative_to(root)]  # (a link beside the model to a helper elsewhere: followed)


def _same_job(previous, settings: dict, byte_digest: str | None = None) -> bool:
    """Whether a folder's job file is this job's. A job file written before jobs recorded
    their model's code has no digest to compare: its settings decide. One written before
    comments were left out of the digest recorded the files' bytes (``byte_digest`` now)."""
    if not isinstance(previous, dict):
        return False
    if "model_code" not in previous:
        return _named(previous, settings) == _without_code(settings)
    if byte_digest is not None and previous["model_code"] == byte_digest:
        settings = {**settings, "model_code": byte_digest}
    return _named(previous, settings) == settings


def _without_code(settings: dict) -> dict:
    return {key: value for key, value in settings.items() if key != "model_code"}


def _named(previous: dict, settings: dict) -> dict:
    """A folder's job settings with its model file named as this job names it when the job
    named the same file without a Model's name (``plant.py``, whose one Model this job
    names, ``plant.py:PLANT``): one job however it was named (it had been refused as
    another). Another file, or a moved folder, stays another job: the code's digest does
    not cover the data files a model may read beside it."""
    spec, named = previous.get("model_file"), settings.get("model_file")
    if isinstance(spec, str) and isinstance(named, str) and ":" not in Path(spec).name \
            and named.rsplit(":", 1)[0] == spec:
        return {**previous, "model_file": named}
    return previous


def _differences(previous: dict, settings: dict) -> str:
    """What differs between a folder's job and this one, for a message."""
    keys = [k for k in dict.fromkeys([*previous, *settings]) if previous.get(k) != settings.get(k)]
    return "; ".join(f"{k} {shown_value(previous.get(k), 40)} there, {shown_value(settings.get(k), 40)} now"
                     for k in keys[:4])


MAX_TRACES = 10_000_000  # a job's count: its trace files in one folder, its list of the missing ones


def generate_traces(model_name: str, targets: str, count: int, out: str | os.PathLike, particles: int = 600,
                    seed: int = 0, executor: concurrent.futures.Executor | None = None,
                    set_size: int = SCRIBBLE_SET_SIZE, progress=None, overwrite: bool = False,
                    params: dict | None = None) -> dict:
    """Make ``count`` traces in ``out`` (resuming a previous run of the same job).

    ``model_name`` is a built-in model's name or a model of the user's own Python file
    (``FILE.py:NAME``; workers import the file from its absolute path). ``params``: model
    parameters every trace is drawn at (``Model.configure``; the defaults where absent),
    recorded in the job: a guide for runs at another drawing size trains on traces drawn
    at it.

    Everything is checked before the folder is touched: the settings, that the training
    targets fit the model, and ``out`` (see :class:`procmod.core.runfolder.RunFolder`).
    Returns a summary: traces made now, already present, seconds, traces per hour, and
    notes (a model that drew from the global generators, whose traces the seed does not fix).
    """
    from ..data import target_from_spec
    from ..infer.common import check_population
    from ..models import MODELS, model_from_spec
    from ..parallel import InlineExecutor, procmod_code_digest

    model = model_from_spec(model_name)  # fail early on an unknown model or a broken file
    if params is not None and not isinstance(params, dict):
        raise InvalidArgumentError(f"{argument('params')} must be a dict of model parameters, got "
                                   f"{shown_value(params)}")
    params = dict(params or {})
    configured = model.configure(**params) if params else model  # (refuses an unknown name or a bad value)
    # as configure took them (typed, plain), the defaults left out: a default given is the default job
    params = {name: configured.params[name] for name in params
              if plain_value(configured.params[name]) != plain_value(model.params[name])}  # ([0, -3] is (0, -3))
    from ..core.model import picture_placed
    placed = sorted(set(params) & set(picture_placed(model.params))) if targets == "scribble" else []
    if placed:
        # (h78: recorded, and every trace drawn at its scribble's own start, without a word)
        raise InvalidArgumentError(f"{argument('params')} {', '.join(placed)}: each training scribble places the "
                                   "model (where its drawing starts and heads), so traces cannot be drawn at a "
                                   "given one; leave it out (runs with a start of their own use the guide all the "
                                   "same)")
    model_file = None
    if model_name not in MODELS:
        from ..models.from_file import named_spec
        model_file = named_spec(model_name)  # plant.py:PLANT for plant.py: one job however it is named
    for name, value in (("count", count), ("particles", particles), ("set_size", set_size)):
        if whole_number(value) is None or value < 1:
            raise InvalidArgumentError(f"{argument(name)} must be a positive integer, got {shown_value(value)}")
    if whole_number(seed) is None or not 0 <= seed < 2 ** 63:
        raise InvalidArgumentError(f"{argument('seed')} must be a whole number from 0 to 2**63-1, got "
                                   f"{shown_value(seed)}")
    count, particles, set_size, seed = int(count), int(particles), int(set_size), int(seed)  # numpy's: plain
    if count > MAX_TRACES:
        raise InvalidArgumentError(f"{argument('count')} {count:,} traces is more than one job makes (at most "
                                   f"{MAX_TRACES:,}; seed 004 trains on 10,000); split it into jobs")
    first = target_from_spec(trace_target_spec(targets, seed, 0, set_size))  # validates the target set
    try:
        empty = first.new_output(first.configure(configured))
    except ProcmodError as exc:
        raise GuideError(f"{argument('targets')} {targets!r} does not fit model {model_name!r}: {exc}") from None
    check_population("particles", particles, empty)
    out = Path(out)
    folder = RunFolder(out, TRACES_JOB, overwrite)
    settings = _job_settings(model, model_file, targets, particles, seed, set_size, params)
    byte_digest = model_code_digests(model, model_file)[1]
    # what the workers must run (before anything is written): the job's model code and procmod's
    code = settings["model_code"], procmod_code_digest()
    job_file = out / "traces.json"
    resume = False
    if TRACES_JOB.recognises(out):
        previous = read_json(job_file, GuideError, "traces job file")
        resume = _same_job(previous, settings, byte_digest)
        if not resume and not overwrite:
            if isinstance(previous, dict) and "model_code" in previous and \
                    _without_code(previous) == _without_code(settings):
                raise GuideError(f"{out} holds traces of model {model.name!r} as its code was before an edit (its "
                                 "rules' source has changed since the job began): they may not replay under it; "
                                 f"pass {argument('overwrite=True')} to make them afresh, or give a new "
                                 f"{argument('out')} folder")
            what = ("its job file is not a JSON object" if not isinstance(previous, dict) else
                    _differences(_named(previous, settings), settings) if "model_code" in previous else
                    _differences(_named(previous, settings), _without_code(settings)))
            raise GuideError(f"{out} holds traces of another job ({what}); give a new "
                             f"{argument('out')} folder, the same settings to resume, or pass "
                             f"{argument('overwrite=True')} to replace it")
    present_ok, remade = _finished_traces(out, count) if resume else (set(), [])
    created = not out.exists()
    folder.prepare_in_place(keep=resume)
    # a job killed (SIGKILL) while writing a trace leaves write_text_atomic's temporary file
    # behind (never a half-written trace): a resumed job clears them
    for stale in out.glob(".trace_*.json.*"):
        stale.unlink(missing_ok=True)
    if not resume or previous.get("model_code") != settings["model_code"]:
        # (a job file of the byte digest resumed: it records today's, so a comment does not stop it next time)
        write_text_atomic(job_file, json.dumps(settings, indent=1) + "\n")
    missing = [i for i in range(count) if i not in present_ok]
    present = count - len(missing)
    executor = executor or InlineExecutor()
    # A bounded number of tasks in flight: finished traces are written while others run
    # (an inline executor runs a task as it is submitted, so it gets one at a time).
    in_flight = 1 if isinstance(executor, InlineExecutor) else 32
    code = None if isinstance(executor, InlineExecutor) else code
    began = time.perf_counter()
    queue = list(reversed(missing))
    running = {}
    done = 0
    notes = []  # what the traces' makers found (a model drawing from the global generators), once
    try:
        while queue or running:
            while queue and len(running) < in_flight:
                i = queue.pop()
                spec = trace_target_spec(targets, seed, i, set_size)
                # (params only when given: a job at the defaults calls as before)
                running[executor.submit(generate_trace, model_file or model_name, spec, particles, seed, i,
                                        code, *((params,) if params else ()))] = i
            finished, _ = concurrent.futures.wait(running, return_when=concurrent.futures.FIRST_COMPLETED)
            for future in finished:
                index = running.pop(future)
                try:
                    trace = future.result()
                except TypeError as exc:  # a worker of a procmod before the code check: other arguments
                    if "generate_trace()" not in str(exc):
                        raise
                    raise GuideError(f"a worker runs other code than this traces job (an older procmod: {exc}); "
                                     "give the workers the same procmod and model files (their PYTHONPATH) and "
                                     "rerun") from None
                drew = trace.pop(GLOBAL_DRAWS_KEY, None)
                if drew and not notes:
                    notes.append(drew)
                write_text_atomic(trace_path(out, index), json.dumps(trace) + "\n")
                done += 1
                if progress is not None:
                    progress(present + done, count)
    except BaseException:
        for future in running:  # don't wait for traces nobody will write
            future.cancel()
        if done == 0 and present == 0 and not resume:  # nothing made: leave nothing
            if created:
                shutil.rmtree(out, ignore_errors=True)
            else:
                job_file.unlink(missing_ok=True)
        raise
    seconds = time.perf_counter() - began
    return {"made": done, "present": present, "remade": remade, "seconds": seconds,
            "traces_per_hour": 3600.0 * done / seconds if done and seconds > 0 else None, "notes": notes}


def load_traces(folder: str | os.PathLike, limit: int | None = None) -> tuple[dict, list]:
    """The job settings and the traces of a folder (sorted by index; the first ``limit``)."""
    if limit is not None and (whole_number(limit) is None or limit < 1):
        raise GuideError(f"limit must be a positive whole number (the first traces to read), got {shown_value(limit)}")
    folder = Path(folder)
    job_file = folder / "traces.json"
    if not job_file.is_file():
        raise GuideError(f"{folder} is not a traces folder (no traces.json); make one with 'procmod guide traces'")
    settings = read_versioned_json(job_file, JOB_FORMAT, GuideError)
    if not isinstance(settings.get("model"), str) or not settings["model"]:
        raise GuideError(f"{job_file} names no model (its \"model\" is missing or not a name): it was edited or "
                         "not written by 'procmod guide traces'; put the model's name back, or make the traces again")
    names = sorted((int(m.group(1)), p) for p in folder.iterdir() if (m := _TRACE_NAME.match(p.name)))
    if limit is not None:
        names = names[:limit]
    traces = [read_versioned_json(path, TRACE_FORMAT, GuideError, advice="; delete it and rerun the traces job")
              for _, path in names]
    for (number, path), trace in zip(names, traces):
        if not isinstance(trace.get("target"), str):  # training read it first: a KeyError traceback
            raise GuideError(f"{path} is damaged (its \"target\" is missing or not a target's name); delete it and "
                             "rerun the traces job")
        if trace.get("index") != number:  # training's messages name a trace by its index: it must be its file's
            raise GuideError(f"{path} holds trace {shown_value(trace.get('index'))} (its \"index\"), not trace "
                             f"{number}: it was copied or renamed from another trace; delete it and rerun the traces "
                             "job (procmod guide traces makes it again)")
    if not traces:
        raise GuideError(f"{folder} holds no traces yet; run 'procmod guide traces' first")
    return settings, traces
