"""Files a person looks at after an inference run: renders, curves, an HTML report."""

from __future__ import annotations

import html
import json
import os
import textwrap
from pathlib import Path

import numpy as np
from PIL import Image

from .core import save_derivation, write_text_atomic
from .core.io import standard_json
from .core.serialize import program_reference
from .core.serialize import derivation_to_dict
from .core.protocols import Target, check_declared
from .chart import COLOURS, Series, line_chart_svg
from .geometry import contact_sheet, save_image_atomic
from .render import check_geometry, derivation_image, derivation_images, output_formats, write_derivation


# What the curves' "mean" is, per engine: for SMC most particles are still partial
# derivations, scored as drawn so far, while "best" counts only complete ones; so the mean
# can lie above the best without anything being wrong.
MEAN_MEANING = {
    "smc": "mean: all current particles, most of them partial (scored as drawn so far); best: complete "
           "derivations only, so the mean can lie above it",
    "ga": "mean: the current population", "mcmc": "mean: the current chain states",
    "forward": "mean: the latest batch of forward samples",
}


def mean_meaning(engine: str) -> str:
    """What the "mean" curve of an engine's history averages (for captions)."""
    base = engine.split("+", 1)[0]
    return MEAN_MEANING.get("smc" if base == "sosmc" else base, "mean: the current population")


def convergence_figure(results: dict, path: str | os.PathLike, title: str = "") -> None:
    """Best (solid, stepped) and mean (dashed) score against evaluations, one colour per
    run, as an SVG chart (:mod:`procmod.chart`).

    The x axis is evaluations, not seconds: the history's rows are recorded at points of
    the work done, so a seeded run with a work budget draws the same figure, byte for
    byte, however fast the machine ran it (the wall time is in history.csv).
    """
    series = []
    engines = []
    for i, (label, result) in enumerate(results.items()):
        # each curve where it is finite: the best is -inf until a complete derivation the
        # target allows is found (a proxy run that found none had no chart at all)
        best = [r for r in result.history if np.isfinite(r.best_score)]
        mean = [r for r in result.history if np.isfinite(r.mean_score)]
        if not best and not mean:
            continue
        engines.append(result.engine)
        colour = COLOURS[i % len(COLOURS)]
        if best:
            series.append(Series(f"{label} best", [r.evaluations for r in best], [r.best_score for r in best], colour,
                                 step=True))
        if mean:
            series.append(Series(f"{label} mean", [r.evaluations for r in mean], [r.mean_score for r in mean], colour,
                                 dashed=True, opacity=0.6))
    notes = [textwrap.fill(n, 118) for n in dict.fromkeys(mean_meaning(e) for e in engines)]
    svg = line_chart_svg(series, title, "evaluations", "score", "\n".join(notes))
    write_text_atomic(path, svg)


SAMPLE_TILES = 16


def display_mask(target, width: int):
    """The target's picture to draw results over (``Target.display_mask``), or None for a
    target class that does not subclass Target and leaves it out, as the protocol's default
    says (h82: the run's report had failed on it after every engine had run)."""
    method = getattr(target, "display_mask", None)
    return method(width) if callable(method) else None


def sample_of_final(result, count: int = SAMPLE_TILES) -> list:
    """At most ``count`` of the engine's final samples, for the report's contact sheet.

    A fixed-size sample, so writing the report costs the same at 10 or 10,000
    particles. With importance weights (SMC, SOSMC, forward sampling) the sample is drawn
    by weight (systematic, a fixed seed: the report of a seeded run is reproducible);
    otherwise it is the first ``count`` (GA population, MCMC chains: already ordered as
    the engine keeps them). GA and MCMC give their states' log-likelihoods as
    ``log_weights``, which are no importance weights: drawn by them, a GA report of a
    population of 200 showed one or two individuals.
    """
    samples = list(result.samples)
    if len(samples) <= count:
        return samples
    weights = result.log_weights
    if weights is None or len(weights) != len(samples) or not np.isfinite(np.max(weights)) \
            or str(result.engine).split("+")[0] in ("ga", "mcmc"):
        return samples[:count]
    from .core.random import resample

    chosen = resample(weights, np.random.default_rng(0), "systematic", count)
    return [samples[i] for i in sorted(set(chosen.tolist()))]


