"""procmod against WebPPL 0.9.15 on the vines program, end to end, judged by one neutral scorer.

    python bench/vs_webppl.py                       # glyphs + scribbles, SMC at 10/50/200/600, 3 seeds
    python bench/vs_webppl.py --targets-dir DIR     # also every target picture in DIR
    python bench/vs_webppl.py --mcmc                # also MCMC vs WebPPL's MH (+ SOSMC, GA) at equal time
    python bench/vs_webppl.py --mcmc --mcmc-workers 1 2   # ... and procmod's MCMC on two cores
    python bench/vs_webppl.py --guide vines-scribbles --guided-particles 1 5 10 20

Both systems run the vines program of shared/seeds/vines.md (with leaves and flowers by
default; ``--no-leaves`` for the plain one) as whole processes on the same target files:
procmod as ``procmod infer vines --target T.png --engine smc --particles N --seed S --out
DIR`` (renders, report and all), WebPPL as ``webppl bench/peers/webppl/vines.wppl`` with
``Infer({method: 'SMC', particles: N})``. WebPPL is installed by this script from npm into
``bench/.cache/`` (node and npm must be on the machine).

Time: the wall time of a run beyond a 1-particle run of the same command (same target and
seed), so start-up and report costs that do not depend on the particles cancel; with
``--guide``, ``guided_time_ratios`` holds guided procmod's time over WebPPL's at every pair
of particle counts, summed over the same (target, seed) runs, with a bootstrap interval
(start-up jitter is larger than a short run's work). Quality:
every run's best complete output (procmod: ``best.json``; WebPPL: the complete particle of
highest similarity, recorded as particles finish) is judged by ``bench/peers/scorer.py``,
the original program's normalised similarity on a 50x50 mask of the output geometry,
which shares no code with procmod. Each summary row gives the median over all its runs
(``similarity_median``) and seed 004's Fig. 5 measure, each target's median averaged over
the targets (``similarity_target_mean``): the pooled median sees only on which side of
the middle a run falls, so a target one system fills and the other fails moves it little;
the mean weighs every target's level. With ``--guide``, ``guided_similarity_differences``
holds guided procmod's per-target median minus WebPPL's, averaged over targets, on the
same (target, seed) runs. Intervals are 95% bootstrap intervals (those of per-target
means resample targets). Targets are 50x50 masks written once as PNG (+ sidecar
start/direction) for procmod and as JSON for WebPPL: the same pixels for both. A picture
is left out, with the reason, when it cannot be read, when its shape covers fewer than 25
of the 2,500 pixels at 50x50 (the normalised similarity of a dot is no measure) or more
than 90% of the frame, when procmod would read its written mask otherwise than the
scorer, when procmod reads it as a light page with its drawing as holes (a page in a dark
frame, or on a desk as dark as its ink: no target of the drawing's), or when it is the
same target as a picture before it (a link or a copy, counted twice in the means);
procmod's other notes on a picture (a frame left out, translucent strokes left out) are
printed, each naming its file. ``--targets-dir`` reads the folder's pictures (HEIC, SVG
and PDF files too, to say what each is and how to convert it), not its subfolders
(named); links to nothing and JSON files that are no picture's sidecar are named.
``--bottom-centre`` starts at the bottom centre of the picture itself, not of the square
it is padded to. With ``--work``, a run already in the folder is reused only when it
was made with the same settings (leaves, start, repeats, workers, guide and its files)
on the same mask; without it the runs go to a temporary folder, removed at exit.
``bench/results/NAME.json`` is replaced at the end (said at the start).

Sets: ``glyphs``, the first lower-case glyphs of DejaVu Sans Bold; ``scribbles``, procmod's
procedural scribbles from number 49 on (0-48 train the guides); ``stix`` (not in the
default), the first lower-case glyphs of STIX General Bold, a serif typeface whose
hairlines and serifs neither the guides' training scribbles nor DejaVu Sans have;
``serif`` (not in the default), the same from DejaVu Serif Bold;
``silhouettes`` (not in the default; ``pip install pybullet``), 50x50 silhouettes of the
objects and robots pybullet_data ships (bench/peers/silhouettes.py). ``--bottom-centre``
starts every target at the bottom centre, growing up, as the original experiments' do.
Results:
``bench/results/vs_webppl.json`` and ``.png`` (``--name`` changes the stem).
"""

from __future__ import annotations

import argparse
import atexit
import dataclasses
import json
import math
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from PIL import Image  # noqa: E402

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE / "peers"))
import scorer  # noqa: E402

ROOT = HERE.parent
RESULTS = HERE / "results"
WEBPPL_VERSION = "0.9.15"
WEBPPL_CACHE = HERE / ".cache" / f"webppl-{WEBPPL_VERSION}"
PEER = HERE / "peers" / "webppl"
SIZE = 50
SETS = ("glyphs", "scribbles", "stix", "serif", "silhouettes")  # the built-in target sets
BOTTOM_CENTRE, UP = (0.5, 0.9166), (0.0, -1.0)  # every original target's start (shared/seeds/vines.md)


# ---- the peer -------------------------------------------------------------------------

def ensure_webppl() -> list:
    """The command that runs WebPPL, installing it from npm into the cache on first use."""
    binary = WEBPPL_CACHE / "node_modules" / "webppl" / "webppl"
    if not binary.exists():
        if shutil.which("npm") is None or shutil.which("node") is None:
            sys.exit("vs_webppl: node and npm are needed to install the WebPPL peer")
        WEBPPL_CACHE.mkdir(parents=True, exist_ok=True)
        print(f"installing webppl@{WEBPPL_VERSION} into {WEBPPL_CACHE} ...", flush=True)
        subprocess.run(["npm", "install", "--prefix", str(WEBPPL_CACHE), "--no-audit", "--no-fund",
                        "--no-save", f"webppl@{WEBPPL_VERSION}"], check=True, stdout=subprocess.DEVNULL)
    return ["node", str(binary)]


def procmod_command() -> list:
    """``procmod`` as this interpreter imports it (so a bench run from another checkout,
    with PYTHONPATH pointing at it, times that checkout)."""
    return [sys.executable, "-m", "procmod.cli"]


