"""Writing files so that a reader never sees half of one (write to a temporary name, then rename), and their
SHA-256 checksums: used by object folders, shards, model checkpoints and reports alike; and the one JSON writer
(`write_json`: NumPy values as plain ones, non-finite numbers as null, written atomically); and what native
decoders write to the process's standard error about a file they read (`caught_stderr`: libjpeg through OpenCV,
'Premature end of JPEG file'; LibRaw, 'Unexpected end of file'), caught so that a refusal stays one line and a
decoder's complaint can be told from its silence.
"""
from __future__ import annotations

import errno
import math
import os
import re
import sys
import tempfile
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


def sha256_file(path: str | Path) -> str:
    """Hex SHA-256 of a file, read in 1 MiB chunks (the checksums of manifests and shard indexes)."""
    import hashlib

    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def not_a_file(path: str | os.PathLike) -> str:
    """Why `path` cannot be read as a file, as the words after its name ('' for a regular file or a link to one):
    'does not exist', 'is a link to T, which does not exist', 'is a folder' or 'is not a regular file (a device, a
    pipe or a socket)'. One rule, so that a device or a pipe is never reported as missing (or read forever)."""
    p = Path(path)
    if p.is_file():
        return ""
    if p.is_symlink() and not p.exists():
        return f"is a link to {os.readlink(p)}, which does not exist"
    if p.is_dir():
        return "is a folder; expected a file"
    if p.exists():
        return "is not a regular file (a device, a pipe or a socket); expected a file"
    return "does not exist"


def shown_name(name: str | os.PathLike) -> str:
    """A name as text for messages and records: bytes that are not UTF-8 (kept by Python as lone surrogates) shown
    as U+FFFD, so that printing or a JSON record never fails on them."""
    return os.fspath(name).encode("utf-8", "surrogateescape").decode("utf-8", "replace")


def text_name_problem(path: str | os.PathLike) -> str | None:
    """Why `path` cannot be used as a name here, or None: the first part of it whose bytes are not UTF-8 text
    (a Latin-1 'é' written by an old camera or archive). The image, EXR and page writers take names as text only
    (OpenEXR and OpenCV refuse such a name or crash on it), so the one rule is to refuse it up front; the remedy is
    renaming, whatever the locale."""
    for part in Path(path).parts:
        bad = next((ch for ch in part if "\udc80" <= ch <= "\udcff"), None)
        if bad is not None:
            return (f"the name {shown_name(part)!r} is not UTF-8 text (byte 0x{ord(bad) - 0xDC00:02X}); expected names "
                    "that are text: rename it (e.g. with convmv, or by hand)")
    return None


def check_text_name(path: str | os.PathLike, flag: str) -> None:
    """A ValueError naming `flag` and the path when a part of it is not UTF-8 text (`text_name_problem`)."""
    problem = text_name_problem(path)
    if problem is not None:
        raise ValueError(f"{flag}: {shown_name(path)!r}: {problem}")


def is_within(path: str | os.PathLike, folder: str | os.PathLike) -> bool:
    """Whether `path` is `folder` or lies inside it, links followed and a second mount of `folder` seen through
    (the one rule of 'inside' for untrusted links and output folders)."""
    real, root = os.path.realpath(path), os.path.realpath(folder)
    return real == root or real.startswith(root.rstrip(os.sep) + os.sep) or mount_of(real, root) is not None


def mount_of(path: str | os.PathLike, folder: str | os.PathLike) -> str | None:
    """The existing folder at or above `path` that is `folder` itself under another path (the same device and
    inode: a bind mount of it), None when there is none. No path comparison can tell such a second name, and no
    link is involved."""
    if not os.path.isdir(folder):
        return None
    target = os.stat(folder)
    here = os.path.realpath(path)
    while True:
        try:
            st = os.stat(here)
        except OSError:
            st = None
        if st is not None and (st.st_dev, st.st_ino) == (target.st_dev, target.st_ino):
            return here
        parent = os.path.dirname(here)
        if parent == here:
            return None
        here = parent