def _mask_image(mask, width: int) -> Image.Image:
    grey = np.where(np.asarray(mask, bool), 60, 255).astype(np.uint8)
    return Image.fromarray(grey).resize((width, width), Image.NEAREST).convert("RGB")


def _json_setting(value):
    """A setting json cannot write as it is: a numpy number as the number (a user's
    ``elitism=np.float32(0.2)``), anything else as its text."""
    if isinstance(value, np.generic):
        return value.item()
    return str(value)


def write_run(result, target: Target, out: str | os.PathLike, size: int = 512, command: str = "") -> Path:
    """Write every file of an inference run into ``out`` and return the report's path.

    Files: best.png (2D: over the target in grey; 3D: a shaded view), best.svg (2D) or
    best.obj and best.glb (3D), best.json (derivation), target.png (image targets: the
    mask; silhouette targets: the first view with the best result's silhouette over it),
    history.csv, convergence.svg, samples.png (contact sheet of at most 16 of the final
    samples, drawn by weight: see :func:`sample_of_final`),
    settings.json and report.html tying them together.

    ``out`` is written into as it is (the CLI passes a fresh folder: see
    :class:`procmod.core.runfolder.RunFolder`). A seeded run with a budget in evaluations
    or generations writes the same bytes every time except its timing fields: the
    ``seconds`` column of history.csv, ``"seconds"`` of settings.json and the
    ``<span class="seconds">`` of report.html.
    """
    check_declared(target, Target, "the target")
    best = result.best
    if best is None:  # nothing to write a report of (the command line says so before calling this)
        from .infer.common import no_result_error
        raise no_result_error(result)
    derivation_to_dict(best)  # refuses what cannot be saved before any file is written
    check_geometry(best)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    underlay = display_mask(target, size)
    target_caption = "target"
    save_image_atomic(derivation_image(best, size, underlay=underlay), out / "best.png")
    extra = [suffix for suffix in output_formats(best) if suffix != ".png"]
    for suffix in extra:
        write_derivation(best, out / f"best{suffix}", size)
    save_derivation(best, out / "best.json")
    if underlay is not None:
        save_image_atomic(_mask_image(underlay, size), out / "target.png")
    elif target.has_overlay:  # silhouettes: the best result seen by the target camera
        from .core import replay
        seen = replay(best.model, best.choice_map(), np.random.default_rng(0), order=best.order(),
                      output=target.new_output(best.model)).derivation
        save_image_atomic(target.overlay_image(seen.output, 0, size), out / "target.png")
        target_caption = ("target view 1: the best result's silhouette (green) over the image "
                          "(blue: hit, yellow: avoid)")
    write_text_atomic(out / "history.csv", result.history_csv())
    target_name = str(getattr(target, "name", None) or type(target).__name__)  # (a user's target may have none)
    convergence_figure({result.engine: result}, out / "convergence.svg", f"{result.engine} on {target_name}")
    # 128 px tiles at 2x2 supersampling: the one part of the report whose cost grows with the
    # particles (up to 16 tiles), so kept cheap (~2 ms a vine tile here, each distinct
    # output drawn once: after the last resampling most particles are copies)
    tile_underlay = display_mask(target, 128)
    tiles = derivation_images(sample_of_final(result), 128, underlay=tile_underlay, supersample=2)
    save_image_atomic(contact_sheet(tiles), out / "samples.png")
    summary = {
        # a learned program's model name is its program.json's absolute path: written, as in
        # best.json, relative to the run folder (the page and settings.json had carried this
        # machine's layout, stale once the two were moved together)
        "engine": result.engine, "target": target_name, "model": program_reference(best.model.name, out),
        # the one timing field, to the microsecond: a short run takes a few milliseconds
        "best_score": result.best_score, "seconds": round(result.seconds, 6),
        "evaluations": result.evaluations, "log_marginal_likelihood": result.log_marginal_likelihood,
        "settings": result.settings, "notes": result.notes, "command": command,
    }
    # standard JSON (a -inf is null; the report's page and notes say what it was)
    write_text_atomic(out / "settings.json", json.dumps(standard_json(summary), indent=1, default=_json_setting)
                      + "\n")
    caption = target_caption if (out / "target.png").exists() else None
    viewer = run_viewer_html(out / "best.glb", target) if ".glb" in extra else ""
    write_text_atomic(out / "report.html", _report_html(summary, caption, extra, mean_meaning(result.engine),
                                                        viewer))
    return out / "report.html"


