"""Exceptions raised by uio_jax.

Every error a user can cause (bad model, bad option, bad file) is a subclass of
:class:`UioJaxError`, itself a ``ValueError``, with a one-line message that names the
problem. The command line prints that line and exits with code 2.
"""


class UioJaxError(ValueError):
    """Base class of every error caused by the user's input."""


class ModelError(UioJaxError):
    """The model is malformed: wrong shapes, unknown names, NaN everywhere, ..."""


class OptionError(UioJaxError):
    """An option of an analysis or of the command line is impossible."""


class LoadError(UioJaxError):
    """A model file or entry point could not be loaded."""


class ExpressionError(ModelError):
    """An expression of a model file is not valid or uses something outside the whitelist."""


def exit_message(exc: SystemExit) -> str:
    """What user code that raised ``exc`` did, for a one-line error:
    ``called sys.exit(0)``."""
    return f"called sys.exit({exc.code!r}) (SystemExit)"