def mount_points() -> list[str]:
    """This process's mount points (/proc/self/mountinfo; [] where it cannot be read)."""
    try:
        with open("/proc/self/mountinfo", encoding="utf-8", errors="replace") as f:
            points = [line.split()[4] for line in f if len(line.split()) > 4]
    except OSError:
        return []
    return [re.sub(r"\\([0-7]{3})", lambda m: chr(int(m[1], 8)), p) for p in points]  # '\040' is a space


def mounts_within(path: str | os.PathLike, points: list[str] | None = None) -> list[str]:
    """The mount points (of `points`, default `mount_points()`) at or under `path`: a file or folder that is one,
    or a folder holding one, cannot be replaced or removed (EBUSY), whatever its permissions say."""
    root = os.path.realpath(path)
    return [p for p in (mount_points() if points is None else points)
            if p == root or p.startswith(root.rstrip(os.sep) + os.sep)]


def links_out_of(path: str | os.PathLike, folder: str | os.PathLike) -> bool:
    """Whether `path` is a link that leads outside `folder` (an untrusted dataset's link to any file of the
    machine)."""
    return os.path.islink(path) and not is_within(path, folder)


def read_text_file(path: str | os.PathLike) -> str:
    """The text of a regular file (UTF-8). A pipe, a device or a socket under the name is refused without being
    waited on (opened non-blocking, checked before any read), an OSError saying what it is: a record read from
    an untrusted folder never hangs a command. Missing files raise as `open` does; bytes that are not UTF-8 raise
    `NotUTF8`, naming the file."""
    import stat

    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    try:
        if not stat.S_ISREG((st := os.fstat(fd)).st_mode):
            raise OSError(f"{str(path)!r} is not a regular file (a device, a pipe or a socket); expected a file")
        from scenes.checks import check_read_whole

        check_read_whole(path, repr(str(path)), st.st_size)
        os.set_blocking(fd, True)
        with os.fdopen(fd, "rb", closefd=False) as f:
            data = f.read()
    finally:
        os.close(fd)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise NotUTF8(path, exc) from None


class NotUTF8(UnicodeDecodeError):
    """A file read as text that is not UTF-8 (a Windows-1252 'é' in a record a user saved), said with the file and
    the remedy; a UnicodeDecodeError still, so that readers that name their flag go on catching it."""

    def __init__(self, path: str | os.PathLike, exc: UnicodeDecodeError):
        super().__init__(exc.encoding, exc.object, exc.start, exc.end, exc.reason)
        self.path = path

    def __str__(self) -> str:
        return (f"{shown_name(self.path)!r} is not UTF-8 text (byte 0x{self.object[self.start]:02X} at offset "
                f"{self.start}); expected a file saved as UTF-8 (save it again in that encoding)")


def read_json(path: str | os.PathLike):
    """A JSON file read as `read_text_file` reads (never waiting on a pipe): the errors of `read_text_file` and of
    `json.loads`; nesting deeper than the decoder goes, or an integer of more digits than Python converts, is a
    ValueError naming the file."""
    return parse_json(path, read_text_file(path))


def parse_json(path: str | os.PathLike, text: str, **hooks):
    """`text` (of file `path`, or whatever names it in errors) parsed as `read_json` parses a file: each key once,
    each string text, nesting within what Python reads, integers within 64 bits, every number finite (NaN,
    Infinity and 1e400 refused), every refusal a ValueError naming `path`."""
    import json
    import sys

    made = hooks.pop("object_hook", dict)

    def once(pairs: list) -> object:  # a key given twice: Python keeps the last, other readers the first
        keys = [k for k, _ in pairs]
        if len(set(keys)) < len(keys):
            twice = next(k for k in keys if keys.count(k) > 1)
            raise ValueError(f"{str(path)!r}: holds the key {shown_name(twice)[:60]!r} twice in one object; expected "
                             "each key once (an edit merged by hand?)")
        return made(dict(pairs))

    def whole(digits: str) -> int:  # no record of ours holds an integer beyond 64 bits; a bigger one overflows
        number = int(digits)  # numpy, torch or a float far from here, in a traceback that names no file
        if not -(2**63) <= number < 2**63:
            raise ValueError(f"{str(path)!r}: holds the integer {digits[:24]}{'...' if len(digits) > 24 else ''} "
                             f"({len(digits.lstrip('-'))} digits), beyond 64 bits; expected a record as this toolkit "
                             "writes it")
        return number

    hooks.setdefault("parse_int", whole)
    try:
        value = json.loads(text, object_pairs_hook=once, **hooks)
    except RecursionError:  # an untrusted file must not end in a traceback
        raise ValueError(f"{str(path)!r}: JSON nested too deeply (over {sys.getrecursionlimit()} levels); expected "
                         "a record as this toolkit writes it") from None
    except json.JSONDecodeError:
        raise
    except ValueError as exc:  # e.g. an integer of 5000 digits (Python's limit on converting one)
        if str(path) in str(exc):
            raise
        raise ValueError(f"{str(path)!r}: {exc}") from None
    return _text_only(value, path)


