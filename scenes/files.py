"""Writing files so that a reader never sees half of one (write to a temporary name, then rename), and their
SHA-256 checksums: used by object folders, shards, model checkpoints and reports alike.
"""
from __future__ import annotations

import os
import re
from pathlib import Path


def sha256_file(path: str | Path) -> str:
    """Hex SHA-256 of a file, read in 1 MiB chunks (the checksums of manifests and shard indexes)."""
    import hashlib

    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _temporary(path: Path) -> Path:
    """A hidden name beside `path` with the same extension (image writers choose the format by it)."""
    return path.with_name(f".{path.stem}.tmp{os.getpid()}{path.suffix}")


_TEMPORARY = re.compile(r"^\.(?P<stem>.+)\.tmp\d+(?P<suffix>(\.[^.]*)?)$")


def temporary_target(name: str) -> str | None:
    """The file name whose temporary (`atomic_write`: `.<stem>.tmp<pid><suffix>`) `name` is, or None: what a
    killed writer left behind, which an --overwrite of the same outputs removes."""
    m = _TEMPORARY.match(name)
    return None if m is None else m["stem"] + m["suffix"]


def atomic_write(path: str | Path, write) -> None:
    """Call `write(tmp)` on a temporary name beside `path`, then rename it to `path`: a kill or a full disk
    never leaves a truncated file under the real name (the temporary one is removed on failure)."""
    path = Path(path)
    tmp = _temporary(path)
    try:
        write(tmp)
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        if str(path) in str(exc):
            raise
        raise OSError(exc.errno, f"could not write {str(path)!r}: {exc.strerror or exc}") from exc
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def atomic_write_text(path: str | Path, text: str) -> None:
    """Write a text file through a temporary name and rename, so readers never see half a file."""
    atomic_write(path, lambda tmp: tmp.write_text(text))


class FolderBusy(ValueError):
    """Another process holds the lock of a folder (`folder_lock`)."""


def folder_lock(folder: str | Path):
    """An exclusive advisory lock (`flock`) on the folder itself, held until the returned descriptor is closed
    (`os.close`; the kernel releases it when the process dies). Nothing is written into the folder. Raises
    FolderBusy when another process holds it."""
    import fcntl

    fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        raise FolderBusy(str(folder)) from None
    return fd