def compile_timed_package() -> None:
    """Write the bytecode of the procmod package the runs time, as an install by pip
    does (or Python's first import, where it may write). With PYTHONDONTWRITEBYTECODE set
    (this machine's shell sets it) a checkout's modules were compiled from source in every
    process: ~0.3-0.5 s of each run's start-up that a user's installed procmod never pays.
    Done in a process started as the timed ones are (:func:`procmod_command`: the current
    folder first on the path), so it finds the package they import, not this one's."""
    code = ("import compileall, pathlib, procmod; "
            "compileall.compile_dir(str(pathlib.Path(procmod.__file__).parent), quiet=1)")
    subprocess.run([sys.executable, "-c", code], check=True)


# ---- targets --------------------------------------------------------------------------

def target_images(sets: list, count: int, targets_dir: Path | None, scribble_first: int) -> dict:
    """``set name -> [TargetImage]``."""
    from procmod.core import ProcmodError
    from procmod.data import glyph_set, scribble_set
    from procmod.targets import load_target_image

    out = {}
    if "glyphs" in sets:
        out["glyphs"] = [t for t in glyph_set("dejavu-sans") if t.name[-1].islower()][:count]
    if "scribbles" in sets:
        out["scribbles"] = scribble_set(count, first=scribble_first)
    if "stix" in sets:  # another typeface: serifs and hairlines, unlike the training scribbles
        out["stix"] = [t for t in glyph_set("stix") if t.name[-1].islower()][:count]
    if "serif" in sets:  # DejaVu Serif: serifs, thinner strokes than DejaVu Sans Bold
        out["serif"] = [t for t in glyph_set("dejavu-serif") if t.name[-1].islower()][:count]
    if "silhouettes" in sets:  # real 3D assets, not drawn strokes (bench/peers/silhouettes.py)
        from silhouettes import silhouette_targets

        out["silhouettes"] = silhouette_targets(count)
        if not out["silhouettes"]:
            sys.exit("vs_webppl: the silhouettes set reads pybullet_data's assets: pip install pybullet")
    if targets_dir is not None:
        from PIL import Image

        if not targets_dir.is_dir():
            sys.exit(f"vs_webppl: --targets-dir {targets_dir} is not a folder of pictures")
        Image.init()
        # every format procmod infer reads: those Pillow opens (it only writes some, PDF)
        pictures = {suffix for suffix, kind in Image.registered_extensions().items() if kind in Image.OPEN}
        files = sorted(p for p in targets_dir.iterdir() if p.is_file())
        folders = sorted(p.name for p in targets_dir.iterdir() if p.is_dir())
        if folders:  # read one folder deep only: say so, rather than pass over them without a word
            print(f"vs_webppl: subfolders not read (give each as its own --targets-dir): {', '.join(folders[:5])}"
                  + (f" and {len(folders) - 5} more" if len(folders) > 5 else ""), file=sys.stderr)

        def is_picture(path: Path) -> bool:  # by its suffix, or, without a known one, by what Pillow finds in it
            if path.suffix.lower() in pictures or path.suffix.lower() in PICTURES_NOT_READ:
                return True  # (those Pillow cannot read: procmod's loader says what they are and what to do)
            if path.suffix.lower() == ".json":  # a picture's sidecar
                return False
            try:
                with Image.open(path):
                    return True
            except (OSError, ValueError, Image.DecompressionBombError):
                return False

        left_out = [p.name for p in files if not is_picture(p) and p.suffix.lower() != ".json"]
        if left_out:
            print(f"vs_webppl: not pictures, left out: {', '.join(left_out[:5])}"
                  + (f" and {len(left_out) - 5} more" if len(left_out) > 5 else ""), file=sys.stderr)
        broken = sorted(p.name for p in targets_dir.iterdir() if p.is_symlink() and not p.exists())
        if broken:  # neither a file nor a folder: they had vanished without a word
            print(f"vs_webppl: links to nothing, left out: {', '.join(broken)}", file=sys.stderr)
        from procmod.targets.image import sidecar_files

        def identity(path: Path) -> tuple:  # a file once, however a file system that ignores case spells it
            info = path.stat()
            return info.st_dev, info.st_ino

        sidecars = {identity(s) for p in files if is_picture(p) for s in sidecar_files(p)}
        orphans = [p.name for p in files if p.suffix.lower() == ".json" and identity(p) not in sidecars]
        if orphans:
            print(f"vs_webppl: JSON files that are no picture's sidecar (NAME.json beside NAME.png), not read: "
                  f"{', '.join(orphans)}", file=sys.stderr)
        from procmod.models import get_model
        from procmod.targets import ShapeMatch
        from procmod.targets.image import PAGE_NOTE
        from procmod.targets.placement import picture_note

        vines = get_model("vines")
        loaded, seen = [], {}
        for path in (p for p in files if is_picture(p)):
            try:
                target = load_target_image(path)
                mask = target.at_size(SIZE, SIZE)  # a shape that vanishes at the bench's size is refused here
            except ProcmodError as error:  # a blank or unreadable picture: say so, bench the rest
                print(f"vs_webppl: skipping {path.name}: {error}", file=sys.stderr)
                continue
            problem = coverage_problem(mask)
            if problem is not None:
                print(f"vs_webppl: skipping {path.name}: {problem}", file=sys.stderr)
                continue
            doubt = picture_note(ShapeMatch(target), vines)  # what procmod infer says of it (a page read as the shape)
            if doubt is not None and PAGE_NOTE in doubt:  # its drawing read as holes: no target of the drawing's
                print(f"vs_webppl: skipping {path.name}: {doubt}", file=sys.stderr)
                continue
            if doubt is not None:
                print(f"vs_webppl: note: {path.name}: {doubt}", file=sys.stderr)
            digest = target_digest(mask, {"start": list(target.start), "direction": list(target.direction)})
            if digest in seen:  # a link to another picture, or a copy: counted twice in the means
                print(f"vs_webppl: skipping {path.name}: the same target as {seen[digest]}", file=sys.stderr)
                continue
            seen[digest] = path.name
            loaded.append(target)
        if not loaded:
            sys.exit(f"vs_webppl: no usable target pictures in {targets_dir}")
        name = targets_dir.resolve().name
        if name in out or name in SETS or not name:  # never in place of a built-in set, never nameless
            name = f"dir-{name or 'root'}"
        out[name] = loaded
    return out


