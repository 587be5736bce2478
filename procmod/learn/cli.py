"""The ``procmod learn`` command (registered into :mod:`procmod.cli`)."""

from __future__ import annotations

import sys

from ..core.errors import InvalidArgumentError


def register(sub, int_arg) -> None:
    """Add the ``learn`` subcommand to the argparse subparsers ``sub``.

    Each parser sets ``handler`` (a function of the parsed args) with ``set_defaults``.
    """
    learn = sub.add_parser(
        "learn", help="learn a probabilistic program from part-based examples (procmod-examples/1, or "
                      "glTF / GLB / URDF files, one example each)")
    learn.add_argument("examples", metavar="EXAMPLES", nargs="+",
                       help="a procmod-examples/1 JSON file, or asset files (.gltf, .glb, .urdf) and folders of "
                            "them: one example per file, parts shared by geometry")
    learn.add_argument("--out", required=True, help="output folder: program.json (+ program.pt), "
                                                    "contact_sheet.png, report.html; resumes a killed run")
    learn.add_argument("--particles", type=int_arg, default=4,
                       help="parallel structure searches (particle filter; default 4)")
    group = learn.add_mutually_exclusive_group()
    group.add_argument("--workers", type=int_arg, default=None,
                       help="local worker processes for the parallel searches (default 0: one per "
                            "core; 1 runs them in this process)")
    group.add_argument("--scheduler", default=None, help="dask scheduler address (tcp://host:8786)")
    learn.add_argument("--seed", type=int_arg, default=0, help="random seed (default 0)")
    learn.add_argument("--estimator", default="exact", choices=("exact", "vi"),
                       help="parameter estimation: exact marginal likelihood (default) or the paper's VI")
    learn.add_argument("--samples", type=int_arg, default=10, help="samples on the contact sheet (default 10)")
    learn.add_argument("--overwrite", action="store_true",
                       help="replace a non-empty --out folder that is not an earlier learn run (never one holding "
                            "an input)")
    learn.set_defaults(handler=_cmd_learn)


def _cmd_learn(args) -> None:
    from .pipeline import learn
    from .search import SearchOptions

    if args.particles < 1:
        raise InvalidArgumentError(f"--particles must be a positive integer, got {args.particles}")
    if args.seed < 0:
        raise InvalidArgumentError(f"--seed must be a non-negative integer, got {args.seed}")
    if args.workers is not None and args.workers < 0:
        raise InvalidArgumentError(f"--workers must be >= 0 (0 = one per core), got {args.workers}")
    from ..progress import progress_lines

    progress = progress_lines()

    command = "procmod " + " ".join(sys.argv[1:]) if sys.argv and sys.argv[0].endswith("procmod") else ""
    workers = 0 if args.workers is None and args.scheduler is None else args.workers
    out = learn(args.examples, args.out, particles=args.particles, workers=workers,
                scheduler=args.scheduler, seed=args.seed, options=SearchOptions(estimator=args.estimator),
                samples=args.samples, progress=progress, command=command, overwrite=args.overwrite,
                note=lambda text: print(f"note: {text}", file=sys.stderr))
    progress.end()
    t = out["table"]
    print(f"learned {t['A_star']} abstractions (P0: {t['A0']}); O_D {t['O_P0']:.2f} -> {t['O_Pstar']:.2f} "
          f"in {t['seconds']:.1f} s; program: {out['program']}; report: {out['report']}")
