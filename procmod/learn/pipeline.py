"""``procmod learn``: examples (a procmod-examples/1 file, or asset files) in, program folder out.

``DIR/program.json`` + ``DIR/program.pt`` (the program; meshes copied to ``DIR/parts/``),
``DIR/contact_sheet.png`` (the examples, then samples of the program), ``DIR/report.json``
and ``DIR/report.html`` (Table-1 figures, the search trace, an objective-per-round plot
``DIR/search.svg``), and ``DIR/checkpoint/`` (resumes a killed run).
"""

from __future__ import annotations

import html
import json
import os
from dataclasses import asdict
from pathlib import Path

import numpy as np

from ..chart import COLOURS, Series, line_chart_svg
from ..core import run_forward
from ..core.io import standard_json
from ..core.errors import InvalidArgumentError, argument
from ..core.runfolder import LEARN_RUN, RunFolder
from ..core.serialize import write_text_atomic
from ..geometry import contact_sheet, save_image_atomic
from ..geometry.export import colour_of, shaded_preview
from .examples import (ExampleSet, duplicate_note, example_parts, facing_examples, near_twin_note, orientation_note,
                       read_example_inputs, size_note, stray_note)
from .preprocessing import check_part_names
from .program import program_model, save_program
from .search import SearchOptions, run_search


def render_parts(parts, size: int = 160):
    """A shaded PIL image of world-space parts."""
    return shaded_preview(parts, size, colour_of)


def examples_and_samples_sheet(example_set: ExampleSet, derivations, path, tile: int = 160) -> None:
    """One contact sheet: every example, then every sample. The examples are drawn facing
    the way the set faced (:attr:`ExampleSet.facing`), as the samples stand: read, they
    face the world's axes (h141: the rows had stood 42 degrees apart)."""
    images = [render_parts(example_parts(e, example_set.parts), tile) for e in facing_examples(example_set)]
    labels = [f"example {i}" for i in range(len(images))]
    images += [render_parts(d.geometry(), tile) for d in derivations]
    labels += [f"sample {i}" for i in range(len(derivations))]
    save_image_atomic(contact_sheet(images, columns=len(example_set.examples), labels=labels), path)


def sample_program(program, name: str, n: int, seed: int) -> list:
    model = program_model(program, name)
    return [run_forward(model, np.random.default_rng([seed, i])) for i in range(n)]


def _search_plot(rounds, path) -> None:
    """Best O_D per round of each phase, as an SVG chart (:mod:`procmod.chart`: importing
    matplotlib and drawing with it cost ~0.6 s of every run, and it wrote its font cache under the user's home)."""
    series = []
    for colour, phase, label in zip(COLOURS, ("discrete", "fixed"), ("phase 1 (discrete)", "phase 2 (fixed sigmas)")):
        rows = [r for r in rounds if r["phase"] == phase and r["event"] == "step"]
        if rows:
            series.append(Series(label, [r["round"] for r in rows], [max(r["objectives"]) for r in rows], colour,
                                 markers=True))
    write_text_atomic(path, line_chart_svg(series, "structure search", "round", "best O_D"))


def _report_html(table: dict, trace: list, examples_path: str, command: str) -> str:
    rows = "".join(f"<tr><td>{html.escape(k)}</td><td>{v:.2f}</td></tr>" if isinstance(v, float)
                   else f"<tr><td>{html.escape(k)}</td><td>{html.escape(str(v))}</td></tr>"
                   for k, v in table.items())
    trace_rows = "".join("<tr>" + "".join(f"<td>{html.escape(str(r.get(k, '')))}</td>" for k in
                                          ("phase", "split", "accepted", "proposed", "objective", "abstractions",
                                           "complexity", "seconds")) + "</tr>" for r in trace)
    return f"""<!doctype html><html><head><meta charset="utf-8"><title>procmod learn</title>
<style>body{{font-family:sans-serif;margin:2em}} td{{padding:2px 8px}} table{{border-collapse:collapse}}
tr:nth-child(even){{background:#f2f2f2}}</style></head><body>
<h1>Learned program</h1><p>from <code>{html.escape(examples_path)}</code></p>
<p><code>{html.escape(command)}</code></p>
<h2>Examples (top) and samples</h2><img src="contact_sheet.png" style="max-width:100%">
<h2>Summary (seed 000 Table 1)</h2><table>{rows}</table>
<h2>Structure search</h2><img src="search.svg">
<table><tr><th>phase</th><th>split</th><th>accepted</th><th>O_D proposed</th><th>O_D</th><th>|A|</th><th>C(P)</th><th>s</th></tr>
{trace_rows}</table></body></html>
"""


MAX_SHEET_SAMPLES = 1000  # samples drawn for the contact sheet (``procmod sample`` draws more)


