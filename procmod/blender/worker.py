"""The procmod side of the Blender add-on: one job in its own process.

    python -m procmod.blender.worker JOB_FOLDER

Blender runs this in a separate process (so long work never freezes its UI, a job can be
stopped or killed, and procmod's dependencies need not be installed into Blender's own
Python) with the Python of an environment where procmod is installed. The add-on writes
``JOB_FOLDER/job.json`` (``procmod-blender-job/1``) and the files it names, then reads:

- ``progress.json`` — ``{"fraction": 0.42 or null, "message": "..."}``, replaced as the job
  goes (atomically: the add-on never reads half a file);
- ``result.json`` — written last: ``{"ok": true, ...}`` or ``{"ok": false, "error": "one
  line"}`` (the line a ``procmod`` command would print; a traceback only goes to the log);
- a file ``stop`` that the add-on creates asks an engine to end early: it finishes the
  current step and writes its run with the best result so far.

Commands (``job["command"]``), each with the library's own functions:

- ``sample``: ``count`` derivations of ``model`` from ``seed`` (sample i from ``(seed, i)``,
  as ``procmod sample``);
- ``infer``: the target is built from the scene's files (``volume``: the meshes, in procmod's
  frame, written as a ``procmod-volume/1`` folder that the library voxelizes onto one grid;
  ``silhouette``: a camera and a weight image written as ``procmod-silhouette/1``), then an engine runs and the run folder
  is written as ``procmod infer`` writes it (:func:`procmod.report.write_run`), its command
  line recorded so the CLI can repeat it;
- ``learn``: :func:`procmod.learn.learn` on the selected hierarchies, exported by the
  add-on as GLB files (or a ``procmod-examples/1`` file), then ``count`` samples of the
  learned program.

Every result holds the parts of its derivations (``samples``) in the form
:func:`derivation_parts` writes, for the add-on to build objects from.
"""

from __future__ import annotations

import json
import math
import os
import re
import shlex
import sys
import traceback
from pathlib import Path

import numpy as np

from ..core.io import write_text_atomic
from .jobs import JOB_FORMAT

MAX_VOXELS = 4_000_000  # a target grid above this is refused (each voxel is scored per part drawn)
AUTO_VOXELS = 40_000  # voxel_size 0 picks the size that gives about this many voxels
POPULATION_OPTION = {"smc": "particles", "sosmc": "particles", "forward": "particles",
                     "ga": "population", "mcmc": "chains"}


class JobError(Exception):
    """A job file the add-on wrote wrongly (a bug, not the user's doing)."""


# ---- files -------------------------------------------------------------------------------------

def write_json_atomic(path: Path, data) -> None:
    """``data`` as JSON in ``path``, atomically: the add-on never reads half a file."""
    write_text_atomic(path, json.dumps(data))


class Progress:
    """Writes ``progress.json`` at most every ``interval`` seconds, and sees the stop file."""

    def __init__(self, folder: Path, interval: float = 0.2):
        self.folder, self.interval = folder, interval
        self._last = -math.inf

    def __call__(self, fraction, message: str, force: bool = False) -> None:
        import time
        now = time.monotonic()
        if force or now - self._last >= self.interval:
            self._last = now
            write_json_atomic(self.folder / "progress.json", {"fraction": fraction, "message": message})

    @property
    def stop_requested(self) -> bool:
        return (self.folder / "stop").exists()


# ---- derivations as parts ----------------------------------------------------------------------

