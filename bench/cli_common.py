"""What the bench scripts' command lines share: the toolkit's tyro CLI (`scenes.cli.options.Command`), read the
same way, the default DiLiGenT folder and the record of the machine a result was measured on.

Each script (run as `python bench/NAME.py`, with the repository root put first on sys.path) declares its options
as a config dataclass and `COMMAND = Command(Options, prog="python bench/NAME.py", description=...)`; its `main`
reads the command line with `parse(COMMAND, argv)`.
"""
from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

from scenes.cli.errors import INPUT_ERRORS, report_error
from scenes.cli.options import Command, check_fields

ROOT = Path(__file__).resolve().parents[1]
"""The repository root."""
DILIGENT = ROOT.parent / "shared" / "data" / "diligent"
"""Where the DiLiGenT objects (ballPNG/, catPNG/, ...) lie next to the checkout."""


def parse(command: Command, argv: Sequence[str] | None = None) -> Any:
    """The checked config of `argv` (sys.argv[1:] when None): its `validate()` where the config has one, else
    `check_fields`. A bad command line prints one line `error: ...` on stderr and exits with status 2, as
    argparse did; `--help` prints the help and exits 0."""
    try:
        cfg = command.parse(argv)
        return cfg.validate() if hasattr(cfg, "validate") else check_fields(cfg)
    except INPUT_ERRORS as exc:
        raise SystemExit(report_error(exc)) from None


def machine() -> dict:
    """The `machine` record of a bench's output: the machine's cores and platform."""
    import os
    import platform

    return {"cpus": os.cpu_count(), "platform": platform.platform()}
