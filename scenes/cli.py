"""The one usage-error type of every command-line entry point, and how it is reported.

Defined at the bottom layer so that `wildgen`, `unips`, `validate` and `orchestrate` CLIs share it without
importing each other: a CLI raises `UsageError` (or lets its library raise ValueError /
FileNotFoundError), and its `main` turns that into one line `error: ...` on stderr and a non-zero exit
status with `report_error`, never a traceback. `check_output_folder` refuses an output folder that cannot
be written before any work (`make_output_folder` then creates it).

Also here, so that every command applies them the same way before any work:
- `claim_outputs`: the one rule of `--overwrite` (see its docstring and docs/development.md, "Outputs and
  --overwrite");
- `check_memory` / `available_memory`: a command whose size a flag controls estimates the bytes it needs and
  refuses, in one line with the estimate and the limit, what this machine cannot hold;
- `check_threads`: a thread count this machine cannot start is refused by its flag;
- `Progress` (and the callback form `progress_bar`): what every command shows while it works, a bar only on a
  terminal, plain lines at most every `PLAIN_EVERY_S` seconds in a log.
"""
from __future__ import annotations

import os
import sys
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator

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
            kind = "a link" if p.is_symlink() else "a folder" if p.is_dir() else "a file" if p.is_file() else "not a plain file"
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