# pictures people have that Pillow does not read: sent to procmod's loader all the same,
# which says what each is and how to convert it (they had been listed as "not pictures")
PICTURES_NOT_READ = (".heic", ".heif", ".svg", ".svgz", ".pdf")

MIN_SHAPE_PIXELS = 25  # of the 50x50 mask (1%)


def bottom_centre(target) -> tuple:
    """The original experiments' start (:data:`BOTTOM_CENTRE`) in the picture's own frame:
    a picture that is not square is padded to the square mask, and the square's bottom
    centre lay in the padding, below a wide picture's drawing."""
    if target.picture is None:
        return BOTTOM_CENTRE
    top, left, height, width = target.picture
    side = float(target.mask.shape[0])
    return ((left + BOTTOM_CENTRE[0] * width) / side, (top + BOTTOM_CENTRE[1] * height) / side)
MAX_SHAPE_SHARE = 0.9


def coverage_problem(mask: np.ndarray) -> str | None:
    """Why a 50x50 target mask cannot be benched, or None. The scorer's similarity is
    normalised by an empty canvas's: for a shape of a few pixels that is ~1 and the
    score's scale explodes (one dot scored -8 and -9.5, moving the per-target mean by 0.3);
    a shape filling the frame has no outline to grow along, and its picture, written back
    opaque everywhere, reads as nothing."""
    filled = int(mask.sum())
    if filled < MIN_SHAPE_PIXELS:
        return (f"the shape covers {filled} of the {mask.size} pixels at {SIZE}x{SIZE} (fewer than "
                f"{MIN_SHAPE_PIXELS}): the similarity of so small a shape is not a measure")
    if filled > MAX_SHAPE_SHARE * mask.size:
        return (f"the shape covers {filled / mask.size:.0%} of the frame at {SIZE}x{SIZE}: nothing to grow into "
                "(a picture read inverted? a dark frame around the page is read as the paper's colour)")
    return None


def target_digest(mask: np.ndarray, placement: dict) -> str:
    """What a run on a target depends on: its mask and where the vine starts."""
    from procmod.core.io import fingerprint
    return fingerprint(np.packbits(mask).tobytes() + json.dumps(placement, sort_keys=True).encode())


def write_targets(images: dict, folder: Path) -> dict:
    """Write each target as NAME.png + NAME.json (procmod) and NAME.mask.json (WebPPL).

    Returns ``set -> [(name, target label, png path, mask json path, 50x50 mask, digest)]``
    (:func:`target_digest`); a target that cannot be written so that procmod reads the
    scorer's mask is left out, with the reason, and the rest are benched.
    """
    from procmod.core import ProcmodError
    from procmod.targets import load_target_image

    folder.mkdir(parents=True, exist_ok=True)
    out = {}
    for set_name, targets in images.items():
        rows = []
        for k, target in enumerate(targets):
            mask = target.at_size(SIZE, SIZE)
            problem = coverage_problem(mask)
            if problem is not None:
                print(f"vs_webppl: skipping {target.name}: {problem}", file=sys.stderr)
                continue
            name = f"{set_name}_{k:02d}"
            png = folder / f"{name}.png"
            # the shape opaque black on a transparent ground: procmod reads transparency as the
            # shape's outline whatever the shape touches (a black-on-white mask whose shape ran
            # along most of the border read inverted: the border colour is taken for the paper)
            pixels = np.zeros(mask.shape + (4,), dtype=np.uint8)
            pixels[..., 3] = np.where(mask, 255, 0)
            Image.fromarray(pixels, "RGBA").save(png)
            try:
                read = load_target_image(png).at_size(SIZE, SIZE)
            except ProcmodError as error:
                print(f"vs_webppl: skipping {target.name}: its mask, written for procmod, reads back as: {error}",
                      file=sys.stderr)
                continue
            if not np.array_equal(read, mask):  # procmod, WebPPL and the scorer must see one shape
                print(f"vs_webppl: skipping {target.name}: procmod reads {int((read != mask).sum())} pixels of the "
                      "written target otherwise than the scorer", file=sys.stderr)
                continue
            placement = {"start": [float(v) for v in target.start],
                         "direction": [float(v) for v in target.direction]}
            png.with_suffix(".json").write_text(json.dumps(placement))
            spec = {"width": SIZE, "height": SIZE, "mask": mask.astype(int).ravel().tolist(), **placement}
            mask_json = folder / f"{name}.mask.json"
            mask_json.write_text(json.dumps(spec))
            rows.append((name, target.name, png, mask_json, mask, target_digest(mask, placement)))
        if rows:
            out[set_name] = rows
        else:
            print(f"vs_webppl: set {set_name}: no target left to bench", file=sys.stderr)
    return out


# ---- one run of each system -----------------------------------------------------------

def procmod_geometry(derivation_path: Path) -> list:
    """The primitives of a saved procmod derivation, as the scorer's dicts."""
    from procmod.core import load_derivation
    from procmod.geometry import Disc, Ellipse, Segment
    from procmod.models import get_model

    out = []
    for g in load_derivation(derivation_path, get_model).geometry():
        if isinstance(g, Segment):
            out.append({"type": "segment", "x0": g.x0, "y0": g.y0, "x1": g.x1, "y1": g.y1, "width": g.width})
        elif isinstance(g, Ellipse):
            out.append({"type": "ellipse", "x": g.x, "y": g.y, "angle": g.angle, "length": g.length,
                        "width": g.width})
        elif isinstance(g, Disc):
            out.append({"type": "disc", "x": g.x, "y": g.y, "radius": g.radius})
        else:
            raise ValueError(f"the scorer does not know {type(g).__name__}")
    return out