_LONE_SURROGATE = re.compile("[\ud800-\udfff]")


def _text_only(value, path: str | os.PathLike):
    """`value` (parsed JSON) when every number in it is finite (none of our writers writes NaN or Infinity) and every
    string and key text; a ValueError naming the file and the key when a number is not finite, or a string holds a
    lone surrogate (JSON's escape \\udce9 is valid syntax but half of a character: no file, page or terminal can
    write it, so it would fail far from here)."""
    stack = [(value, "")]
    while stack:
        item, key = stack.pop()
        if isinstance(item, dict):
            stack.extend((k, key) for k in item.keys())
            stack.extend((v, f"{key}.{k}" if key else str(k)) for k, v in item.items())
        elif isinstance(item, list):
            stack.extend((v, f"{key}[{i}]") for i, v in enumerate(item))
        elif isinstance(item, float) and not math.isfinite(item):  # NaN, Infinity, 1e400: our writers refuse them
            raise ValueError(f"{shown_name(path)!r}: holds {shown_name(key)[:60] or 'the number'} = {item}, not a "
                             "finite number; expected a record as this toolkit writes it")
        elif isinstance(item, str) and _LONE_SURROGATE.search(item):
            half = ord(_LONE_SURROGATE.search(item)[0])
            raise ValueError(f"{shown_name(path)!r}: holds the text {shown_name(item)[:60]!r}, whose escape "
                             f"\\u{half:04x} is half of a character, not text; expected text (write the character "
                             "itself, or a whole escape pair)")
    return value


def read_figures(path: str | os.PathLike, **hooks):
    """A JSON record of figures (a bench's output, a model card) as `read_json` reads it, stricter: NaN, Infinity, a
    number beyond a float's range (1e999) and an integer of more than 15 digits are a ValueError naming the file (each
    would print as a figure or overflow on the way), and the file is never read through a link. `hooks`: more
    keyword arguments of `json.loads` (e.g. object_hook)."""
    import math

    def refuse(text: str):
        raise ValueError(f"{str(path)!r}: holds the number {text[:40]}; expected finite figures")

    def number(text: str) -> float:
        value = float(text)
        return value if math.isfinite(value) else refuse(text)

    def whole(text: str) -> int:
        return int(text) if len(text.lstrip("-")) <= 15 else refuse(text)

    if os.path.islink(path):
        raise ValueError(f"{str(path)!r} is a link (to {os.readlink(path)!r}); a record is read from its own file "
                         "only")
    return parse_json(path, read_text_file(path), parse_constant=refuse, parse_float=number, parse_int=whole, **hooks)


class RecordError(ValueError):
    """A JSON record another run wrote (a bench's output, a training log, a model card) that is not of the shape
    its reader expects: one line naming the file (`reading_record`)."""


