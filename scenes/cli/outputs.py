"""What a command may write: `check_output_folder` refuses an output folder that cannot be written before any
work (`make_output_folder` then creates it); `output_lock` holds an output folder for the length of a run (one
writer per folder; never inside what the run reads); `claim_outputs` is the one rule of `--overwrite` (see their
docstrings and docs/development.md, "Outputs and --overwrite").
"""
from __future__ import annotations

import os
import threading
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable

from scenes.cli.errors import UsageError
from scenes.files import is_within, mount_of, mount_points, mounts_within, read_json


def _tell_supervisor(path: str | os.PathLike) -> None:
    """Tell the supervising process of a held folder (`scenes.cli.supervise.HELD_FILE`, a pipe): after a stop it
    removes the stopped work's temporaries there."""
    from scenes.cli.supervise import CHILD, HELD_FILE

    # The descriptor is this process's only where the supervisor started it (a step of a pipeline inherits the
    # variables, not the pipe: there the number is some other file)
    if os.environ.get(CHILD) != str(os.getppid()) or not os.environ.get(HELD_FILE, "").isdigit():
        return
    try:
        os.write(int(os.environ[HELD_FILE]), os.fsencode(os.path.abspath(path) + "\n"))
    except OSError:  # the pipe is gone or full: nothing more to tell
        pass


def _held_by_another(folder: str | os.PathLike) -> bool:
    """Whether another run holds `folder` (its lock, `output_lock`, as wildgen.make's while it renders). A shared
    probe, released at once: readers started together never refuse each other, a writer's lock refuses them. A
    path that is not a folder, or one this process may not open, is not held as far as can be told."""
    import fcntl

    if not os.path.isdir(folder):
        return False
    try:
        fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    finally:
        os.close(fd)
    return False


def check_not_being_written(path: str | os.PathLike, flag: str) -> None:
    """Refuse to read a folder or file another run is writing (`_held_by_another`: it holds the folder, or a folder
    above it, as a run holds its --out): what it holds now is a part of what it will hold (a training run's
    checkpoint of step 100 of 1000, a predict's first maps). Folders this process or the commands that started it
    hold are ours (`HELD_ENV`: a session's steps read what its earlier steps wrote)."""
    if not path or not os.path.lexists(path):
        return
    real = os.path.realpath(path)
    if (here := _holder_from(real)) is not None:
        within = "" if here == real else f" (it lies in {here!r}, which that run holds)"
        raise UsageError(f"{flag}: {str(path)!r} is being written by another run{within}; wait until it has "
                         "finished, then run this again")
    if (below := _holder_below(real)) is not None:  # a part of it (one object of a dataset) is still being written
        raise UsageError(f"{flag}: {below!r}, inside {str(path)!r}, is being written by another run; wait until it "
                         "has finished, then run this again")


def _ours() -> set[str]:
    """The folders this process or the commands that started it hold (`HELD_ENV`): never another run's."""
    return set(_HELD) | set(filter(None, os.environ.get(HELD_ENV, "").split(os.pathsep)))


def _holder_below(folder: str, limit: int = 20000) -> str | None:
    """The first folder strictly inside `folder` (links not followed) that another run holds, None when none does
    (or `folder` is not a folder); folders ours (`HELD_ENV`) are not counted. At most `limit` folders are probed:
    a run's folders are object folders, a few levels down, never more."""
    if not os.path.isdir(folder):
        return None
    ours = _ours()
    seen = 0
    for top, dirs, _ in os.walk(folder, followlinks=False):
        for name in dirs:
            sub = os.path.join(top, name)
            seen += 1
            if seen > limit:
                return None
            if sub not in ours and not os.path.islink(sub) and _held_by_another(sub):
                return sub
    return None


def _holder_from(folder: str) -> str | None:
    """The first of `folder` and the folders above it that another run holds (`_held_by_another`), None when none
    does; folders this process or the commands that started it hold are ours (`HELD_ENV`)."""
    ours = _ours()
    while True:
        if folder not in ours and _held_by_another(folder):
            return folder
        parent = os.path.dirname(folder)
        if parent == folder:
            return None
        folder = parent


