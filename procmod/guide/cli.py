"""The ``procmod guide traces`` and ``procmod guide train`` commands (registered into
:mod:`procmod.cli`)."""

from __future__ import annotations

import sys
from pathlib import Path

from ..core import InvalidArgumentError
from ..core.errors import spelled


def register(sub, int_arg) -> None:
    """Add the ``guide`` subcommand group to the argparse subparsers ``sub``."""
    guide = sub.add_parser("guide", help="neural guides: make SMC training traces, train a guide")
    group = guide.add_subparsers(dest="guide_command", metavar="SUBCOMMAND", parser_class=type(guide))
    group.required = True

    traces = group.add_parser("traces", help="generate training traces with SMC (resumes an interrupted job)")
    traces.add_argument("model", metavar="MODEL", help="a built-in model, or FILE.py:NAME (a model of your own file)")
    traces.add_argument("--targets", default="scribble", help="scribble (default) or circuit")
    traces.add_argument("--count", type=int_arg, required=True, help="number of traces")
    traces.add_argument("--particles", type=int_arg, default=600, help="SMC particles per trace (default 600)")
    traces.add_argument("--seed", type=int_arg, default=0, help="random seed (default 0)")
    traces.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                        help="set a model parameter for every trace (repeatable), e.g. --param size=100: make "
                             "traces at the values the guide will run at")
    traces.add_argument("--out", required=True, help="traces folder (created; rerun to resume)")
    where = traces.add_mutually_exclusive_group()
    where.add_argument("--workers", type=int_arg, help="local worker processes (default: one per core)")
    where.add_argument("--scheduler", help="dask scheduler address, e.g. tcp://host:8786")
    traces.add_argument("--overwrite", action="store_true",
                        help="replace --out whole if it holds anything but traces of this same job "
                             "(which are resumed)")
    traces.set_defaults(handler=_cmd_traces)

    train = group.add_parser("train", help="train a guide on traces (resumes from its checkpoint)")
    train.add_argument("model", metavar="MODEL", help="the traces' model: a built-in model, or FILE.py:NAME")
    train.add_argument("--traces", required=True, help="traces folder made by 'procmod guide traces'")
    train.add_argument("--out", required=True, help="guide path: writes OUT.pt + OUT.json + OUT.npz (the weights inference reads "
                       "without torch)")
    train.add_argument("--features", default="all",
                       help="constant, local, local+target or all (default; seed 004 Figure 5), or any "
                            "'+'-joined set of local, target, partial and progress (circuit: local+partial; "
                            "all+progress: all, and the pending calls and covered fraction of the target)")
    train.add_argument("--mixture", type=int_arg, default=4, help="Gaussian components per continuous choice (default 4)")
    train.add_argument("--iterations", type=int_arg, default=20000, help="Adam steps (default 20000, as the papers)")
    train.add_argument("--batch", type=int_arg, default=1, help="traces per minibatch (default 1, as the papers)")
    train.add_argument("--lr", type=float, default=0.01, help="Adam step size (default 0.01)")
    train.add_argument("--lr-schedule", choices=("cosine", "constant"), default="cosine",
                       help="cosine (default): the step size anneals to zero over the run; "
                            "constant: the papers' setting")
    train.add_argument("--limit", type=int_arg, help="use only the first N traces")
    train.add_argument("--seed", type=int_arg, default=0, help="random seed (default 0)")
    train.set_defaults(handler=_cmd_train)


def _progress(total, unit):
    from ..progress import progress_bar
    return progress_bar(total=total, unit=unit)


def _cmd_traces(args) -> None:
    from ..parallel import check_scheduler, open_executor
    from .traces import generate_traces, trace_path

    if args.seed < 0:
        raise InvalidArgumentError(f"--seed must be a non-negative integer, got {args.seed}")
    params = {}
    if args.param:
        from ..cli import param_settings
        from ..models import model_from_spec

        params = param_settings(model_from_spec(args.model), args.param)
    if args.scheduler is not None:
        check_scheduler(args.scheduler)
    workers = 0 if args.workers is None and args.scheduler is None else args.workers
    bar = _progress(args.count, " traces")
    try:
        def progress(done, total):
            bar.n = done
            bar.refresh()

        with open_executor(workers=workers, scheduler=args.scheduler,
                           note=lambda text: print(f"note: {text}", file=sys.stderr)) as executor:
            summary = generate_traces(args.model, args.targets, args.count, args.out, args.particles,
                                      args.seed, executor, progress=progress, overwrite=args.overwrite,
                                      params=params)
    finally:
        bar.close()
    rate = summary["traces_per_hour"]
    for note in summary.get("notes", ()):
        print(f"note: {note}", file=sys.stderr)
    if summary.get("remade"):
        shown = ", ".join(str(trace_path(Path(args.out), i)) for i in summary["remade"][:3])
        one = len(summary["remade"]) == 1
        print(f"note: {len(summary['remade'])} trace {'file was' if one else 'files were'} damaged or not "
              f"{'its' if one else 'their'} number's trace ({shown}"
              f"{', ...' if len(summary['remade']) > 3 else ''}) and {'was' if one else 'were'} made again",
              file=sys.stderr)
    print(f"{summary['made']} traces made, {summary['present']} already there, in {summary['seconds']:.1f} s"
          + (f" ({rate:.0f} traces/hour)" if rate else "") + f"; folder: {args.out}")