VIEW_WIDTH, VIEW_HEIGHT = 720, 480


def run_viewer_html(best_glb: str | os.PathLike, target) -> str:
    """The report's orbitable 3D view of a 3D run (:mod:`procmod.viewer`): the best result
    (the bytes of ``best.glb``) and the target (volumes as translucent surfaces, silhouette
    views as cut-outs where their cameras see them), everything inline."""
    from .viewer import viewer_html
    from .viewer.layers import run_view

    view = run_view(Path(best_glb).read_bytes(), target)
    return ("<h2>3D view</h2>\n<p>Drag to turn, scroll to zoom, right-drag to pan, double-click to reset; "
            "the boxes in the corner show or hide each layer.</p>\n" + viewer_html([view], VIEW_WIDTH, VIEW_HEIGHT))


def _report_html(summary: dict, target_caption: str | None, extra: list, mean_note: str, viewer: str = "") -> str:
    """The report page. Its one timing field is the wall time, written only inside
    ``<span class="seconds">``, so two runs of one seeded job differ only there."""
    rows = "".join(f"<tr><th>{html.escape(str(k))}</th><td>{html.escape(str(v))}</td></tr>"
                   for k, v in summary["settings"].items())
    notes = "".join(f"<li>{html.escape(n)}</li>" for n in summary["notes"])
    target_cell = (f'<figure><img src="target.png" alt="target"><figcaption>{html.escape(target_caption)}'
                   '</figcaption></figure>' if target_caption else "")
    seconds = f'<span class="seconds">{summary["seconds"]}</span>'
    links = "".join(f'<a href="best{suffix}">{suffix[1:].upper()}</a>, ' for suffix in extra)
    lml = summary["log_marginal_likelihood"]
    lml_row = f"<tr><th>log marginal likelihood</th><td>{lml:.4f}</td></tr>" if lml is not None else ""
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8">
<title>procmod: {html.escape(summary['engine'])} on {html.escape(summary['target'])}</title>
<style>
body {{ font-family: sans-serif; margin: 2em; color: #222; max-width: 70em; }}
figure {{ display: inline-block; margin: 0 1em 1em 0; vertical-align: top; }}
figure img {{ width: 320px; border: 1px solid #ccc; }}
table {{ border-collapse: collapse; margin: 1em 0; }}
th, td {{ text-align: left; padding: 0.2em 0.8em; border-bottom: 1px solid #eee; }}
code {{ background: #f4f4f4; padding: 0.1em 0.3em; }}
</style></head><body>
<h1>{html.escape(summary['model'])} &rarr; {html.escape(summary['target'])}</h1>
<p>Engine <b>{html.escape(summary['engine'])}</b>: best score <b>{summary['best_score']:.4f}</b>
after {summary['evaluations']} evaluations in {seconds} s.</p>
<p><code>{html.escape(summary['command'])}</code></p>
{viewer}{target_cell}
<figure><img src="best.png" alt="best result"><figcaption>best result
({links}<a href="best.json">derivation</a>)</figcaption></figure>
<figure><img src="convergence.svg" alt="convergence" style="width:480px"><figcaption>score against
evaluations ({html.escape(mean_note)}; <a href="history.csv">CSV</a>, with wall seconds)</figcaption></figure>
<h2>Final samples</h2>
<img src="samples.png" alt="final samples" style="max-width:100%">
<h2>Settings</h2>
<table><tr><th>seconds</th><td>{seconds}</td></tr>
<tr><th>evaluations</th><td>{summary['evaluations']}</td></tr>{lml_row}{rows}</table>
{'<h2>Notes</h2><ul>' + notes + '</ul>' if notes else ''}
</body></html>
"""