def timed(command: list, repeats: int = 1, before=None, after=None) -> tuple:
    """``(wall seconds, after())`` of the fastest of ``repeats`` runs of ``command`` (a
    seeded run does the same work each time; what differs is the machine's noise, mostly
    start-up). ``before()`` readies each run (e.g. removes the last run's folder) and
    ``after()`` reads what it wrote; neither is timed."""
    best, kept = math.inf, None
    for _ in range(max(repeats, 1)):
        if before is not None:
            before()
        t0 = time.perf_counter()
        done = subprocess.run(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        seconds = time.perf_counter() - t0
        if done.returncode != 0:
            raise RuntimeError(f"{' '.join(command)} failed:\n{done.stderr[-2000:]}")
        if seconds < best:
            best, kept = seconds, (after() if after is not None else None)
    return best, kept


def run_procmod(png: Path, mask, work: Path, engine: str, n: int, seed: int, leaves: bool,
                budget: str | None = None, guide: str | None = None, workers: int | None = None,
                repeats: int = 1) -> dict:
    out = work / "run"
    command = procmod_command() + ["infer", "vines", "--target", str(png), "--engine", engine,
                                   "--seed", str(seed), "--out", str(out)]
    if not leaves:
        command += ["--param", "leaves=false"]
    option = {"smc": "--particles", "sosmc": "--particles", "mcmc": "--chains", "ga": "--population"}[engine]
    if n is not None:
        command += [option, str(n)]
    if budget is not None:
        command += ["--budget", budget]
    if guide is not None:
        command += ["--guide", guide]
    if workers is not None and engine in ("smc", "sosmc", "mcmc"):
        command += ["--workers", str(workers)]
    def clear():
        if out.exists():
            shutil.rmtree(out)

    def read():  # the kept run's output, its engine time included
        return procmod_geometry(out / "best.json"), json.loads((out / "settings.json").read_text())

    seconds, (geometry, settings) = timed(command, repeats, before=clear, after=read)
    # infer_seconds: the engine's own time, as procmod reports it (WebPPL's rows: its Infer call)
    row = {"seconds": seconds, "similarity": scorer.score(geometry, mask), "own_score": settings["best_score"],
           "primitives": len(geometry), "infer_seconds": settings["seconds"],
           "workers": settings["settings"].get("workers"),
           "ess_threshold": settings["settings"].get("ess_threshold")}  # None: resampled at every emit
    if engine in ("smc", "sosmc"):  # particle-steps: a particle advanced to its next emit or to its end
        row["steps"] = settings["evaluations"]
    return row


def run_webppl(webppl: list, mask_json: Path, mask, work: Path, method: str, n: int, seed: int,
               leaves: bool, repeats: int = 1) -> dict:
    out = work / "webppl.json"
    command = webppl + [str(PEER / "vines.wppl"), "--require", str(PEER / "vines_peer"),
                        "--random-seed", str(seed + 1), "--", "--target", str(mask_json), "--out", str(out),
                        "--leaves", "1" if leaves else "0", "--method", method]
    command += ["--particles", str(n)] if method == "SMC" else ["--samples", str(n)]
    seconds, result = timed(command, repeats, after=lambda: json.loads(out.read_text()))
    row = {"seconds": seconds, "similarity": scorer.score(result["geometry"], mask),
           "own_score": result["similarity"], "primitives": len(result["geometry"]),
           "infer_seconds": result["inferSeconds"]}
    if method == "SMC":  # procmod's unit: a particle advanced to its next factor, or to its end
        row["steps"] = result["factors"] + result["finished"]
    return row


# ---- summaries ------------------------------------------------------------------------

def median_interval(values, rng, draws: int = 2000) -> list:
    """Median with a 95% bootstrap interval."""
    v = np.asarray(values, dtype=np.float64)
    boots = np.median(rng.choice(v, size=(draws, len(v)), replace=True), axis=1)
    return [float(np.median(v)), float(np.quantile(boots, 0.025)), float(np.quantile(boots, 0.975))]


def mean_over_targets(per_target: list, rng, draws: int = 4000) -> list:
    """The mean of per-target statistics (seed 004's Fig. 5: each target's median
    similarity, averaged over the targets) with a 95% bootstrap interval that resamples
    targets. Targets only: each observed statistic already carries its seeds' noise, so
    resampling seeds within targets as well would count that noise twice."""
    values = np.asarray(per_target, dtype=np.float64)
    if values.size == 0:
        raise ValueError("no targets to average over")
    means = values[rng.integers(0, len(values), size=(draws, len(values)))].mean(axis=1)
    return [float(values.mean()), float(np.quantile(means, 0.025)), float(np.quantile(means, 0.975))]


# A per-step cost is quoted where the runs averaged at least this many particle-steps beyond
# the 1-particle run (~0.15 s of work): procmod's set-up time jitters by ~0.1 s a run, which
# would swamp the few milliseconds of work at 10 or 50 particles.
MIN_STEPS_PER_RUN = 10_000


def summarise(rows: list, key_fields: tuple) -> list:
    rng = np.random.default_rng(0)
    per_target_rng = np.random.default_rng(1)  # its own: the other intervals stay as they were
    groups = {}
    for row in rows:
        groups.setdefault(tuple(row[k] for k in key_fields), []).append(row)
    out = []
    for key, group in sorted(groups.items(), key=lambda kv: tuple(str(v) for v in kv[0])):
        # (procmod's MCMC-comparison rows ran for a budget: their time is that budget)
        beyond = [r["beyond_seconds"] if "beyond_seconds" in r else r["budget_seconds"] for r in group]
        infer = [r["infer_seconds"] for r in group if r.get("infer_seconds") is not None]
        n_seeds = len({r["seed"] for r in group})
        # in-process seconds and particle-steps beyond the 1-particle run (its set-up cancels)
        timed_steps = [(r["infer_seconds"] - r["baseline_infer_seconds"], r["steps"] - r["baseline_steps"])
                       for r in group if r.get("steps") and r.get("baseline_steps") is not None
                       and r.get("infer_seconds") is not None and r.get("baseline_infer_seconds") is not None]
        out.append({**dict(zip(key_fields, key)), "runs": len(group),
                    "similarity_median": median_interval([r["similarity"] for r in group], rng),
                    # seed 004's Fig. 5 measure: per-target medians averaged over the targets
                    "similarity_target_mean": mean_over_targets(
                        [np.median(v) for v in by_target(group).values()], per_target_rng),
                    "beyond_seconds_median": float(np.median(beyond)),
                    "beyond_seconds_per_set": float(np.sum(beyond) / n_seeds),
                    # in-process inference time (rows that recorded it): procmod's engine, WebPPL's Infer
                    "infer_seconds_median": float(np.median(infer)) if infer else None,
                    # the work both systems do, in one unit, and what a unit costs in process
                    "steps_median": (float(np.median([r["steps"] for r in group])) if all("steps" in r for r in group)
                                     else None),
                    "infer_us_per_step": (1e6 * sum(t for t, _ in timed_steps) / sum(n for _, n in timed_steps)
                                          if timed_steps and sum(n for _, n in timed_steps)
                                          >= MIN_STEPS_PER_RUN * len(timed_steps) else None),
                    "wall_seconds_median": float(np.median([r["seconds"] for r in group]))})
    return out


def by_target(group: list) -> dict:
    """target -> its runs' similarities."""
    out = {}
    for r in group:
        out.setdefault(r["target"], []).append(r["similarity"])
    return out


def paired_similarity_differences(rows: list, sets: list) -> list:
    """Guided procmod's similarity against WebPPL's unguided SMC, per set and pair of
    particle counts, on the (target, seed) runs both made: the pooled medians, and the
    per-target median differences averaged over targets (seed 004's Fig. 5 measure) with
    a 95% bootstrap interval that resamples targets."""
    rng = np.random.default_rng(2)
    out = []
    for set_name, n, m, own, peer, keys in guided_webppl_pairs(rows, sets):
        paired = {}
        for t, seed in keys:
            a, b = paired.setdefault(t, ([], []))
            a.append(own[(t, seed)]["similarity"])
            b.append(peer[(t, seed)]["similarity"])
        differences = [np.median(a) - np.median(b) for a, b in paired.values()]
        out.append({"set": set_name, "guided_particles": n, "webppl_particles": m, "pairs": len(keys),
                    "targets": len(paired),
                    "guided_median": float(np.median([own[k]["similarity"] for k in keys])),
                    "webppl_median": float(np.median([peer[k]["similarity"] for k in keys])),
                    "target_mean_difference": mean_over_targets(differences, rng),
                    "targets_guided_ahead": int(sum(d > 0 for d in differences))})
    return out


def guided_webppl_pairs(rows: list, sets: list):
    """For each set, guided particle count ``n`` and WebPPL SMC count ``m`` that share
    runs: ``(set, n, m, guided rows, WebPPL rows, shared keys)``, rows by (target, seed)."""
    for set_name in sets:
        guided = [r for r in rows if r["set"] == set_name and r["system"] == "procmod+guide"]
        webppl = [r for r in rows if r["set"] == set_name and r["system"] == "webppl" and r["method"] == "SMC"]
        for n in sorted({r["n"] for r in guided}):
            own = {(r["target"], r["seed"]): r for r in guided if r["n"] == n}
            for m in sorted({r["n"] for r in webppl}):
                peer = {(r["target"], r["seed"]): r for r in webppl if r["n"] == m}
                keys = sorted(set(own) & set(peer))
                if keys:
                    yield set_name, n, m, own, peer, keys


THRESHOLDS = (0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8)


def time_to_similarity(summary: list, set_name: str, system: str, clock: str,
                       measure: str = "similarity_median") -> dict:
    """Seconds (``clock``: a summary field) at which ``system``'s similarity on
    ``set_name`` (``measure``: a summary field) first reaches each threshold, interpolated
    linearly between its particle counts (seed 004 Fig. 5b); None where it never does."""
    pts = sorted((s for s in summary if s["set"] == set_name and s["system"] == system
                  and s["method"] in ("smc", "SMC") and s.get(clock) is not None), key=lambda s: s["n"])
    out = {}
    for threshold in THRESHOLDS:
        out[threshold] = None
        prev = None
        for s in pts:
            sim, sec = s[measure][0], max(s[clock], 0.0)
            if sim >= threshold:
                if prev is None or prev[0] >= threshold:
                    out[threshold] = sec
                else:
                    f = (threshold - prev[0]) / (sim - prev[0])
                    out[threshold] = prev[1] + f * (sec - prev[1])
                break
            prev = (sim, sec)
    return out


def speedups(summary: list, sets: list) -> list:
    """Guided procmod against WebPPL's unguided SMC: the time each needs to reach each
    similarity (per run: whole process beyond a 1-particle run, and in-process inference
    time) and the ratio, where both reach it; similarity as the pooled median of the runs
    and as seed 004's Fig. 5 measures it (per-target medians averaged over targets)."""
    out = []
    for set_name in sets:
        for measure in ("similarity_median", "similarity_target_mean"):
            for clock in ("beyond_seconds_median", "infer_seconds_median"):
                web = time_to_similarity(summary, set_name, "webppl", clock, measure)
                for system in ("procmod+guide", "procmod"):
                    own = time_to_similarity(summary, set_name, system, clock, measure)
                    if not any(v is not None for v in own.values()):
                        continue
                    for threshold in THRESHOLDS:
                        a, b = own[threshold], web[threshold]
                        out.append({"set": set_name, "system": system, "measure": measure, "clock": clock,
                                    "similarity": threshold, "seconds": a, "webppl_seconds": b,
                                    "speedup": (b / a) if a and b else None})
    return out


def paired_time_ratios(rows: list, sets: list, draws: int = 4000) -> list:
    """Guided procmod's time against WebPPL's unguided SMC, per set and pair of particle
    counts: the sum over (target, seed) pairs both ran of procmod's time beyond its
    1-particle run, over WebPPL's (whole process, and in-process inference time), with a
    95% bootstrap interval that resamples targets (a target's seeds share its difficulty).
    A run's start-up jitters by ~0.15 s against a guided run's ~0.05 s of extra work, so
    the whole-process ratio needs its interval. None where WebPPL's summed time is not
    positive (its extra time lost in the jitter: no ratio to speak of)."""
    rng = np.random.default_rng(0)
    out = []
    for set_name, n, m, own, peer, keys in guided_webppl_pairs(rows, sets):
        row = {"set": set_name, "guided_particles": n, "webppl_particles": m, "pairs": len(keys)}
        for clock, of in (("whole_process", lambda r: r["beyond_seconds"]),
                          ("in_process", lambda r: r["infer_seconds"] - r["baseline_infer_seconds"])):
            try:
                a = np.array([of(own[k]) for k in keys])
                b = np.array([of(peer[k]) for k in keys])
            except (KeyError, TypeError):  # rows without in-process times
                continue
            # per-target sums, then targets drawn with replacement
            targets = sorted({t for t, _ in keys})
            where = {t: i for i, t in enumerate(targets)}
            a_t, b_t = np.zeros(len(targets)), np.zeros(len(targets))
            for (t, _), x, y in zip(keys, a, b):
                a_t[where[t]] += x
                b_t[where[t]] += y
            pick = rng.integers(0, len(targets), size=(draws, len(targets)))
            bottom = b_t[pick].sum(axis=1)
            if b.sum() <= 0 or np.any(bottom <= 0):
                row[f"{clock}_ratio"] = None
                continue
            ratio = a_t[pick].sum(axis=1) / bottom
            row[f"{clock}_ratio"] = [float(a.sum() / b.sum()), float(np.quantile(ratio, 0.025)),
                                     float(np.quantile(ratio, 0.975))]
        out.append(row)
    return out


def plot(summary: list, sets: list, path: Path, title: str) -> None:
    fig, axes = plt.subplots(len(sets), 2, figsize=(11, 3.8 * len(sets)), squeeze=False)
    for row, set_name in enumerate(sets):
        for system, colour in (("procmod", "C0"), ("webppl", "C1"), ("procmod+guide", "C2")):
            pts = sorted((s for s in summary if s["set"] == set_name and s["system"] == system
                          and s["method"] in ("smc", "SMC")), key=lambda s: s["n"])
            if not pts:
                continue
            n = [s["n"] for s in pts]
            med = np.array([s["similarity_median"] for s in pts])
            err = [med[:, 0] - med[:, 1], med[:, 2] - med[:, 0]]
            axes[row, 0].errorbar(n, med[:, 0], yerr=err, marker="o", capsize=3, color=colour, label=system)
            # the median over runs: a sum over the set adds up every run's start-up noise
            secs = [max(s["beyond_seconds_median"], 1e-2) for s in pts]
            axes[row, 1].errorbar(secs, med[:, 0], yerr=err, marker="o", capsize=3, color=colour, label=system)
            for s, x, y in zip(pts, secs, med[:, 0]):
                axes[row, 1].annotate(str(s["n"]), (x, y), fontsize=7, xytext=(3, -9), textcoords="offset points")
        axes[row, 0].set_xscale("log")
        axes[row, 0].set_xlabel("particles")
        axes[row, 0].set_ylabel(f"{set_name}: median similarity")
        axes[row, 1].set_xscale("log")
        axes[row, 1].set_xlabel("seconds beyond a 1-particle run (median per run; floor 0.01)")
        for ax in axes[row]:
            ax.grid(alpha=0.3)
            ax.legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_mcmc(rows: list, path: Path) -> None:
    systems = sorted({(r["system"], r["method"]) for r in rows})
    sets = sorted({r["set"] for r in rows})
    fig, ax = plt.subplots(figsize=(6.5, 4))
    width = 0.8 / max(len(systems), 1)
    rng = np.random.default_rng(0)
    for i, (system, method) in enumerate(systems):
        for j, set_name in enumerate(sets):
            sims = [r["similarity"] for r in rows if r["system"] == system and r["method"] == method
                    and r["set"] == set_name]
            if not sims:
                continue
            m, lo, hi = median_interval(sims, rng)
            ax.bar(j + i * width, m, width, yerr=[[m - lo], [hi - m]], capsize=3, color=f"C{i}",
                   label=f"{system} {method}" if j == 0 else None)
    ax.set_xticks([j + 0.4 - width / 2 for j in range(len(sets))], sets)
    ax.set_ylabel("median similarity at equal wall time")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3, axis="y")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


