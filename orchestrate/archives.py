"""The one rule for every archive the toolkit unpacks (`safe_extract`): the relay's packs (site.tar.xz and
assets.tar.xz of `orchestrate.gpu_session --carry`). Archives are untrusted: whoever ships one chooses its member
names, links and modes. `unpack_once` unpacks into a folder of the command's own (a user's files there are never
replaced member by member).
"""
from __future__ import annotations

import lzma
import os
import tarfile
from pathlib import Path

from scenes.cli.errors import UsageError

UNPACKED_LIMIT = 2**30
"""Bytes an archive may unpack to: a pack travels within the 64 MiB upload limit and xz packs the wheels' binaries
about 4:1 (site.tar.xz: 41.5 MiB), so 1 GiB, 16 times the whole upload, is only reached by a decompression bomb
(a few hundred KiB of xz that unpack to gigabytes of zeros and fill the GPU machine's disk)."""


def _digest(archive: Path) -> str:
    import hashlib

    with open(archive, "rb") as f:
        return hashlib.file_digest(f, "sha256").hexdigest()


def unpack_once(archive: Path, target: Path, under: str | None = None, replace: bool = False) -> None:
    """`safe_extract` into a folder of the command's own: `target` (or its `under` folder), where it already holds
    files, is left as it is when this very archive was unpacked there before (a resumed session: its marker, a
    hidden file beside the folder, holds the archive's SHA-256), refused when anything else put them there (a
    user's files would be replaced member by member), and emptied first with `replace` (--overwrite)."""
    import shutil

    dest = target / under if under else target
    marker = dest.parent / f".{dest.name}.unpacked"
    try:
        digest = _digest(archive)
        held = dest.is_dir() and not dest.is_symlink() and any(dest.iterdir())
        ours = held and marker.is_file() and marker.read_text(errors="replace").strip() == digest
    except OSError as exc:
        raise UsageError(f"--carry: {str(archive)!r} or {str(dest)!r} cannot be read ({exc.strerror or exc}); "
                         "expected a readable pack and --work") from None
    if ours:
        return
    if held and not replace:
        raise UsageError(f"--work: {str(dest)!r} already holds files that {str(archive)!r} did not put there "
                         "(expected a new or empty --work, or the one an earlier session with this pack used); "
                         "pass --overwrite to replace them, or use another --work")
    if held:
        shutil.rmtree(dest)
    marker.unlink(missing_ok=True)
    safe_extract(archive, target, under=under)
    marker.write_text(digest + "\n")


def safe_extract(archive: Path, target: Path, flag: str = "--carry", under: str | None = None) -> None:
    """The one rule for every archive the toolkit unpacks (the relay's packs): every member name relative and
    without '..' and every member a plain file or folder (--pack writes no links: a link, even one inside the
    target, would let a later member write through it), checked before anything is written; then tarfile's `data`
    filter, so that no member lands outside `target` after resolution and no setuid or group/other write bit is
    kept; with `under`, every member lies in that folder of `target` (the assets' archive writes work/assets only,
    never the session's other files or code on its path); a damaged, empty or foreign archive is a UsageError in
    one line naming it."""
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
                if any(ord(c) < 32 or ord(c) == 127 for c in member.name):  # a newline splits a name in any list
                    raise UsageError(f"{flag}: {str(archive)!r} holds member {member.name[:120]!r}, whose name holds a "
                                     "control character (a newline, a tab); expected names as --pack writes them; "
                                     "refused")
                if (problem := text_name_problem(member.name)) is not None:  # the renderer reads names as text
                    raise UsageError(f"{flag}: {str(archive)!r} holds a member whose name is not text: {problem}")
                if under is not None and not (name.parts[:1] == (under,) and (len(name.parts) > 1 or member.isdir())):
                    raise UsageError(f"{flag}: {str(archive)!r} holds member {member.name[:120]!r} outside its "
                                     f"{under}/ folder (expected every member inside {under}/, a folder); refused")
                if not (member.isfile() or member.isdir()):  # a link aliases a path inside or leads writes out
                    raise UsageError(f"{flag}: {str(archive)!r} holds member {member.name[:120]!r}, a link or "
                                     "special file (expected plain files and folders only, as --pack writes); "
                                     "refused")
            if all(seen.values()):  # folders only, or no member: nothing to unpack, not a pack's archive
                raise UsageError(f"{flag}: {str(archive)!r} holds no file (expected the archive `python -m "
                                 "orchestrate.gpu_session --pack` writes); refused")
            _check_unpacked_size(archive, target, sum(m.size for m in tar.getmembers() if m.isfile()), flag)
            tar.extractall(target, filter="data")
    except tarfile.FilterError as exc:
        raise UsageError(f"{flag}: {str(archive)!r} holds a member that would be unpacked outside {str(target)!r} "
                         f"({exc}); refused") from None
    except (tarfile.TarError, EOFError, lzma.LZMAError, OSError, OverflowError, ValueError) as exc:
        # OverflowError / ValueError: a member's time or mode out of range for this platform (a forged header)
        first = (str(exc).splitlines() or [type(exc).__name__])[0]
        raise UsageError(f"{flag}: {str(archive)!r} cannot be unpacked ({first:.200}); expected the archive "
                         "`python -m orchestrate.gpu_session --pack` writes") from None


def _check_unpacked_size(archive: Path, target: Path, total: int, flag: str) -> None:
    """UsageError when the members of `archive` would unpack to more than `UNPACKED_LIMIT` bytes, or to more than
    the free space where `target` lies: said before the first byte is written, not as a full disk."""
    import shutil

    if total > UNPACKED_LIMIT:
        raise UsageError(f"{flag}: {str(archive)!r} would unpack to {total} bytes ({total / 2**30:.1f} GiB) from "
                         f"{archive.stat().st_size} bytes, over the {UNPACKED_LIMIT // 2**20} MiB a pack unpacks to "
                         "(expected the archive `python -m orchestrate.gpu_session --pack` writes); refused")
    existing = next(p for p in (target, *target.parents) if p.exists())
    free = shutil.disk_usage(existing).free
    if total > free:
        raise UsageError(f"{flag}: {str(archive)!r} would unpack to {total} bytes, more than the {free} bytes free "
                         f"where {str(target)!r} lies; free some space or use another --work")
