"""The one usage-error type of every command-line entry point, and how it is reported.

Defined at the bottom layer so that `wildgen`, `unips`, `validate` and `orchestrate` CLIs share it without
importing each other: a CLI raises `UsageError` (or lets its library raise ValueError /
FileNotFoundError), and its `main` turns that into one line `error: ...` on stderr and a non-zero exit
status with `report_error`, never a traceback.
"""
from __future__ import annotations

import sys


EXIT_USAGE = 2
"""Exit status of a usage or input error (argparse's own)."""


class UsageError(Exception):
    """A usage or input error that a CLI reports as one line."""

INPUT_ERRORS: tuple[type[BaseException], ...] = (UsageError, ValueError, FileNotFoundError)
"""Exceptions every CLI reports as one line with `report_error`."""


def one_line(exc: BaseException) -> str:
    """The message of `exc` on one line."""
    return str(exc).replace("\n", " ")


def report_error(exc: BaseException, code: int = EXIT_USAGE) -> int:
    """Print `error: <message>` (one line) on stderr and return the exit status `code`."""
    print(f"error: {one_line(exc)}", file=sys.stderr)
    return code