@contextmanager
def reading_record(path: str | os.PathLike, what: str, fix: str = "restore it, or run what writes it again",
                   flag: str = "") -> Iterator[None]:
    """Around the code that reads a record by its keys: a record of another shape (a number where rows belong, a
    text where a figure, a list where an object, a missing key, a zero divisor, nesting too deep) ends in one
    `RecordError` naming the file (after the `flag` that named it, if any), `what` it should be and the way out
    (`fix`), never in the reading code's own TypeError or KeyError. An error that already names the file passes as
    it is. Files are untrusted: anybody may have edited one."""
    said = f"{flag}: {str(path)!r}" if flag else repr(str(path))
    try:
        yield
    except RecordError:
        raise
    except OSError as exc:  # unreadable (a pipe, a folder, no permission): said with the file
        raise RecordError(f"{said}: cannot be read ({exc.strerror or exc}); {fix}") from None
    except (KeyError, IndexError, TypeError, AttributeError, ValueError, ArithmeticError, RecursionError) as exc:
        if str(path) in str(exc):  # already said with the file: the flag that named it goes first
            if not flag or str(exc).startswith(f"{flag}:"):
                raise
            raise RecordError(f"{flag}: {exc}") from None
        if isinstance(exc, KeyError) and exc.args:
            why = f"no {exc.args[0]!r}"
        elif isinstance(exc, RecursionError):
            why = "nested too deeply"
        else:
            lines = str(exc).strip().splitlines()
            why = f"{type(exc).__name__}: {lines[0][:160]}" if lines else type(exc).__name__
        raise RecordError(f"{said}: not {what} as this toolkit writes it ({why}); {fix}") from None


def _temporary(path: Path) -> Path:
    """A hidden name beside `path` with the same extension (image writers choose the format by it); the stem is
    cut where the name would pass the file system's 255 bytes (the real name itself may be that long)."""
    tail = f".tmp{os.getpid()}{path.suffix}"
    room = 255 - 1 - len(tail.encode())
    stem = path.stem.encode()[:room].decode(errors="ignore")
    return path.with_name(f".{stem}{tail}")


_TEMPORARY = re.compile(r"^\.(?P<stem>.+)\.tmp(?P<pid>\d+)(?P<suffix>(\.[^.]*)?)$")


def temporary_target(name: str) -> str | None:
    """The file name whose temporary (`atomic_write`: `.<stem>.tmp<pid><suffix>`) `name` is, or None: what a
    killed writer left behind, which an --overwrite of the same outputs removes."""
    m = _TEMPORARY.match(name)
    return None if m is None else m["stem"] + m["suffix"]


def temporary_writer(name: str) -> int | None:
    """The pid of the process whose temporary (`atomic_write`) `name` is, or None for another name."""
    m = _TEMPORARY.match(name)
    return None if m is None else int(m["pid"])


_TEMPORARY_FOLDER = re.compile(r"^\.tmp-.+\.(?P<pid>\d+)$")
"""An object folder being written (`wildgen.writer.TMP_PREFIX`, then the folder's name and its writer's pid)."""


def temporary_folder_writer(name: str) -> int | None:
    """The pid of the process whose temporary object folder `name` is, or None for another name."""
    m = _TEMPORARY_FOLDER.match(name)
    return None if m is None else int(m["pid"])


def writer_gone(pid: int | None) -> bool:
    """True when `pid` names a writer that no longer runs, so that a temporary bearing it is a leftover a later
    run may remove. A running pid (this process, init's 1, anybody's) never is: with the folder's lock held no other
    run of ours writes there, so a temporary of a live pid is somebody else's file that only looks like ours."""
    if pid is None or pid <= 1 or pid == os.getpid():
        return False
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except (OverflowError, OSError):  # alive under another user (EPERM), or not a pid at all
        return False
    return False


def atomic_write(path: str | Path, write) -> None:
    """Call `write(tmp)` on a temporary name beside `path`, then rename it to `path`: a kill or a full disk
    never leaves a truncated file under the real name (the temporary one is removed on failure)."""
    path = Path(path)
    tmp = _temporary(path)
    try:
        write(tmp)
        os.replace(tmp, path)
    except OSError as exc:
        _discard(tmp)
        if str(path) in str(exc) and str(tmp) not in str(exc):
            raise
        why = f"{exc.strerror or exc}{' (a mount point?)' if exc.errno == errno.EBUSY else ''}"
        raise OSError(exc.errno, f"could not write {str(path)!r}: {why}") from exc
    except BaseException:
        _discard(tmp)
        raise


