"""The one usage-error type of every command-line entry point, and how it is reported.

Defined at the bottom layer so that `wildgen`, `unips`, `validate` and `orchestrate` CLIs share it without
importing each other: a CLI raises `UsageError` (or lets its library raise ValueError /
FileNotFoundError, or importing `scenes` raise `MissingDependencyError`), and its `main` turns that into one line
`error: ...` on stderr and a non-zero exit status with `report_error`, never a traceback.
"""
from __future__ import annotations

import sys

EXIT_USAGE = 2
"""Exit status of a usage or input error (argparse's own)."""


class UsageError(Exception):
    """A usage or input error that a CLI reports as one line."""


class MissingDependencyError(ModuleNotFoundError):
    """This Python lacks packages every command needs (`scenes.dependencies`, raised by importing `scenes`); its
    message is one line naming them and the fix."""


INPUT_ERRORS: tuple[type[BaseException], ...] = (UsageError, ValueError, FileNotFoundError, MissingDependencyError)
"""Exceptions every CLI reports as one line with `report_error`."""


TRACEBACK = "Traceback (most recent call last):"


def _without_traceback(text: str) -> str:
    """The original message of an error that carries another process's traceback in its text (torch's DataLoader
    re-raises a worker's error as "Caught ValueError in DataLoader worker process 1.\nOriginal Traceback ...");
    other text as it is."""
    if TRACEBACK not in text:
        return text
    lines = text[text.rindex(TRACEBACK) + len(TRACEBACK):].splitlines()
    start = next((i for i, line in enumerate(lines) if line.strip() and not line.startswith(" ")), None)
    if start is None:
        return text
    kind, sep, message = "\n".join(lines[start:]).partition(": ")
    return message if sep and kind.replace(".", "").replace("_", "").isalnum() else kind + sep + message


def one_line(exc: BaseException) -> str:
    """The message of `exc` on one line (without a traceback another process put into it); a copy of a folder that
    failed (`shutil.Error`, a list of every file) by its first file; a full disk with what to do."""
    import errno
    import shutil

    if isinstance(exc, shutil.Error) and exc.args and isinstance(exc.args[0], list) and exc.args[0]:
        first = exc.args[0][0]
        src, dst, why = first if isinstance(first, tuple) and len(first) == 3 else ("?", "?", first)
        more = f" (and {len(exc.args[0]) - 1} more file(s))" if len(exc.args[0]) > 1 else ""
        text = f"could not copy {src!r} to {dst!r}{more}: {why}"
        full = "No space left on device" in str(why)
    else:
        text = _without_traceback(str(exc))
        full = isinstance(exc, OSError) and exc.errno == errno.ENOSPC
    if full:
        text += " (the disk it writes to is full: free space there, or write the output elsewhere)"
    return text.replace("\n", " ")


def report_error(exc: BaseException, code: int = EXIT_USAGE) -> int:
    """Print `error: <message>` (one line) on stderr and return the exit status `code`."""
    print(f"error: {one_line(exc)}", file=sys.stderr)
    return code