# ---- main -----------------------------------------------------------------------------

def guide_files_digest(guide: str | None) -> str | None:
    """A digest of a guide's own files: another guide of the same name is another run."""
    if not guide:
        return None
    from procmod.guide import guide_paths
    from procmod.core.io import fingerprint
    return fingerprint(b"".join(p.read_bytes() for p in guide_paths(guide) if p.is_file()))


def run_settings_digest(args, system: str, target: str, guide_digest: str | None, **more) -> str:
    """What a run's result depends on beyond its (system, method, set, target name, n,
    seed): its target's mask and start (:func:`target_digest`), the program (leaves), the
    timing (repeats), procmod's workers and guide (for SMC runs; ``system`` "mcmc": the
    equal-time comparison's, which take neither), and ``more``. A --work row measured
    under other options, or on another picture of the same name, is not reused (it had
    been, and labelled with the new options)."""
    config = {"target": target, "leaves": args.leaves, **more}
    if system != "mcmc":  # (the equal-time comparison takes neither: its runs are timed once, workers its own)
        config["repeats"] = args.repeats
        if system != "webppl":
            config["workers"] = args.workers
    if system == "procmod+guide":
        config["guide"] = [args.guide, guide_digest]
    from procmod.core.io import fingerprint
    return fingerprint(json.dumps(config, sort_keys=True))


