"""The ``procmod strings ...`` commands (registered into :mod:`procmod.cli`)."""

from __future__ import annotations


def register(sub, int_arg) -> None:
    """Add the ``strings`` subcommand group to the argparse subparsers ``sub``.

    Each leaf parser sets ``handler`` (a function of the parsed args) with ``set_defaults``.
    """