def _example_labels(inputs: list, count: int) -> list | None:
    """The asset files the examples were read from (one example each, in reading order),
    or None for a JSON examples file (its examples are named ``examples[i]``)."""
    from ..geometry.assets import asset_files, is_asset_file
    if not any(p.is_dir() or is_asset_file(p) for p in inputs):
        return None
    files = asset_files(inputs)
    return [f.name for f in files] if len(files) == count else None


def learn(examples, out: str | os.PathLike, particles: int = 4, workers: int | None = None,
          scheduler: str | None = None, seed: int = 0, options: SearchOptions | None = None,
          samples: int = 10, progress=None, command: str = "", overwrite: bool = False, note=None) -> dict:
    """Learn a program from an examples file and write the program folder ``out``.

    Parameters
    ----------
    examples : path or list of paths
        A ``procmod-examples/1`` file, or asset files (glTF, GLB, URDF) and folders of
        them, one example per file (:func:`procmod.learn.examples.read_example_inputs`).
    out : path
        Output folder (created); a checkpoint left there by a killed run with the same
        examples and options is resumed. A non-empty folder that is not an earlier
        ``learn`` folder is refused unless ``overwrite`` (then replaced whole; see
        :class:`procmod.core.runfolder.RunFolder`).
    particles : int
        Parallel structure searches (particle filter), default 4.
    workers, scheduler
        Where the searches run (:func:`procmod.parallel.open_executor`).
    options : SearchOptions, optional
        Search constants (``particles`` and ``seed`` here override its fields).
    note : callable, optional
        Called with a line of advice about the examples before the search (examples of
        very different sizes, standing turned from the others, or holding a part twice at
        one place: :func:`procmod.learn.examples.size_note`,
        :func:`~procmod.learn.examples.orientation_note`, :func:`~procmod.learn.examples.duplicate_note`,
        :func:`~procmod.learn.examples.stray_note`).

    Returns
    -------
    dict
        Table-1 figures and the paths written.
    """
    from ..parallel import check_worker_limit, open_executor
    inputs = [Path(examples)] if isinstance(examples, (str, os.PathLike)) else [Path(p) for p in examples]
    shown = str(inputs[0]) if len(inputs) == 1 else " ".join(map(str, inputs))
    out = Path(out)
    folder = RunFolder(out, LEARN_RUN, overwrite, inputs=inputs)
    if not 1 <= samples <= MAX_SHEET_SAMPLES:
        raise InvalidArgumentError(f"{argument('samples')} must be from 1 to {MAX_SHEET_SAMPLES} (the contact "
                                   f"sheet's), got {samples:,}")
    example_set, digest = read_example_inputs(inputs)  # everything is read and checked before out is made
    check_part_names(example_set.parts)
    options = options or SearchOptions()
    options.particles, options.seed = particles, seed
    options.check()
    if workers:  # refused before the folder is made
        check_worker_limit(workers)
    labels = _example_labels(inputs, len(example_set.examples))
    from ..geometry.assets import faceless_note, left_out_note
    from .hanging import hanging_note
    for advice in (left_out_note(inputs), faceless_note(inputs), hanging_note(list(example_set.rehung), labels),
                   size_note(example_set, labels),
                   orientation_note(example_set, labels),
                   duplicate_note(example_set, labels), stray_note(example_set, labels),
                   near_twin_note(example_set, labels)):
        if advice is not None and note is not None:
            note(advice)
    with open_executor(workers, scheduler, note=note) as executor:  # an unreachable scheduler: before --out is made
        folder.prepare_in_place(keep=True)
        result = run_search(example_set, options, executor, out / "checkpoint", digest, progress,
                            replace_other=overwrite)
    program = result.program
    program.info["examples"] = shown
    # where they are, relative to the program's folder (which may move with them, and whose
    # file should not hold the user's folder layout), so that commands writing beside the
    # program never overwrite them (cli._learned_from)
    program.info["example_files"] = [os.path.relpath(p.resolve(), out.resolve()) for p in inputs]
    json_path = save_program(program, out)
    name = str(json_path.resolve())
    derivations = sample_program(program, name, samples, seed)
    examples_and_samples_sheet(example_set, derivations, out / "contact_sheet.png")
    _search_plot(result.rounds, out / "search.svg")
    report = {"format": "procmod-learn-report/1", "examples": shown, "table": result.table,
              "options": asdict(options), "trace": result.trace, "rounds": result.rounds,
              "resumed": result.resumed}
    write_text_atomic(out / "report.json", json.dumps(standard_json(report), indent=1) + "\n")  # no -Infinity
    write_text_atomic(out / "report.html", _report_html(result.table, result.trace, shown, command))
    return {"table": result.table, "program": str(json_path), "report": str(out / "report.html"),
            "contact_sheet": str(out / "contact_sheet.png"), "result": result}
