"""The ``procmod learn`` command (registered into :mod:`procmod.cli`)."""

from __future__ import annotations


def register(sub, int_arg) -> None:
    """Add the ``learn`` subcommand to the argparse subparsers ``sub``.

    Each parser sets ``handler`` (a function of the parsed args) with ``set_defaults``.
    """
