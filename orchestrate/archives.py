"""The one rule for every archive the toolkit unpacks (`safe_extract`): the relay's packs (site.tar.xz and
assets.tar.xz of `orchestrate.gpu_session --carry`). Archives are untrusted: whoever ships one chooses its member
names, links and modes.
"""
from __future__ import annotations

import lzma
import os
import tarfile
from pathlib import Path

from scenes.cli.errors import UsageError


def safe_extract(archive: Path, target: Path, flag: str = "--carry", under: str | None = None) -> None:
    """The one rule for every archive the toolkit unpacks (the relay's packs): every member name relative and
    without '..' (checked before anything is written), then tarfile's `data` filter, so that no member lands
    outside `target` after resolution (links out and devices are refused) and no setuid or group/other write bit
    is kept; with `under`, every member lies in that folder of `target` (the assets' archive writes work/assets
    only, never the session's other files or code on its path); a damaged, empty or foreign archive is a
    UsageError in one line naming it."""
    from pathlib import PurePosixPath

    from scenes.files import text_name_problem

    for folder in (target, target / under) if under else (target,):  # the filter resolves links, not these
        if folder.is_symlink():
            raise UsageError(f"{flag}: {str(folder)!r}, where {str(archive)!r} is unpacked, is a link (to "
                             f"{os.readlink(folder)!r}); the pack is unpacked only into a folder of its own, never "
                             "through a link into another: remove the link or use another --work")
    try:
        with tarfile.open(archive) as tar:
            seen: dict[str, bool] = {}  # member name -> a folder
            for member in tar.getmembers():  # every name checked before the first byte is written
                name = PurePosixPath(member.name)
                key = os.path.normpath(member.name)
                if key in seen and not (seen[key] and member.isdir()):  # the later would replace the earlier
                    raise UsageError(f"{flag}: {str(archive)!r} holds member {member.name[:120]!r} twice (expected "
                                     "each file once); refused")
                seen[key] = member.isdir()
                if name.is_absolute() or ".." in name.parts:
                    raise UsageError(f"{flag}: {str(archive)!r} holds member {member.name[:120]!r}, whose name would "
                                     f"lead outside {str(target)!r} (expected names relative to it); refused")
                if (problem := text_name_problem(member.name)) is not None:  # the renderer reads names as text
                    raise UsageError(f"{flag}: {str(archive)!r} holds a member whose name is not text: {problem}")
                if under is not None and (not name.parts or name.parts[0] != under):
                    raise UsageError(f"{flag}: {str(archive)!r} holds member {member.name[:120]!r} outside its "
                                     f"{under}/ folder (expected every member under {under}/); refused")
                if under is not None and not (member.isfile() or member.isdir()):  # a link would lead writes out
                    raise UsageError(f"{flag}: {str(archive)!r} holds member {member.name[:120]!r}, a link or "
                                     "special file (expected plain files and folders only); refused")
            tar.extractall(target, filter="data")
    except tarfile.FilterError as exc:
        raise UsageError(f"{flag}: {str(archive)!r} holds a member that would be unpacked outside {str(target)!r} "
                         f"({exc}); refused") from None
    except (tarfile.TarError, EOFError, lzma.LZMAError, OSError) as exc:
        first = (str(exc).splitlines() or [type(exc).__name__])[0]
        raise UsageError(f"{flag}: {str(archive)!r} cannot be unpacked ({first:.200}); expected the archive "
                         "`python -m orchestrate.gpu_session --pack` writes") from None