def _check_replaces_a_guide(path) -> None:
    """Refuse to write a guide over an existing file that is not one (a user's JSON, torch
    model or numpy archive that happens to share the name): a guide's files (``.json``,
    ``.pt``, ``.npz``) are replaced only where ``.json`` beside them is a guide's."""
    import json

    from ..core.runfolder import OutputLocationError
    from .guide import FORMAT

    meta = path.with_suffix(".json")
    files = [p for p in (meta, path.with_suffix(".pt"), path.with_suffix(".npz")) if p.exists()]
    if not files:
        return
    try:
        found = json.loads(meta.read_text(encoding="utf-8")).get("format")
    except (OSError, ValueError, AttributeError):
        found = None
    if found != FORMAT:
        raise OutputLocationError(f"--out would replace {files[0]}, which is not part of a guide ({FORMAT}); give "
                                  "another --out, or move that file")


def _check_not_a_trace_name(out: Path, traces: Path) -> None:
    """Refuse a guide named as a trace inside the traces folder: the traces job took its
    ``.json`` for a trace it had made, and training then failed on it (h135)."""
    from ..core.runfolder import OutputLocationError
    from .traces import is_trace_name

    stem = out.with_suffix("") if out.suffix.lower() in (".pt", ".json", ".npz") else out
    if is_trace_name(stem.name + ".json") and stem.parent.resolve() == traces.resolve():
        raise OutputLocationError(f"--out {out} would put the guide's {stem.name}.json among the traces, under a "
                                  "trace's name; give another --out (a name outside the traces folder)")


def _cmd_train(args) -> None:
    from ..models import model_from_spec
    from .features import FeatureSettings
    from .train import train_guide

    model = model_from_spec(args.model)
    settings = FeatureSettings.condition(args.features)
    from ..core.paths import output_path
    from ..core.runfolder import check_output_file
    from .guide import guide_paths
    if str(args.out).endswith(("/", "\\")) or Path(args.out).is_dir():
        from ..core.runfolder import OutputLocationError
        raise OutputLocationError(f"--out {args.out} is a folder; a guide is files OUT.pt, OUT.npz and OUT.json: "
                                  f"give a name such as {Path(args.out) / 'guide'}")
    args.out = str(output_path(args.out))  # "a/b/../../G": no folders a/b made on the way
    _check_not_a_trace_name(Path(args.out), Path(args.traces))
    for path in guide_paths(args.out, for_writing=True):  # checked now, written after the training
        check_output_file(path, make_parent=True, inputs=[args.traces])
        _check_replaces_a_guide(path)
    bar = _progress(args.iterations, " steps")
    try:
        def progress(done, loss):
            bar.n = done
            bar.set_postfix(nll=f"{loss:.2f}", refresh=False)
            bar.refresh()

        with spelled({**{name: f"--{name}" for name in ("iterations", "batch", "mixture", "limit", "lr")},
                      "schedule": "--lr-schedule"}):
            guide, report = train_guide(model, args.traces, args.out, settings=settings, mixture=args.mixture,
                                        iterations=args.iterations, batch=args.batch, lr=args.lr,
                                        schedule=args.lr_schedule,
                                        limit=args.limit, seed=args.seed, progress=progress)
    finally:
        bar.close()
    print(f"trained {len(guide.sites)} site networks on {report['traces']} traces "
          f"({report['choices']} choices) in {report['seconds']:.1f} s; "
          f"mean negative log-likelihood per trace {report['final_nll']:.2f}; wrote {report['weights']} + {report['metadata']} "
          f"+ {Path(report['weights']).with_suffix('.npz')} (keep the three together)")
