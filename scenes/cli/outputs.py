"""What a command may write: `check_output_folder` refuses an output folder that cannot be written before any
work (`make_output_folder` then creates it); `claim_outputs` is the one rule of `--overwrite` (see its
docstring and docs/development.md, "Outputs and --overwrite").
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Iterable

from scenes.cli.errors import UsageError


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


def make_output_folder(path: str | os.PathLike, flag: str = "--out") -> str | os.PathLike:
    """`check_output_folder`, then create the folder (and its parents); a failure is a UsageError naming
    `flag`. Returns `path`."""
    check_output_folder(path, flag)
    try:
        os.makedirs(path, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"{flag}: cannot create the folder {str(path)!r} ({exc.strerror or exc})") from None
    return path


def claim_outputs(paths: Iterable[str | os.PathLike], overwrite: bool, flag: str = "--out", owner: str = "this command",
                  marker: str | os.PathLike | None = None, folders: bool = False, resume: str = "") -> list[Path]:
    """The one rule of every command that writes, applied before any work to the outputs it is about to write.

    - An output that does not exist yet is written.
    - An output that exists is an earlier run's: without `overwrite` the command refuses (UsageError naming it
      and --overwrite); with `overwrite` it is replaced (a file atomically, by its writer).
    - Never replaced, even with `overwrite`: anything of another kind under an output's name (a folder or a
      link where a file is written, a file where a folder is), and, when `marker` is given (the file that marks
      a folder as a command's own, e.g. predict.json or manifest.json), any output that exists while the
      marker does not: those are not the command's files.

    `folders`: the outputs are folders (e.g. object folders) rather than files. `resume`: how the command
    continues an earlier run instead, for the message (e.g. "--resume to continue it"). Files that are not
    among `paths` are never touched. Returns the outputs that exist (those to be replaced).
    """
    paths = [Path(p) for p in paths]
    existing = [p for p in paths if os.path.lexists(p)]
    want = "a folder" if folders else "a file"
    for p in existing:
        if p.is_symlink() or not (p.is_dir() if folders else p.is_file()):
            kind = (
                "a link"
                if p.is_symlink()
                else "a folder"
                if p.is_dir()
                else "a file"
                if p.is_file()
                else "not a plain file"
            )
            raise UsageError(f"{flag}: {str(p)!r} is {kind}, where {owner} writes {want}; it is never replaced: "
                             f"move it away or use another {flag}")
    if existing and marker is not None and not os.path.lexists(marker):
        more = f" (and {len(existing) - 1} more)" if len(existing) > 1 else ""
        raise UsageError(f"{flag}: {str(existing[0])!r}{more} was not written by {owner} (no {Path(marker).name} in "
                         f"{str(Path(marker).parent)!r}); it is never replaced, even with --overwrite: move it away or "
                         f"use another {flag}")
    if existing and not overwrite:
        more = f" (and {len(existing) - 1} more)" if len(existing) > 1 else ""
        also = f", {resume}" if resume else ""
        raise UsageError(f"{flag}: {str(existing[0])!r}{more} exists, from an earlier run; pass --overwrite to "
                         f"replace it{also}, or use another {flag}")
    return existing
