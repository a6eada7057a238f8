"""A clear word, instead of a traceback, when the toolkit is run with a Python that lacks its packages.

Every package imports this first (`scenes/__init__.py`; `wildgen`, `unips`, `validate` and `orchestrate` import
`scenes`), so `python -m wildgen.make` with the system Python says how to run it rather than failing on the
first missing import.
"""
from __future__ import annotations

import importlib.util
import sys

REQUIRED = ("numpy", "scipy", "cv2")
"""Modules every command needs (import names), checked by presence only (nothing is imported here); Mitsuba and
torch are not listed: a training machine may lack Mitsuba, and their own imports name them."""


def missing_modules() -> list[str]:
    """The modules of `REQUIRED` this Python cannot import."""
    return [m for m in REQUIRED if importlib.util.find_spec(m) is None]


def require_environment() -> None:
    """Exit with one line naming the missing modules and the fix when this Python lacks the toolkit's packages."""
    missing = missing_modules()
    if missing:
        sys.stderr.write(f"error: this Python ({sys.executable}) lacks {', '.join(missing)}: run the toolkit in its "
                         "environment: `make setup`, then `source .venv/bin/activate` (or call .venv/bin/python)\n")
        raise SystemExit(2)
