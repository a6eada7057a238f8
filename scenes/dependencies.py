"""A clear word, instead of a traceback, when the toolkit is run with a Python that lacks its packages.

Every package imports this first (`scenes/__init__.py`; `wildgen`, `unips`, `validate` and `orchestrate` import
`scenes`). Importing never exits the process: in such a Python it raises `MissingDependencyError` (a
ModuleNotFoundError, so `except ImportError` catches it) whose message is one line naming the missing modules
and the fix. Left uncaught, as in `python -m wildgen.make` with the system Python, that error ends the process
like every CLI's usage error: the one line `error: ...` on stderr and exit status 2 (`report_uncaught`), not a
traceback.
"""
from __future__ import annotations

import importlib.util
import os
import sys

from scenes.cli.errors import MissingDependencyError, WorkingFolderGoneError, report_error

REQUIRED = ("numpy", "scipy", "cv2")
"""Modules every command needs (import names), checked by presence only (nothing is imported here); Mitsuba and
torch are not listed: a training machine may lack Mitsuba, and their own imports name them."""

_previous_excepthook = sys.__excepthook__


def missing_modules() -> list[str]:
    """The modules of `REQUIRED` this Python cannot import."""
    return [m for m in REQUIRED if importlib.util.find_spec(m) is None]


def require_environment() -> None:
    """Raise `MissingDependencyError` (one line: the missing modules and the fix) when this Python lacks the
    toolkit's packages, or `WorkingFolderGoneError` when the current folder no longer exists, after making
    `report_uncaught` the interpreter's `sys.excepthook`."""
    global _previous_excepthook
    missing = missing_modules()
    gone = not _working_folder_exists()
    if (missing or gone) and sys.excepthook is not report_uncaught:
        _previous_excepthook, sys.excepthook = sys.excepthook, report_uncaught
    if gone:  # before torch is imported: its MKL dies in such a folder with a misleading "Cannot load libtorch_cpu"
        raise WorkingFolderGoneError("the current folder no longer exists (it was deleted or moved while this "
                                     "shell was in it): cd into a folder that exists and run the command again")
    if missing:
        raise MissingDependencyError(
            f"this Python ({sys.executable}) lacks {', '.join(missing)}: run the toolkit in its environment: "
            "`make setup`, then `source .venv/bin/activate` (or call .venv/bin/python)", name=missing[0])


def _working_folder_exists() -> bool:
    try:
        os.getcwd()
    except FileNotFoundError:
        return False
    return True


def report_uncaught(kind: type[BaseException], exc: BaseException, tb) -> None:
    """`sys.excepthook` once `require_environment` has raised: an uncaught `MissingDependencyError` in a script
    or `python -m` run is reported as the one line `error: ...` and the process exits with status 2 (a SystemExit
    raised by the hook ends the interpreter as `sys.exit` does); anything else, and everything in an interactive
    session, goes to the hook it replaced."""
    ours = isinstance(exc, (MissingDependencyError, WorkingFolderGoneError))
    if ours and not (sys.flags.interactive or hasattr(sys, "ps1")):
        raise SystemExit(report_error(exc))
    _previous_excepthook(kind, exc, tb)
