"""User-facing errors.

Anything raised as :class:`NrmlcError` is a problem with the user's input
(a file, a folder, a parameter). The CLI prints it as a single line and
exits non-zero; tracebacks are reserved for bugs (or ``--debug``).
"""
from __future__ import annotations

import threading

#: Set by the CLI's SIGINT / SIGTERM / SIGHUP handler. A KeyboardInterrupt that lands while Python runs a
#: finaliser (a ``__del__``, e.g. llvmlite's) is printed and dropped, so the CLI also checks this
#: before it commits any output.
interrupt_requested = threading.Event()


class NrmlcError(Exception):
    """Base class: a one-line message that names the file or parameter."""


class DataError(NrmlcError):
    """A sequence folder, image or annotation file is missing or malformed."""


class ParameterError(NrmlcError, ValueError):
    """A tracker or CLI parameter is out of range or malformed."""


class OutputError(NrmlcError, OSError):
    """An output cannot be written completely (a full disk, a lost permission); nothing was replaced."""
