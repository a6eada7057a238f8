"""The one usage-error type of every command-line entry point, and how it is reported.

Defined at the bottom layer so that `wildgen`, `unips`, `validate` and `orchestrate` CLIs share it without
importing each other: a CLI raises `UsageError` (or lets its library raise ValueError /
FileNotFoundError), and its `main` turns that into one line `error: ...` on stderr and a non-zero exit
status with `report_error`, never a traceback.
"""
from __future__ import annotations

import argparse
import os
import sys
from contextlib import contextmanager
from typing import Callable, Iterator, NoReturn

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


def check_output_folder(path: str | os.PathLike, flag: str = "--out") -> str | os.PathLike:
    """Refuse an output folder that cannot be written, before any work: an existing file, a path under a
    file, or a folder (or the nearest existing parent of a new one) this process may not write. Creates
    nothing. Returns `path`."""
    target = os.path.abspath(path)
    if os.path.exists(target):
        if not os.path.isdir(target):
            raise UsageError(f"{flag}: {str(path)!r} is an existing file, expected a folder")
        if not os.access(target, os.W_OK | os.X_OK):
            raise UsageError(f"{flag}: the folder {str(path)!r} is not writable")
        return path
    parent = os.path.dirname(target)
    while not os.path.exists(parent):
        parent = os.path.dirname(parent)
    if not os.path.isdir(parent):
        raise UsageError(f"{flag}: cannot create the folder {str(path)!r}: {parent!r} is a file")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise UsageError(f"{flag}: cannot create the folder {str(path)!r}: {parent!r} is not writable")
    return path


class UsageErrorParser(argparse.ArgumentParser):
    """An ArgumentParser whose errors raise UsageError (one line) instead of printing the usage and exiting."""

    def error(self, message: str) -> NoReturn:
        raise UsageError(message)


@contextmanager
def progress_bar(unit: str) -> Iterator[Callable[[int, int, str], None]]:
    """A `progress(done, total, label)` callback drawing one tqdm bar, closed on exit. The bar is created at the
    first call, so that an input error found before any work still prints one clean error line."""
    from tqdm import tqdm

    bars: list = []

    def progress(done: int, total: int, label: str) -> None:
        if not bars:
            bars.append(tqdm(unit=unit, leave=False))
        bars[0].total, bars[0].n = total, done
        bars[0].set_description(label)
        bars[0].refresh()

    try:
        yield progress
    finally:
        for bar in bars:
            bar.close()