def check_output_folder(path: str | os.PathLike, flag: str = "--out") -> str | os.PathLike:
    """Refuse an output folder that cannot be written, before any work: an existing file, a path under a
    file, or a folder (or the nearest existing parent of a new one) this process may not write. Creates
    nothing. Returns `path`."""
    if not str(path).strip():  # '' would be the current folder: never meant
        raise UsageError(f"{flag}: got an empty value, expected a folder")
    if os.path.dirname(os.path.realpath(path)) == os.path.realpath(path):  # its files would mix with the system's
        raise UsageError(f"{flag}: {str(path)!r} is the file system's root; expected a folder of its own (e.g. "
                         f"{os.path.join(str(path), 'out')!r})")
    target = os.path.abspath(path)
    long = next((part for part in target.split(os.sep) if len(os.fsencode(part)) > 255), None)
    if long is not None:  # the system refuses such a name only when it is written, naming no flag
        raise UsageError(f"{flag}: {str(path)[:80]!r}... holds a name of {len(os.fsencode(long))} bytes; expected "
                         "folder names of at most 255 bytes (the file system's limit)")
    if len(os.fsencode(target)) >= 4096 - 256:  # room left for the files inside (PATH_MAX is 4096 bytes)
        raise UsageError(f"{flag}: {str(path)[:80]!r}... is a path of {len(os.fsencode(target))} bytes; expected at "
                         f"most {4096 - 257} bytes (the system's limit on a whole path, less room for the files "
                         "inside)")
    if os.path.islink(target) and not os.path.exists(target):  # dangling, or a loop of links
        raise UsageError(f"{flag}: {str(path)!r} is a link to {os.readlink(target)!r}, which leads to no folder (it "
                         "is missing, or the links loop); expected a folder")
    if os.path.exists(target):
        if not os.path.isdir(target):
            import stat

            mode = os.stat(target).st_mode
            kind = ("an existing file" if stat.S_ISREG(mode) else "a pipe (FIFO)" if stat.S_ISFIFO(mode) else
                    "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode) else "a socket or other special file")
            raise UsageError(f"{flag}: {str(path)!r} is {kind}, expected a folder")
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


@dataclass
class _Held:
    """An output folder this process holds (`output_lock`)."""

    folder: str  # absolute, as given (the claims below it are built from it)
    flag: str
    inputs: list[tuple[str, str, str]]  # (flag, as given, real path) of what the run reads


_HELD: dict[str, _Held] = {}
"""The output folders this process holds, by real path."""
_HELD_LOCK = threading.Lock()


def busy_message(folder: str | os.PathLike, flag: str = "--out") -> str:
    """The one line of a folder another run holds (`scenes.files.FolderBusy`)."""
    return (f"{flag}: another run holds the folder {str(folder)!r} (it is writing there; one writer per output "
            f"folder): wait for it to end, or use another {flag}")


def check_apart(path: str | os.PathLike, inputs: Mapping[str, str | os.PathLike | None], flag: str = "--out") -> None:
    """Refuse an output folder that is one of the folders the run reads (`inputs`: flag -> path; None skipped),
    lies inside one, or leads into one through a link: a run never writes into its own input (a rerun would read
    its outputs as input, and --overwrite would replace the input's own files). An input that is a file counts
    its folder too where the output would be that very folder (a surface written into the predict folder its normal
    map lies in would mix with predict's files); a folder inside it is fine. Creates nothing."""
    real = os.path.realpath(path)
    for in_flag, given in inputs.items():
        if given is None:
            continue
        if not str(given).strip():  # '' would be the current folder: never meant
            raise UsageError(f"{in_flag}: got an empty value, expected a path")
        folder = os.path.realpath(given)
        # a bench names each of several inputs by its flag and path ('--suite DIR'): the path is said once
        named = in_flag if in_flag.endswith(f" {given}") else f"{in_flag} {str(given)!r}"
        in_flag = in_flag.split(" ", 1)[0]
        if os.path.isfile(folder) and (real == os.path.dirname(folder) or mount_of(real, os.path.dirname(folder))
                                       == real):
            raise UsageError(f"{flag}: {str(path)!r} is the folder {named} lies in; expected "
                             f"another folder (e.g. {os.path.join(str(path), 'out')!r}): a command never writes "
                             "beside what it reads")
        inside = real == folder or real.startswith(folder.rstrip(os.sep) + os.sep)  # is_within by the path alone
        alias = None if inside else mount_of(real, folder)  # its second half, said apart
        if alias is not None:  # the same folder reached by another path (a bind mount): no link tells it
            where = "is" if alias == real else f"lies inside {alias!r}, which is"
            raise UsageError(f"{flag}: {str(path)!r} {where} {named} under another name (the same "
                             f"folder, mounted twice); expected a folder outside {in_flag}: a command never writes "
                             "into what it reads")
        if not inside:
            continue
        where = ("is a link to" if os.path.islink(path) else "is") if real == folder else (
            "is a link into" if os.path.islink(path) else "lies inside")
        raise UsageError(f"{flag}: {str(path)!r} {where} {named}; expected a folder outside {in_flag}: a command "
                         "never writes into what it reads")


HELD_ENV = "PS_TOOLKIT_HELD_FOLDERS"
"""The folders this process and the processes that started it hold (real paths, os.pathsep-separated): a step of a
command writes inside its parent's folder, where any other run is refused (`check_no_holder_above`)."""


def check_replaceable(folder: str | os.PathLike, flag: str = "--out", owner: str = "this command",
                      kept: Iterable[str | os.PathLike] = ()) -> None:
    """A folder whose earlier contents a command replaces or adds to (a dataset's --overwrite or --resume) must hold
    no mount point (a file or folder mounted inside it: removing or renaming it fails mid-way, EBUSY, with part of
    the earlier contents gone), but within `kept` (what the run leaves as it is: a resumed dataset's finished
    objects). UsageError naming it, before the first write."""
    inside = [p for p in mounts_within(folder) if p != os.path.realpath(folder)
              and not any(mounts_within(k, [p]) for k in kept)]
    if inside:
        raise UsageError(f"{flag}: {str(folder)!r} holds the mount point {inside[0]!r}, where {owner} writes; it is "
                         f"never replaced: unmount it, or use another {flag}")


def check_no_holder_above(path: str | os.PathLike, flag: str = "--out") -> None:
    """Refuse an output folder inside a folder another run holds (`output_lock`, `wildgen.make`'s lock): that run
    writes there too, and the two runs' files would mix (a predict into p/00001 while another writes p). A folder
    this process or the commands that started it hold is ours (`HELD_ENV`). Probes each existing folder above with
    a shared lock, released at once; creates nothing."""
    if (above := _holder_from(os.path.dirname(os.path.realpath(path)))) is not None:
        raise UsageError(f"{flag}: {str(path)!r} lies inside {above!r}, which another run holds (it is writing "
                         f"there; one writer per output folder): wait for it to end, or use another {flag}")


@contextmanager
def _held_in_env(real: str) -> Iterator[None]:
    """`real` added to `HELD_ENV` for this block (the steps this process starts inherit it)."""
    before = os.environ.get(HELD_ENV)
    os.environ[HELD_ENV] = os.pathsep.join(filter(None, [before, real]))
    try:
        yield
    finally:
        if before is None:
            os.environ.pop(HELD_ENV, None)
        else:
            os.environ[HELD_ENV] = before


@contextmanager
def output_lock(path: str | os.PathLike, flag: str = "--out",
                inputs: Mapping[str, str | os.PathLike | None] | None = None) -> Iterator[Path]:
    """Hold the output folder `path` for the length of a run: one writer per output folder.

    Before anything is created: `check_apart` (not inside `inputs`) and `check_output_folder`. Then the folder
    is created (with its parents) and locked with `scenes.files.folder_lock`, the lock `wildgen.make` and
    `wildgen.export` take: a second run into it, by any command, is refused in one line naming `flag`
    (`busy_message`); the kernel releases the lock when a process dies. Folders created here that are still
    empty when the block ends are removed (a refused run leaves nothing behind). The lock is not re-entrant:
    taken twice for one folder, in one process too, the second is refused.

    While it is held, `claim_outputs` also refuses an output below it reached through a link (a link inside
    the folder is never followed out of it) and an output inside one of `inputs`."""
    from scenes.files import FolderBusy, folder_lock

    inputs = dict(inputs or {})
    for in_flag, given in inputs.items():  # an input another run is writing is read only once it is whole
        if given is not None:
            check_not_being_written(given, in_flag)
    check_apart(path, inputs, flag)
    check_output_folder(path, flag)
    check_no_holder_above(path, flag)
    if (below := _holder_below(os.path.realpath(path))) is not None:  # its files would mix with the other run's
        raise UsageError(f"{flag}: {below!r}, inside {str(path)!r}, is held by another run (it is writing there; "
                         f"one writer per output folder): wait for it to end, or use another {flag}")
    created = []
    parent = os.path.abspath(path)
    while not os.path.exists(parent):
        created.append(parent)
        parent = os.path.dirname(parent)
    try:
        make_output_folder(path, flag)
        try:
            fd = folder_lock(path)
        except FolderBusy:
            raise UsageError(busy_message(path, flag)) from None
        real = os.path.realpath(path)
        _tell_supervisor(path)
        record = _Held(os.path.abspath(path), flag,
                       [(f, str(g), os.path.realpath(g)) for f, g in inputs.items() if g is not None])
        with _HELD_LOCK:
            _HELD[real] = record
        try:
            with _held_in_env(real):
                yield Path(path)
        finally:
            with _HELD_LOCK:
                _HELD.pop(real, None)
            os.close(fd)
    finally:
        for folder in created:  # deepest first
            try:
                os.rmdir(folder)
            except OSError:  # not empty (the run wrote there), or gone
                break


def check_step_folder(path: str | os.PathLike, owner: str) -> None:
    """A folder that a step of this command (another toolkit command, run as a subprocess) will write: within the
    output folders this process holds (`output_lock`), neither it nor a folder on the way to it may be a link (the
    step would follow it out of the held folder), nor may it lie inside what the run reads."""
    _check_held(Path(path), owner, folder=True)


def _check_held(path: Path, owner: str, folder: bool = False, points: list[str] | None = None) -> None:
    """Within the output folders this process holds (`output_lock`): refuse a link or a mount point on the way from
    the folder to `path` (a link would lead the write out of the folder; a mounted folder is another file system,
    whose files a run replaces only part-way where it fails; `path` itself too), and `path` inside what the run
    reads. `points`: the mount table, when the caller read it already."""
    target = os.path.abspath(path)
    with _HELD_LOCK:
        held = list(_HELD.values())
    for h in held:
        if target.startswith(h.folder.rstrip(os.sep) + os.sep):
            here = h.folder
            parts = Path(target[len(h.folder.rstrip(os.sep)) + 1:]).parts
            inside = mounts_within(h.folder, points)
            for i, part in enumerate(parts):
                here = os.path.join(here, part)
                if (folder or i < len(parts) - 1) and os.path.islink(here):
                    raise UsageError(f"{h.flag}: {here!r} is a link, where {owner} writes a folder; a link inside "
                                     f"{h.flag} is never followed: move it away or use another {h.flag}")
                if os.path.realpath(here) in inside:
                    raise UsageError(f"{h.flag}: {here!r} is a mount point inside {h.flag}, where {owner} writes; "
                                     f"nothing is written into it: unmount it, or use another {h.flag}")
        real = os.path.realpath(target)
        for in_flag, given, folder in h.inputs:
            if is_within(real, folder):
                raise UsageError(f"{h.flag}: {str(path)!r} lies inside {in_flag} {given!r}, where {owner} would write; "
                                 f"a command never writes into what it reads: use another {h.flag}")
            if is_within(folder, real):  # an output replaced whole (a folder, or the very file) holding an input
                raise UsageError(f"{in_flag}: {given!r} lies in {str(path)!r}, which {owner} writes (replacing what "
                                 f"is there); a command never writes over what it reads: move it, or use another "
                                 f"{h.flag}")


def holds_keys(path: Path, keys: tuple[str, ...]) -> bool:
    """Whether `path` is a JSON object holding every key of `keys`."""
    try:
        data = read_json(path)
    except (OSError, ValueError, RecursionError):  # unreadable, not JSON, nested past the parser: not a report
        return False
    return isinstance(data, dict) and all(k in data for k in keys)


def listed_names(record: str | os.PathLike, key: str) -> set[str]:
    """The file names an earlier run listed under `key` of its JSON record (preview.json's `sheets`, a check's
    `renders`, the surface's `meshes`); none when there is no readable record. A name read from a file is untrusted:
    only plain names (no folder part, not '.' or '..') are taken."""
    try:
        listed = read_json(record).get(key, [])
    except (OSError, ValueError, AttributeError):
        return set()
    return {n for n in listed if isinstance(n, str) and n not in ("", ".", "..") and os.path.basename(n) == n
            and "\\" not in n} if isinstance(listed, list) else set()


def check_listed(targets: Iterable[str | os.PathLike], record: str | os.PathLike, key: str, owner: str,
                 flag: str = "--out") -> set[str]:
    """Refuse an existing output whose name the earlier run's `record` does not list under `key`: a user's file
    under a name the command writes, beside the command's own record, is never replaced, even with --overwrite.
    Returns the names listed (the earlier run's files, which this run replaces)."""
    listed = listed_names(record, key)
    foreign = next((Path(t) for t in targets if os.path.lexists(t) and Path(t).name not in listed), None)
    if foreign is not None:
        raise UsageError(f"{flag}: {str(foreign)!r} was not written by {owner} (its record {str(record)!r} lists no "
                         f"such file); it is never replaced, even with --overwrite: move it away or use another {flag}")
    return listed


def _check_name_lengths(path: Path, above: Path | None, flag: str, owner: str) -> None:
    """Refuse an output whose file or folder names (those not made yet) are longer than the file system allows (a
    name derived from a long input name, e.g. capture's work/<name>.data): said before any work, not as an
    ENAMETOOLONG once the work is done."""
    try:
        limit = os.pathconf(above if above is not None else ".", "PC_NAME_MAX")
    except (OSError, ValueError):
        return
    new = path.relative_to(above).parts if above is not None and path.is_relative_to(above) else path.parts
    if long := next((n for n in new if len(os.fsencode(n)) > limit), None):
        raise UsageError(f"{flag}: {owner} would write {long[:60]!r}{'...' if len(long) > 60 else ''} (in "
                         f"{str(path.parent)[:80]!r}), a name of {len(os.fsencode(long))} bytes, longer than the "
                         f"{limit} a name may have on that file system; nothing was written: use shorter names")


def claim_outputs(paths: Iterable[str | os.PathLike], overwrite: bool, flag: str = "--out", owner: str = "this command",
                  marker: str | os.PathLike | None = None, folders: bool = False, resume: str = "",
                  signed: dict[str | os.PathLike, tuple[str, ...]] | None = None) -> list[Path]:
    """The one rule of every command that writes, applied before any work to the outputs it is about to write.

    - An output that does not exist yet is written.
    - An output that exists is an earlier run's: without `overwrite` the command refuses (UsageError naming it
      and --overwrite); with `overwrite` it is replaced (a file atomically, by its writer).
    - Never replaced, even with `overwrite`: anything of another kind under an output's name (a folder or a
      link where a file is written, a file where a folder is), and, when `marker` is given (the file that marks
      a folder as a command's own, e.g. predict.json or manifest.json), any output that exists while the
      marker does not: those are not the command's files.

    - Never replaced either: a JSON report among `signed` (path -> the keys every report of the command holds)
      that exists without those keys, e.g. a report.json of another command or the user's own.

    `folders`: the outputs are folders (e.g. object folders) rather than files. `resume`: how the command
    continues an earlier run instead, for the message (e.g. "--resume to continue it"). Files that are not
    among `paths` are never touched. Returns the outputs that exist (those to be replaced).

    Under `output_lock`, an output reached through a link inside the locked folder, or lying inside one of the
    run's inputs, is refused too.
    """
    paths = [Path(p) for p in paths]
    table = mount_points() if paths else []
    for p in paths:
        _check_held(p, owner, points=table)
        above = next((a for a in p.parents if os.path.lexists(a)), None)  # the nearest thing on the way that exists
        if above is not None and not above.is_dir():
            raise UsageError(f"{flag}: {str(above)!r} is {'a link' if above.is_symlink() else 'a file'}, where "
                             f"{owner} writes a folder (for {p.name}); it is never replaced: move it away or use "
                             f"another {flag}")
        if above is not None and not os.access(above, os.W_OK | os.X_OK):  # read-only (a mount) or not the user's
            raise UsageError(f"{flag}: the folder {str(above)!r}, where {owner} writes {p.name}, is not writable; "
                             "nothing was written")
        _check_name_lengths(p, above, flag, owner)
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
        if (held := mounts_within(p, table)) or (not folders and not os.access(p, os.W_OK)):  # before the first write
            what = f"holds the mount point {held[0]!r}" if held and held[0] != os.path.realpath(p) else \
                "is a mount point" if held else "is read-only"
            raise UsageError(f"{flag}: {str(p)!r} {what}, where {owner} writes {want}; it is never replaced: "
                             f"{'unmount it' if held else 'make it writable'}, or use another {flag}")
    if existing and marker is not None and not os.path.lexists(marker):
        more = f" (and {len(existing) - 1} more)" if len(existing) > 1 else ""
        raise UsageError(f"{flag}: {str(existing[0])!r}{more} was not written by {owner} (no {Path(marker).name} in "
                         f"{str(Path(marker).parent)!r}); it is never replaced, even with --overwrite: move it away or "
                         f"use another {flag}")
    for report, keys in (signed or {}).items():
        if os.path.lexists(report) and not holds_keys(Path(report), keys):
            raise UsageError(f"{flag}: {str(report)!r} was not written by {owner} (it lacks the keys "
                             f"{', '.join(keys)} of its reports); it is never replaced, even with --overwrite: move "
                             f"it away or use another {flag}")
    if existing and not overwrite:
        more = f" (and {len(existing) - 1} more)" if len(existing) > 1 else ""
        also = f", {resume}" if resume else ""
        raise UsageError(f"{flag}: {str(existing[0])!r}{more} exists, from an earlier run; pass --overwrite to "
                         f"replace it{also}, or use another {flag}")
    return existing