def derivation_parts(derivation) -> dict:
    """The parts of a derivation for Blender.

    ``{"parts": [...], "meshes": [...], "colours": {tag: [r, g, b]}, "bounds": [lo, hi]}`` — each part is
    ``{"kind": "box" | "cylinder" | "mesh", "tag", "transform": 16 floats (row-major, procmod's
    y-up frame), "parent": index or null}`` plus ``size`` (box), ``radius``, ``length``,
    ``top_radius`` (cylinder) or ``mesh`` (an index into ``meshes``, shared by parts with the
    same local mesh). A part's parent is a part of the nearest ancestor rule call that drew
    parts (with as many parts as the call has, part i of a call hangs under part i // k of
    its parent's, as learned programs' copies do; otherwise under the first).
    """
    from ..geometry.export import colour_of
    from ..geometry.solid import Box, Cylinder, Mesh, scene_bounds, with_positive_length

    parts, meshes, mesh_index, calls = [], [], {}, {}
    for node in derivation.nodes():
        if not node.geometry:
            continue
        parent_parts = None
        for k in range(len(node.address) - 1, -1, -1):
            if node.address[:k] in calls:
                parent_parts = calls[node.address[:k]]
                break
        mine = []
        for i, part in enumerate(node.geometry):
            if isinstance(part, Cylinder):
                part = with_positive_length(part)  # built in Blender along +z, as everywhere else
            entry = {"tag": part.tag, "transform": [float(v) for v in part.transform], "parent": None}
            if parent_parts:
                per = len(node.geometry) // len(parent_parts)
                entry["parent"] = parent_parts[i // per] if per and len(node.geometry) % len(parent_parts) == 0 \
                    else parent_parts[0]
            if isinstance(part, Box):
                entry.update(kind="box", size=[float(v) for v in part.size])
            elif isinstance(part, Cylinder):
                entry.update(kind="cylinder", radius=float(part.radius), length=float(part.length),
                             top_radius=None if part.top_radius is None else float(part.top_radius))
            elif isinstance(part, Mesh):
                key = (part.vertices, part.faces)
                if key not in mesh_index:
                    mesh_index[key] = len(meshes)
                    meshes.append({"vertices": [list(map(float, v)) for v in part.vertices],
                                   "faces": [list(map(int, f)) for f in part.faces]})
                entry.update(kind="mesh", mesh=mesh_index[key])
            else:
                continue  # 2D geometry never reaches here: models are checked to be 3D first
            mine.append(len(parts))
            parts.append(entry)
        calls[node.address] = mine
    colours = {p["tag"]: list(colour_of(p["tag"])) for p in parts}
    lo, hi = scene_bounds(derivation.geometry())
    return {"parts": parts, "meshes": meshes, "colours": colours,
            "bounds": [[float(v) for v in lo], [float(v) for v in hi]]}


# ---- models and targets --------------------------------------------------------------------------

def resolve_model(spec: str):
    """A built-in model by name, or a learned program (program.json or its folder)."""
    from ..core import InvalidArgumentError
    from ..models import MODELS, get_model

    if spec in MODELS:
        model = get_model(spec)
    elif spec.lower().endswith(".json") or Path(spec).is_dir():
        from ..learn import load_program
        model = load_program(spec)
    else:
        model = get_model(spec)  # the library's one-line message lists the models
    if model.new_output().dimension != 3:
        raise InvalidArgumentError(f"model {model.name!r} draws 2D pictures; Blender takes 3D models "
                                   "(spaceship, tree, city, or a learned program)")
    return model


MIN_VOXELS_ACROSS = 8  # an automatic voxel size puts at least this many along each layer's longest side


def _grid_voxels(size: float, lo, hi) -> int:
    """Voxels of the grid around ``lo``..``hi`` with edge ``size`` and a two-voxel margin."""
    return math.prod(max(1, math.ceil((h - l + 4 * size) / size)) for l, h in zip(lo, hi))


def _size_for(voxels: int, lo, hi) -> float:
    """The smallest voxel size whose grid (margin counted) has at most ``voxels`` voxels."""
    small, large = 1e-12, 2.0 * float(np.max(np.subtract(hi, lo))) + 1.0  # large: 5 voxels an axis at most
    for _ in range(100):  # bisection in the log: the count only falls as the size grows
        middle = math.sqrt(small * large)
        if _grid_voxels(middle, lo, hi) > voxels:
            small = middle
        else:
            large = middle
    return large


def _auto_voxel_size(lo, hi, layer_bounds) -> float:
    """Voxel size 0 in the panel: about :data:`AUTO_VOXELS` voxels around the layers
    (margin counted: a large flat layer was refused for going over :data:`MAX_VOXELS`), but
    fine enough that every layer has :data:`MIN_VOXELS_ACROSS` voxels along its longest side
    (a 2 m cube on a 200 m ground slab fell between voxel centres), within :data:`MAX_VOXELS`."""
    smallest = min(float(np.max(b[1] - b[0])) for b in layer_bounds)
    size = min(_size_for(AUTO_VOXELS, lo, hi), smallest / MIN_VOXELS_ACROSS)
    return max(size, _size_for(MAX_VOXELS, lo, hi))


def build_volume_target(spec: dict, job_folder: Path, out: Path) -> Path:
    """Write the layers' meshes (procmod frame) and ``out/target.json`` (``procmod-volume/1``
    with mesh layers: the library voxelizes them onto one grid around all of them, with
    winding numbers, so holes and overlaps need no repair); returns the file."""
    import shutil

    import trimesh

    from ..core import InvalidArgumentError

    layers = spec.get("layers") or []
    if not layers:
        raise InvalidArgumentError("the volume target has no layers: add the scene's meshes as fill or avoid layers")
    if not any(float(layer.get("w_fill", 1.0)) > 0 or float(layer.get("w_avoid", 0.0)) > 0 for layer in layers):
        raise InvalidArgumentError("the volume target has nothing to fill: no layer has a positive Inside or Outside "
                                   "weight (Avoid layers only); add a mesh as Fill")
    bounds = []
    for layer in layers:
        name = layer.get("object", layer["mesh"])
        try:
            mesh = trimesh.load(job_folder / layer["mesh"], force="mesh", process=False)
        except Exception as exc:  # trimesh raises many types for unreadable files
            raise InvalidArgumentError(f"cannot read the mesh of target layer {name!r} ({exc})") from None
        if len(getattr(mesh, "faces", ())) == 0:
            raise InvalidArgumentError(f"target layer {name!r} has no faces")
        bounds.append(mesh.bounds)
    lo = np.min([b[0] for b in bounds], axis=0)
    hi = np.max([b[1] for b in bounds], axis=0)
    automatic = not float(spec.get("voxel_size") or 0)
    size = _auto_voxel_size(lo, hi, bounds) if automatic else float(spec["voxel_size"])
    if not (math.isfinite(size) and size > 0):
        raise InvalidArgumentError(f"the voxel size must be a positive number, got {size!r}")
    chosen = f"Voxel size {size:.4g}" + (" (0 in the panel: chosen for the whole scene)" if automatic else "")
    margin = 2 * size
    count = _grid_voxels(size, lo, hi)
    if count > MAX_VOXELS:
        raise InvalidArgumentError(f"a {chosen} gives {count:,} voxels around the target layers "
                                   f"(at most {MAX_VOXELS:,}); give a larger Voxel size in the panel")
    for layer, (b_lo, b_hi) in zip(layers, bounds):
        # the library's message for this speaks of a target file's fields (mesh_scale)
        across = float(np.max(b_hi - b_lo))
        if across < 2 * size:
            limit = _size_for(MAX_VOXELS, lo, hi)  # the finest size within the voxel limit
            if across / MIN_VOXELS_ACROSS >= limit:
                fix = f"give a Voxel size of {across / MIN_VOXELS_ACROSS:.3g} in the panel"
            elif across / 2 > limit:  # automatic picks the finest that fits, which resolves it
                fix = f"give a Voxel size of 0 in the panel (automatic: it picks {limit:.3g}, the finest that fits)"
            else:
                fix = (f"the layers span {float(np.max(hi - lo)):.4g} across, so no Voxel size fits both within "
                       f"{MAX_VOXELS:,} voxels: make the layer larger, or leave out the layers far from it")
            raise InvalidArgumentError(f"target layer {layer.get('object', layer['mesh'])!r} is {across:.3g} "
                                       f"across, under two voxels of the {chosen}, so no voxel lies inside it; {fix}")
    out.mkdir(parents=True, exist_ok=True)
    files = []
    for i, ((w_fill, w_avoid), group) in enumerate(_layer_groups(layers)):
        if len(group) == 1:
            shutil.copy(job_folder / group[0]["mesh"], out / f"layer{i}.obj")
        else:  # one layer: the union of the meshes (winding numbers add up where they overlap)
            meshes = [trimesh.load(job_folder / layer["mesh"], force="mesh", process=False) for layer in group]
            trimesh.util.concatenate(meshes).export(out / f"layer{i}.obj", file_type="obj", include_normals=False,
                                                    include_texture=False)
        files.append({"file": f"layer{i}.obj", "w_fill": w_fill, "w_avoid": w_avoid})
    target = {"format": "procmod-volume/1", "score": "svol", "voxel_size": size, "margin": margin, "layers": files,
              "w_self": float(spec.get("w_self", 0.0))}
    write_json_atomic(out / "target.json", target)
    return out / "target.json"


def _layer_groups(layers: list) -> list:
    """The panel's layers grouped by their weights: ``[((w_fill, w_avoid), [layer, ...])]``
    in the order of first use. A group is one layer of the target file, the union of its
    meshes: seed 002's s_vol adds every layer's avoid weight outside it, so two meshes added
    with "Fill" as two layers (1 inside, -1 outside each) cancelled each other, 1 - 1 = 0
    inside either, and the model had nothing to fill."""
    groups = {}
    for layer in layers:
        weights = (float(layer.get("w_fill", 1.0)), float(layer.get("w_avoid", 0.0)))
        groups.setdefault(weights, []).append(layer)
    return list(groups.items())


# a target file's fields, as the panel names them
PANEL_FIELDS = {"w_fill": "Inside weight", "w_avoid": "Outside weight", "voxel_size": "Voxel size (in the panel)"}


def _in_panel_terms(message: str) -> str:
    for field, shown in PANEL_FIELDS.items():
        message = message.replace(field, shown)
    return message


def _name_layers(message: str, spec: dict) -> str:
    """A target file's message names ``layers[i]``; say which scene objects that is."""
    groups = _layer_groups(spec.get("layers") or [])
    if re.match(r"^.*?target\.json: (?!layers\[)", message):  # of the whole target (nothing to fill)
        return _in_panel_terms(re.sub(r"^.*?target\.json: ", "", message))
    found = re.search(r"layers\[(\d+)\]", message)
    if found and int(found.group(1)) < len(groups):
        names = [layer.get("object") for layer in groups[int(found.group(1))][1]]
        if all(names):
            # the target file the message starts with is the job's, removed with it: the
            # scene's objects and the panel's fields say it to a Blender user
            message = _in_panel_terms(re.sub(r"^.*?target\.json: layers\[\d+\](?:\.(\w+))?:? ",
                                             lambda m: f"its {m.group(1)} " if m.group(1) in PANEL_FIELDS else "",
                                             message))
            if len(names) == 1:
                return f"target layer {names[0]!r}: {message}"
            return f"target layers {', '.join(map(repr, names))} (one layer: their weights are the same): {message}"
    return message


def build_silhouette_target(spec: dict, job_folder: Path, out: Path) -> Path:
    """Write the views (camera + weights .npy from the scene) as ``out/target.json``."""
    import shutil

    from ..core import InvalidArgumentError

    views = spec.get("views") or []
    if not views:
        raise InvalidArgumentError("the silhouette target has no view: pick a camera and a mask")
    out.mkdir(parents=True, exist_ok=True)
    written = []
    for i, view in enumerate(views):
        name = f"view{i}.npy"
        shutil.copy(job_folder / view["weights"], out / name)
        written.append({"weights": name, "camera": view["camera"]})
    write_json_atomic(out / "target.json", {"format": "procmod-silhouette/1", "views": written})
    return out / "target.json"


# ---- commands ------------------------------------------------------------------------------------

def cmd_sample(job: dict, folder: Path, progress: Progress) -> dict:
    from ..core import InvalidArgumentError

    model = resolve_model(job["model"])
    count, seed = int(job.get("count", 1)), int(job.get("seed", 0))
    if not 1 <= count <= 1000:
        raise InvalidArgumentError(f"ask for 1 to 1000 samples at a time, not {count}")
    samples = []
    for i in range(count):
        progress(i / count, f"sampling {model.name}: {i} of {count}")
        samples.append({"label": f"sample {i} (seed {seed})", **derivation_parts(_sample_one(model, seed, i))})
    return {"samples": samples, "message": f"{count} sample{'s' if count != 1 else ''} of {_short(model.name)} "
                                           f"from seed {seed}"}


def _sample_one(model, seed: int, i: int):
    from ..core import run_forward
    return run_forward(model, np.random.default_rng([seed, i]))


def _short(name: str) -> str:
    return Path(name).parent.name if name.endswith("program.json") else name


def cmd_infer(job: dict, folder: Path, progress: Progress) -> dict:
    from ..core import InvalidArgumentError, ProcmodError
    from ..core.runfolder import INFER_RUN, RunFolder
    from ..infer import ENGINES, parse_budget
    from ..infer.common import check_population
    from ..report import write_run
    from ..targets import load_target_file

    model = resolve_model(job["model"])
    engine = job.get("engine", "ga")
    if engine not in ENGINES:
        raise InvalidArgumentError(f"unknown engine {engine!r}; choose one of {', '.join(ENGINES)}")
    budget = parse_budget(job["budget"]) if job.get("budget") else None
    seed = int(job.get("seed", 0))
    option = POPULATION_OPTION[engine]
    kwargs = {}
    if job.get("population"):
        kwargs[option] = int(job["population"])
    out = Path(job["out"])
    target_spec = job["target"]
    target_folder = Path(job["target_folder"])
    progress(None, "building the target")
    if target_spec["kind"] == "volume":
        target_file = build_volume_target(target_spec, folder, target_folder)
    elif target_spec["kind"] == "silhouette":
        target_file = build_silhouette_target(target_spec, folder, target_folder)
    else:
        raise JobError(f"unknown target kind {target_spec['kind']!r}")
    try:
        target = load_target_file(target_file)
    except ProcmodError as exc:
        raise type(exc)(_name_layers(str(exc), target_spec)) from None
    run_folder = RunFolder(out, INFER_RUN, bool(job.get("overwrite")), inputs=[target_folder, job["model"]])
    empty = target.new_output(target.configure(model))
    if option in kwargs:
        check_population(option, kwargs[option], empty)  # the panel's field, not a command-line flag
    from ..targets.placement import placement_note
    note = placement_note(model, target, np.random.default_rng(seed))
    stopped = []

    def report(tracker):
        if progress.stop_requested and not stopped:
            stopped.append(tracker.evaluations)
            tracker.request_stop()  # the engine ends at its next budget check with what it has
        fraction = tracker.fraction() if budget is not None else None
        best = "none yet" if tracker.best is None else f"{tracker.best_score:.4g}"
        progress(fraction, f"{engine}: {tracker.evaluations:,} evaluations, best {best}"
                 + (" (stopping)" if stopped else ""))

    result = ENGINES[engine](model, target, seed=seed, budget=budget, progress=report, **kwargs)
    if result.best is None:
        from ..infer.common import no_result_error
        raise no_result_error(result)
    argv = ["infer", job["model"], "--target", str(target_folder), "--engine", engine]
    if option in kwargs:
        argv += [f"--{option}", str(kwargs[option])]
    if budget is not None:
        argv += ["--budget", job["budget"]]
    argv += ["--seed", str(seed), "--out", str(out)]
    if stopped:
        result.notes.append(f"stopped from Blender after {stopped[0]:,} evaluations")
    if note is not None:
        result.notes.append(note)
    progress(1.0, "writing the run folder", force=True)
    with run_folder.writing() as tmp:
        write_run(result, target, tmp, int(job.get("size", 512)), "procmod " + shlex.join(argv))
    return {"samples": [{"label": f"best {engine} {result.best_score:.4g}", **derivation_parts(result.best)}],
            "run": str(out), "report": str(out / "report.html"), "score": result.best_score,
            "stopped": bool(stopped),
            "message": (f"{engine}: best score {result.best_score:.4f} after {result.evaluations} evaluations in "
                        f"{result.seconds:.3g} s{' (stopped early)' if stopped else ''}; report: {out / 'report.html'}"
                        + (f"; note: {note}" if note else ""))}


# What a Blender user does about a sheared world matrix (the library's message says what it is)
SHEAR_FIX = ("in Blender, apply the scale of the object's parents (select them, Object > Apply > Scale) "
             "so that no rotated child sits under a non-uniform scale")


def _name_objects(message: str, names: dict, examples_file: Path | None = None) -> str:
    """An examples error names a JSON path (``examples[2].children[0]``) or one of the
    job's GLB files (the add-on exports each selected hierarchy); say which object it is.

    The examples are the job's own temporary copy of the selection, which means nothing
    to the user: their names are dropped, and the message names the scene object instead."""
    if examples_file is not None:
        for file, root in names.items():
            if file.endswith(".glb"):  # the hierarchy of root object ``root``
                message = message.replace(str(examples_file / file), f"the hierarchy of {root!r}")
        message = message.replace(f"{examples_file}: ", "").replace(str(examples_file), "the selection")
    paths = re.findall(r"examples\[\d+\](?:\.children\[\d+\])*", message)
    for path in sorted(set(paths), key=len, reverse=True):
        if path in names:
            message = f"object {names[path]!r}: {message}"
            break
    if "shears" in message:
        message = f"{message}; {SHEAR_FIX}"
    return message


def cmd_learn(job: dict, folder: Path, progress: Progress) -> dict:
    from ..core import InvalidArgumentError, ProcmodError
    from ..learn import load_program
    from ..learn import learn as learn_program

    count, seed = int(job.get("count", 4)), int(job.get("seed", 0))
    names = json.loads((folder / job["names"]).read_text(encoding="utf-8")) if job.get("names") else {}
    examples_file = folder / job["examples"]
    out = Path(job["out"])
    if out.exists() and any(out.iterdir()) and not (out / "checkpoint").exists():
        raise InvalidArgumentError(f"{out} is not empty and not an earlier procmod learn folder; give another")

    def report(line: str) -> None:
        progress(None, line.strip())

    notes = []
    try:
        learned = learn_program(examples_file, out, particles=int(job.get("particles", 2)),
                                workers=int(job.get("workers", 1)), seed=seed, samples=max(count, 1),
                                progress=report, command=job.get("command", ""), note=notes.append)
    except ProcmodError as exc:
        raise type(exc)(_name_objects(str(exc), names, examples_file)) from None
    model = load_program(learned["program"])
    samples = [{"label": f"learned sample {i} (seed {seed})", **derivation_parts(_sample_one(model, seed, i))}
               for i in range(count)]
    t = learned["table"]
    return {"samples": samples, "program": learned["program"], "report": learned["report"],
            "message": (f"learned {t['A_star']} abstractions from {job.get('n_examples', '')} examples in "
                        f"{t['seconds']:.1f} s; program: {learned['program']}"
                        + "".join(f"; note: {_name_objects(n, names, examples_file)}" for n in notes))}


def one_line(message, limit: int = 600) -> str:
    """An error message as one line (as the command line prints it)."""
    text = re.sub(r"\s*\n\s*", " ", str(message)).strip()
    return text if len(text) <= limit else text[:limit // 2 - 3] + " ... " + text[-(limit // 2 - 3):]


COMMANDS = {"sample": cmd_sample, "infer": cmd_infer, "learn": cmd_learn}


def run_job(folder: str | os.PathLike) -> int:
    """Run the job in ``folder``; always leaves ``result.json`` behind. Returns the exit status."""
    from ..core import ProcmodError

    folder = Path(folder)
    progress = Progress(folder)
    try:
        job = json.loads((folder / "job.json").read_text(encoding="utf-8"))
        if job.get("format") != JOB_FORMAT or job.get("command") not in COMMANDS:
            raise JobError(f"not a {JOB_FORMAT} job with a known command")
        progress(None, f"{job['command']}: starting", force=True)
        result = {"ok": True, **COMMANDS[job["command"]](job, folder, progress)}
        status = 0
    except ProcmodError as exc:
        # the user's error: the one line is all there is to it (the add-on removes the job's folder)
        result, status = {"ok": False, "error": one_line(exc), "user_error": True}, 2
    except Exception as exc:  # a bug: the one line says where the details are
        traceback.print_exc()
        result = {"ok": False, "error": f"internal error ({type(exc).__name__}: {one_line(exc, 200)}); "
                                        f"the traceback is in {folder / 'worker.log'}"}
        status = 1
    write_json_atomic(folder / "result.json", result)
    return status


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: python -m procmod.blender.worker JOB_FOLDER")
    sys.exit(run_job(sys.argv[1]))