def check_arguments(parser: argparse.ArgumentParser, args) -> None:
    """Refuse what would fail later, after minutes of runs (a 0-particle count failed after
    its baseline run; an unknown guide after every unguided run of the first target; a
    --name with a folder in it after the whole bench, at the results file)."""
    for option, values in (("--particles", args.particles), ("--guided-particles", args.guided_particles),
                           ("--mcmc-workers", args.mcmc_workers)):
        if any(v < 1 for v in values):
            parser.error(f"{option} takes positive counts, got {' '.join(map(str, values))}")
    for option, value in (("--repeats", args.repeats), ("--seeds", args.seeds), ("--count", args.count),
                          ("--mh-samples", args.mh_samples), ("--mcmc-targets", args.mcmc_targets)):
        if value < 1:
            parser.error(f"{option} must be 1 or more, got {value}")
    if args.workers is not None and args.workers < 1:
        parser.error(f"--workers must be 1 or more, got {args.workers}")
    if args.scribble_first < 0:
        parser.error(f"--scribble-first must be 0 or more, got {args.scribble_first}")
    if not args.sets and args.targets_dir is None:
        parser.error("nothing to bench: give --sets or --targets-dir")
    if args.targets_dir is not None and not args.targets_dir.is_dir():  # before WebPPL's check and a work folder
        parser.error(f"--targets-dir {args.targets_dir} is not a folder of pictures")
    if not re.fullmatch(r"[A-Za-z0-9_.-]+", args.name) or set(args.name) == {"."}:
        parser.error(f"--name is a file stem in bench/results/ (letters, digits, _ . -), got {args.name!r}")
    if "procmod+guide" in args.systems and not args.guide:
        parser.error("--systems procmod+guide needs --guide")
    if args.guide:
        from procmod.core import ProcmodError
        from procmod.guide import Guide
        try:
            Guide.load(args.guide)
        except ProcmodError as error:
            parser.error(f"--guide: {error}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sets", nargs="*", default=["glyphs", "scribbles"], choices=SETS)
    parser.add_argument("--bottom-centre", action="store_true",
                        help="start every target at the bottom centre, growing up, as the original experiments' "
                             "targets all do (shared/seeds/vines.md), instead of the target's own start")
    parser.add_argument("--targets-dir", type=Path, help="a folder of target pictures (added as its own set)")
    parser.add_argument("--count", type=int, default=12, help="targets per built-in set (default 12)")
    parser.add_argument("--scribble-first", type=int, default=49, help="first scribble number (default 49)")
    parser.add_argument("--particles", type=int, nargs="*", default=[10, 50, 200, 600])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--no-leaves", dest="leaves", action="store_false", help="the vines program without leaves/flowers")
    parser.add_argument("--systems", nargs="+", default=["procmod", "webppl"], choices=("procmod", "procmod+guide", "webppl"),
                        help="what to run (default procmod webppl); procmod+guide: only procmod's guided runs "
                             "(with --guide), e.g. to repeat the guided-against-WebPPL pairs alone")
    parser.add_argument("--mcmc", action="store_true",
                        help="also WebPPL MH (--mh-samples) vs procmod mcmc, sosmc and ga at WebPPL's wall time")
    parser.add_argument("--mh-samples", type=int, default=20000)
    parser.add_argument("--mcmc-targets", type=int, default=4, help="targets per set for the MCMC comparison")
    parser.add_argument("--mcmc-workers", type=int, nargs="+", default=[1],
                        help="procmod mcmc runs with these --workers (one chain each; default 1); W > 1 is "
                             "reported as method mcmc-wW: W chains on W cores in the same wall time")
    parser.add_argument("--guide", help="also guided procmod SMC with this guide (name or GUIDE.pt)")
    parser.add_argument("--guided-particles", type=int, nargs="*", default=[1, 5, 10, 20])
    parser.add_argument("--workers", type=int, help="procmod's --workers for SMC (default: the CLI's, 1: one "
                                                     "process, as WebPPL's)")
    parser.add_argument("--repeats", type=int, default=1,
                        help="SMC runs: time each command this many times and keep the least (default 1)")
    parser.add_argument("--name", default="vs_webppl", help="results file stem (default vs_webppl)")
    parser.add_argument("--work", type=Path, help="work folder (default: a temporary one)")
    args = parser.parse_args()
    check_arguments(parser, args)

    webppl = ensure_webppl() if "webppl" in args.systems else None
    if "procmod" in args.systems or "procmod+guide" in args.systems:
        compile_timed_package()
    results = RESULTS / f"{args.name}.json"
    if results.exists():  # replaced at the end: said now, while the run can still be stopped
        print(f"vs_webppl: {results} exists and will be replaced (another --name keeps it)", file=sys.stderr)
    if args.work is None:  # a temporary one, removed at exit: without --work a run cannot be resumed anyway
        work = Path(tempfile.mkdtemp(prefix="vs_webppl_"))
        atexit.register(shutil.rmtree, work, True)
    else:
        work = args.work
    work.mkdir(parents=True, exist_ok=True)
    images = target_images(args.sets, args.count, args.targets_dir, args.scribble_first)
    if args.bottom_centre:
        images = {k: [dataclasses.replace(t, start=bottom_centre(t), direction=UP) for t in v]
                  for k, v in images.items()}
    targets = write_targets(images,
                            work / "targets")
    sets = list(targets)
    rows = []
    started = time.time()
    # Rows are appended to WORK/rows.jsonl as they are measured; a rerun with the same
    # --work skips the runs already there (a long bench survives an interruption).
    log_path = work / "rows.jsonl"
    done = {}
    reused = 0  # rows read back from --work instead of measured
    guide_digest = guide_files_digest(args.guide)

    def run_config(system: str, digest: str, **more) -> str:
        return run_settings_digest(args, system, digest, guide_digest, **more)

    if log_path.exists():
        for line in log_path.read_text().splitlines():
            row = json.loads(line)
            done[(row["system"], row["method"], row["set"], row["target"], row["n"], row["seed"],
                  row.get("config"))] = row

    def record(row):
        rows.append(row)
        with log_path.open("a") as handle:
            handle.write(json.dumps(row) + "\n")
        print(f"{row['system']:>13} {row['method']:>5} {row['set']:>10} {row['target']:>22} n={row['n']:<6} "
              f"seed={row['seed']} {row['seconds']:6.2f} s (beyond {row['beyond_seconds']:6.2f}) "
              f"similarity {row['similarity']:.3f}", flush=True)

    # SMC at every particle count; a 1-particle run of each (system, target, seed) is the baseline.
    for set_name, items in targets.items():
        for name, label, png, mask_json, mask, digest in items:
            for seed in range(args.seeds):
                plans = []
                if "procmod" in args.systems:
                    plans.append(("procmod", "smc", args.particles,
                                  lambda n: run_procmod(png, mask, work, "smc", n, seed, args.leaves,
                                                        workers=args.workers, repeats=args.repeats)))
                if args.guide and ("procmod" in args.systems or "procmod+guide" in args.systems):
                    plans.append(("procmod+guide", "smc", args.guided_particles,
                                  lambda n: run_procmod(png, mask, work, "smc", n, seed, args.leaves,
                                                        guide=args.guide, workers=args.workers,
                                                        repeats=args.repeats)))
                if webppl is not None:
                    plans.append(("webppl", "SMC", args.particles,
                                  lambda n: run_webppl(webppl, mask_json, mask, work, "SMC", n, seed, args.leaves,
                                                       repeats=args.repeats)))
                for system, method, counts, run in plans:
                    config = run_config(system, digest)
                    keys = [(system, method, set_name, label, n, seed, config) for n in counts]
                    if all(k in done for k in keys):
                        rows.extend(done[k] for k in keys)
                        reused += len(keys)
                        continue
                    base = run(1)
                    for n in counts:
                        r = run(n)
                        record({"system": system, "method": method, "set": set_name, "target": label,
                                "n": n, "seed": seed, "config": config, **r, "baseline_seconds": base["seconds"],
                                "beyond_seconds": r["seconds"] - base["seconds"],
                                "baseline_infer_seconds": base.get("infer_seconds"),
                                "baseline_steps": base.get("steps")})

    mcmc_rows = []
    mcmc_path = work / "mcmc_rows.jsonl"
    mcmc_done = {}
    if mcmc_path.exists():
        for line in mcmc_path.read_text().splitlines():
            row = json.loads(line)
            mcmc_done.setdefault((row["set"], row["target"], row["seed"], row.get("config")), []).append(row)
    if args.mcmc and webppl is not None and "procmod" in args.systems:
        for set_name, items in targets.items():
            for name, label, png, mask_json, mask, digest in items[: args.mcmc_targets]:
                config = run_config("mcmc", digest, mh_samples=args.mh_samples, mcmc_workers=args.mcmc_workers)
                for seed in range(args.seeds):
                    key = (set_name, label, seed, config)
                    if key in mcmc_done:
                        mcmc_rows.extend(mcmc_done[key])
                        reused += len(mcmc_done[key])
                        continue
                    first = len(mcmc_rows)
                    base_w = run_webppl(webppl, mask_json, mask, work, "MH", 1, seed, args.leaves)["seconds"]
                    r = run_webppl(webppl, mask_json, mask, work, "MH", args.mh_samples, seed, args.leaves)
                    budget = max(r["seconds"] - base_w, 0.05)
                    mcmc_rows.append({"system": "webppl", "method": "MH", "set": set_name, "target": label,
                                      "seed": seed, "config": config, "n": args.mh_samples, **r,
                                      "beyond_seconds": budget})
                    plans = [("mcmc" if w == 1 else f"mcmc-w{w}", "mcmc", w) for w in args.mcmc_workers]
                    plans += [("sosmc", "sosmc", None), ("ga", "ga", None)]
                    for method, engine, workers in plans:
                        p = run_procmod(png, mask, work, engine, None, seed, args.leaves, budget=f"{budget:.3f}s",
                                        workers=workers)
                        mcmc_rows.append({"system": "procmod", "method": method, "set": set_name, "target": label,
                                          "seed": seed, "config": config, "n": None, **p,
                                          "budget_seconds": budget})
                    with mcmc_path.open("a") as handle:
                        handle.writelines(json.dumps(row) + "\n" for row in mcmc_rows[first:])
                    print(f"  mcmc {set_name} {label} seed {seed}: MH {r['similarity']:.3f} in {budget:.2f} s; "
                          + ", ".join(f"{m['method']} {m['similarity']:.3f}" for m in mcmc_rows[first + 1:]),
                          flush=True)

    summary = summarise(rows, ("system", "method", "set", "n"))
    RESULTS.mkdir(exist_ok=True)
    result = {
        "command": "python bench/vs_webppl.py " + " ".join(sys.argv[1:]),
        "machine": {"platform": platform.platform(), "cpus": os.cpu_count(), "python": platform.python_version(),
                    "node": subprocess.run(["node", "--version"], capture_output=True, text=True).stdout.strip()
                    if shutil.which("node") else None},
        "webppl_version": WEBPPL_VERSION, "leaves": args.leaves, "seeds": args.seeds, "workers": args.workers,
        "repeats": args.repeats, "bottom_centre": args.bottom_centre,
        "targets": {s: [label for _, label, *_ in items] for s, items in targets.items()},
        "seconds_total": round(time.time() - started, 1),  # of this pass: rows read back from --work took none
        "rows_read_from_work": reused,
        "summary": summary, "runs": rows,
        "speedups": speedups(summary, sets),
        "guided_time_ratios": paired_time_ratios(rows, sets),
        "guided_similarity_differences": paired_similarity_differences(rows, sets),
        "mcmc_summary": summarise(mcmc_rows, ("system", "method", "set")) if mcmc_rows else [],
        "mcmc_runs": mcmc_rows,
    }
    results.write_text(json.dumps(result, indent=1) + "\n")
    title = f"vines {'with' if args.leaves else 'without'} leaves and flowers: procmod vs WebPPL {WEBPPL_VERSION}"
    if summary:  # (`--particles` with no counts: the MCMC comparison alone)
        plot(summary, sets, RESULTS / f"{args.name}.png", title)
    if mcmc_rows:
        plot_mcmc(mcmc_rows, RESULTS / f"{args.name}_mcmc.png")
    for s in summary:
        m, t = s["similarity_median"], s["similarity_target_mean"]
        print(f"{s['system']:>13} {s['set']:>10} n={s['n']:<5} median {m[0]:.3f} [{m[1]:.3f}, {m[2]:.3f}]  "
              f"target mean {t[0]:.3f} [{t[1]:.3f}, {t[2]:.3f}]  "
              f"beyond-1 per set {s['beyond_seconds_per_set']:7.2f} s"
              + (f"  {s['infer_us_per_step']:.1f} us per step beyond 1 particle, in process" if s.get("infer_us_per_step") else ""))
    for t in result["guided_time_ratios"]:
        shown = [f"{clock.replace('_', ' ')} {t[clock + '_ratio'][0]:.2f}x [{t[clock + '_ratio'][1]:.2f}, "
                 f"{t[clock + '_ratio'][2]:.2f}]" if t.get(clock + "_ratio") else f"{clock.replace('_', ' ')} -"
                 for clock in ("whole_process", "in_process") if clock + "_ratio" in t]
        print(f"procmod+guide-{t['guided_particles']} / webppl-{t['webppl_particles']} {t['set']:>10}: time "
              + ", ".join(shown))
    for d in result["guided_similarity_differences"]:
        diff = d["target_mean_difference"]
        print(f"procmod+guide-{d['guided_particles']} - webppl-{d['webppl_particles']} {d['set']:>10}: similarity "
              f"per-target mean {diff[0]:+.3f} [{diff[1]:+.3f}, {diff[2]:+.3f}], ahead on "
              f"{d['targets_guided_ahead']} of {d['targets']} targets; pooled medians "
              f"{d['guided_median']:.3f} / {d['webppl_median']:.3f}")
    print(f"wrote {RESULTS / (args.name + '.json')}")


if __name__ == "__main__":
    main()