def _meminfo(key: str) -> int | None:
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith(key + ":"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def _cgroup_left() -> int | None:
    """Bytes the cgroup (v2 or v1) of this process may still use, or None without a limit."""
    for limit, usage in (("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
                         ("/sys/fs/cgroup/memory/memory.limit_in_bytes", "/sys/fs/cgroup/memory/memory.usage_in_bytes")):
        try:
            text = Path(limit).read_text().strip()
            if text == "max" or int(text) >= 2**60:
                return None
            return max(0, int(text) - int(Path(usage).read_text().strip()))
        except (OSError, ValueError):
            continue
    return None


def available_memory() -> int | None:
    """Bytes this process may still allocate: the smaller of Linux's MemAvailable and what the cgroup memory
    limit leaves; None when neither is known (then nothing is refused)."""
    known = [v for v in (_meminfo("MemAvailable"), _cgroup_left()) if v is not None]
    return min(known) if known else None


def gib(n: float) -> str:
    """A byte count in GiB for messages."""
    return f"{n / 2**30:.1f} GiB" if n >= 2**30 / 10 else f"{n / 2**20:.0f} MiB"


def check_memory(need: float, flags: str, what: str, advice: str, available: int | None = None) -> None:
    """Refuse work whose estimated memory `need` (bytes) is more than this machine has available: UsageError
    `FLAGS: WHAT needs about N GiB of memory, this machine has M GiB available; ADVICE`. `flags` names the flags
    that set the size, `what` the work (e.g. "the model at 20000 x 20000 px with 4 images")."""
    available = available_memory() if available is None else available
    if available is not None and need > available:
        raise UsageError(f"{flags}: {what} needs about {gib(need)} of memory, this machine has {gib(available)} "
                         f"available; {advice}")


def thread_limit() -> int | None:
    """Threads this process may still start: the smallest of RLIMIT_NPROC, kernel.threads-max, the cgroup's
    pids.max and half of vm.max_map_count (each thread's stack takes two memory maps: its pages and a guard
    page), less the threads already running; None when none is known."""
    limits = []
    try:
        import resource

        soft = resource.getrlimit(resource.RLIMIT_NPROC)[0]
        if soft != resource.RLIM_INFINITY:
            limits.append(soft)
    except (ImportError, OSError, ValueError):
        pass
    for path, per_thread in (("/proc/sys/kernel/threads-max", 1), ("/sys/fs/cgroup/pids.max", 1),
                             ("/proc/sys/vm/max_map_count", 2)):
        try:
            text = Path(path).read_text().strip()
            if text != "max":
                limits.append(int(text) // per_thread)
        except (OSError, ValueError):
            pass
    if not limits:
        return None
    running = 0
    try:
        running = sum(1 for _ in Path("/proc/self/task").iterdir())
    except OSError:
        pass
    return max(1, min(limits) - running)


def check_threads(threads: int | None, flag: str = "--threads", processes: int = 1) -> None:
    """Refuse a thread count (per process, `processes` of them) that this machine cannot start, naming `flag`."""
    limit = thread_limit()
    if threads is None or limit is None:
        return
    if threads * processes > limit:
        per = f" x {processes} processes" if processes > 1 else ""
        raise UsageError(f"{flag}: got {threads}{per}, this machine lets this process start at most {limit} more "
                         f"threads; expected at most {max(1, limit // max(processes, 1))} (one per core is usually best: "
                         f"{os.cpu_count() or 1})")


PLAIN_EVERY_S = 10.0
"""Without a terminal on stderr (a log file, a pipe): at most one progress line per this many seconds."""


def _is_terminal(stream: Any) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):  # no isatty, or a closed stream
        return False


class Progress:
    """The progress of one piece of work, shown the one way of every CLI: a tqdm bar on stderr when stderr is a
    terminal; otherwise (a log file, a pipe) a plain line `DESC: DONE/TOTAL UNIT, key=value..., N s` at most
    every `PLAIN_EVERY_S` seconds, and a last one at the end when any was printed, never a bar redraw (carriage
    returns) in a log. With `enabled` false (--quiet, --no-progress, a rank other than 0) it shows nothing.
    A context manager (closed on exit); `update` sets the count, `advance` adds to it."""

    def __init__(self, desc: str, unit: str, total: int | None = None, done: int = 0, enabled: bool = True,
                 stream: Any = None, clock: Callable[[], float] = time.monotonic) -> None:
        self.desc, self.unit, self.total, self.done = desc, unit, total, done
        self.postfix: dict[str, Any] = {}
        self.stream = sys.stderr if stream is None else stream
        self.enabled, self.clock = enabled, clock
        self.start = self.last_line = clock()
        self.lines = 0
        self.bar = None
        if enabled and _is_terminal(self.stream):
            from tqdm import tqdm

            self.bar = tqdm(total=total, initial=done, unit=unit, desc=desc, file=self.stream, dynamic_ncols=True,
                            leave=False)

    def update(self, done: int, total: int | None = None, desc: str | None = None,
               postfix: dict[str, Any] | None = None) -> None:
        """The work is at `done` (of `total`, when given); `desc` replaces the description, `postfix` values
        (name -> value) are shown after the count."""
        step, self.done = done - self.done, done
        self.total = self.total if total is None else total
        self.desc = desc or self.desc
        self.postfix.update(postfix or {})
        if self.bar is not None:
            self.bar.total = self.total
            self.bar.set_description(self.desc, refresh=False)
            if self.postfix:
                self.bar.set_postfix(self.postfix, refresh=False)
            self.bar.update(step)
        elif self.enabled and self.clock() - self.last_line >= PLAIN_EVERY_S:
            self._line()

    def advance(self, n: int = 1, postfix: dict[str, Any] | None = None) -> None:
        """`n` more units done."""
        self.update(self.done + n, postfix=postfix)

    def _line(self) -> None:
        self.last_line = now = self.clock()
        of = f"/{self.total}" if self.total is not None else ""
        more = "".join(f", {k}={v}" for k, v in self.postfix.items())
        print(f"{self.desc}: {self.done}{of} {self.unit}{more}, {now - self.start:.0f} s", file=self.stream, flush=True)
        self.lines += 1

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None
        elif self.enabled and self.lines:
            self._line()
            self.enabled = False

    def __enter__(self) -> "Progress":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


@contextmanager
def logs_above_progress() -> Iterator[None]:
    """Log records (warnings of a long run) printed above a progress bar instead of through it (tqdm's logging
    redirect; harmless without a bar)."""
    from tqdm.contrib.logging import logging_redirect_tqdm

    with logging_redirect_tqdm():
        yield


@contextmanager
def progress_bar(unit: str) -> Iterator[Callable[[int, int, str], None]]:
    """A `progress(done, total, label)` callback showing one `Progress`, closed on exit. It is created at the first
    call, so that an input error found before any work still prints one clean error line."""
    shown: list[Progress] = []

    def progress(done: int, total: int, label: str) -> None:
        if not shown:
            shown.append(Progress(label, unit, total))
        shown[0].update(done, total, desc=label)

    try:
        yield progress
    finally:
        for p in shown:
            p.close()
