"""The error types procmod raises for problems a user can cause.

Every user-caused error is a :class:`ProcmodError`; its message says what was wrong and
how to fix it, so the command-line tool can print it as one line and exit with status 2.
"""


class ProcmodError(Exception):
    """Base class of every error a user of procmod can cause."""


class ModelError(ProcmodError):
    """A model (its rules) broke a rule of the runtime, e.g. reused a choice name."""


class UnknownModelError(ProcmodError):
    """A model name that no registry knows."""


class DerivationFormatError(ProcmodError):
    """A derivation file that cannot be read, is malformed, or does not match its model."""


class InvalidArgumentError(ProcmodError):
    """A bad value for an option or argument (negative count, unknown format, ...)."""
