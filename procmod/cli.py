"""The ``procmod`` command.

Every error a user can cause prints one line on stderr and exits with status 2, leaving
no partial output file behind.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from . import __version__
from .core import InvalidArgumentError, ProcmodError, load_derivation, run_forward, save_derivation
from .models import MODELS, get_model
from .render import check_format, check_size, write_contact_sheet, write_derivation


class _Parser(argparse.ArgumentParser):
    """argparse that reports a usage error as one line (exit 2) instead of usage text."""

    def error(self, message):
        raise InvalidArgumentError(f"{message} (see '{self.prog} --help')")


def _int_arg(text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None


def _build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="procmod", description="Probabilistic procedural modeling.")
    parser.add_argument("--version", action="version", version=f"procmod {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True

    sub.add_parser("models", help="list the built-in models")

    sample = sub.add_parser("sample", help="sample a model forward; write PNG, SVG and JSON per sample")
    sample.add_argument("model", metavar="MODEL")
    sample.add_argument("-n", type=_int_arg, default=16, help="number of samples (default 16)")
    sample.add_argument("--seed", type=_int_arg, default=0, help="random seed (default 0)")
    sample.add_argument("--out", required=True, help="output folder (created if missing)")
    sample.add_argument("--size", type=_int_arg, default=256, help="render width in pixels (default 256)")

    render = sub.add_parser("render", help="render a saved derivation to PNG or SVG")
    render.add_argument("derivation", metavar="DERIVATION.json")
    render.add_argument("--out", required=True, help="output file, .png or .svg")
    render.add_argument("--size", type=_int_arg, default=512, help="width in pixels (default 512)")
    return parser


def _cmd_models(args) -> None:
    width = max(len(name) for name in MODELS)
    for name in sorted(MODELS):
        print(f"{name:<{width}}  {MODELS[name].description}")


def _cmd_sample(args) -> None:
    model = get_model(args.model)
    if args.n < 1:
        raise InvalidArgumentError(f"-n must be a positive number of samples, got {args.n}")
    if args.seed < 0:
        raise InvalidArgumentError(f"--seed must be a non-negative integer, got {args.seed}")
    size = check_size(args.size)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise InvalidArgumentError(f"--out {out} exists and is not a folder")
    # Sample i depends only on (seed, i), so asking for more samples keeps the first ones.
    derivations = [run_forward(model, np.random.default_rng([args.seed, i])) for i in range(args.n)]
    out.mkdir(parents=True, exist_ok=True)
    digits = max(3, len(str(args.n - 1)))
    for i, derivation in enumerate(derivations):
        stem = out / f"sample_{i:0{digits}d}"
        save_derivation(derivation, stem.with_suffix(".json"))
        write_derivation(derivation, stem.with_suffix(".png"), size)
        write_derivation(derivation, stem.with_suffix(".svg"), size)
    write_contact_sheet(derivations, out / "contact_sheet.png", labels=[str(i) for i in range(args.n)])
    print(f"wrote {args.n} samples of {model.name} to {out}/ (contact sheet: {out / 'contact_sheet.png'})")


def _cmd_render(args) -> None:
    check_format(args.out)
    size = check_size(args.size)
    derivation = load_derivation(args.derivation, get_model)
    write_derivation(derivation, args.out, size)
    print(f"wrote {args.out}")


_COMMANDS = {"models": _cmd_models, "sample": _cmd_sample, "render": _cmd_render}


def main(argv=None) -> int:
    """Entry point of the ``procmod`` console script; returns the exit status."""
    try:
        args = _build_parser().parse_args(argv)
        _COMMANDS[args.command](args)
    except ProcmodError as exc:
        print(f"procmod: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("procmod: interrupted", file=sys.stderr)
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