def _discard(tmp: Path) -> None:
    """Remove a temporary that may not exist; on a read-only file system unlinking even a missing name fails
    (EROFS), which must not replace the error that names the real file."""
    try:
        tmp.unlink(missing_ok=True)
    except OSError:
        pass


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


def to_plain(value, *, strict: bool = False, where: str = ""):
    """`value` as plain JSON values: dicts (keys as str, int, float, bool or None, like `json`), lists (from
    lists and tuples), str, int, float, bool and None. NumPy scalars and arrays become Python numbers and lists,
    Paths strings, dataclasses dicts; a non-finite float (a measurement that could not be made) becomes None,
    or with `strict` raises ValueError naming where it is (`where` prefixes that path: "scene.json").
    Anything else raises TypeError, also naming where."""
    import dataclasses
    import math

    import numpy as np

    if value is None or isinstance(value, (str, bool)):
        return value
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        if math.isfinite(value):
            return float(value)
        if strict:
            raise ValueError(f"{where or 'value'}: got {float(value)}, JSON has no non-finite numbers")
        return None
    if isinstance(value, dict):
        return {_plain_key(k, where): to_plain(v, strict=strict, where=f"{where}.{k}" if where else str(k))
                for k, v in value.items()}
    if isinstance(value, np.ndarray):
        value = value.tolist()
    if isinstance(value, (list, tuple)):
        return [to_plain(v, strict=strict, where=f"{where}[{i}]") for i, v in enumerate(value)]
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return to_plain(dataclasses.asdict(value), strict=strict, where=where)
    raise TypeError(f"{where or 'value'}: {type(value).__name__} is not JSON serializable")


def _plain_key(key, where: str):
    """A dict key as `json` takes it (str, int, float, bool, None); NumPy scalars as Python ones."""
    import numpy as np

    if isinstance(key, np.generic):
        return key.item()
    if key is None or isinstance(key, (str, int, float, bool)):
        return key
    raise TypeError(f"{where or 'value'}: a key of type {type(key).__name__} is not JSON serializable")


def json_text(obj, *, indent: int | None = 1, sort_keys: bool = False, newline: bool = False,
              strict: bool = False) -> str:
    """The JSON text of `to_plain(obj)`: valid JSON always (no NaN or Infinity literals). `indent`, `sort_keys`
    and a trailing `newline` are as each file has always been written (the bytes of a dataset's scene.json,
    manifest.json and index.json must not change); `strict` raises on a non-finite number instead of null."""
    import json

    text = json.dumps(to_plain(obj, strict=strict), indent=indent, sort_keys=sort_keys, allow_nan=False)
    return text + "\n" if newline else text


def write_json(path: str | Path, obj, *, indent: int | None = 1, sort_keys: bool = False, newline: bool = False,
               strict: bool = False) -> None:
    """Write `json_text(obj, ...)` to `path` atomically (`atomic_write_text`): the one JSON writer of the
    project (scene.json, manifests, indexes, reports, model cards, sidecars)."""
    atomic_write_text(path, json_text(obj, indent=indent, sort_keys=sort_keys, newline=newline, strict=strict))


_LOCK = threading.RLock()


@contextmanager
def caught_stderr() -> Iterator[list[str]]:
    """Catch what is written to file descriptor 2 in the block; the list yielded is filled, one stripped non-empty
    line per entry, when the block ends (also when it raises). One capture at a time in this process (a lock; a
    capture inside another catches its own block); none where the process has no standard error or no room for the
    temporary file (the block then runs uncaught)."""
    said: list[str] = []
    with _LOCK:
        sys.stderr.flush()
        try:
            saved = os.dup(2)
        except OSError:  # no standard error: nothing to catch
            yield said
            return
        try:
            caught = tempfile.TemporaryFile()
        except OSError:  # no room for the file: run uncaught
            os.close(saved)
            yield said
            return
        with caught:
            os.dup2(caught.fileno(), 2)
            try:
                yield said
            finally:
                os.dup2(saved, 2)
                os.close(saved)
                caught.seek(0)
                said.extend(line.strip() for line in caught.read().decode(errors="replace").splitlines()
                            if line.strip())
