"""Ctrl-C for commands whose work runs inside Mitsuba and Dr.Jit: the command runs as a child process in a session
of its own, and this process (the one the user started) only waits for it.

Why not a KeyboardInterrupt: Mitsuba's `Integrator.render` binding installs its own C-level SIGINT handler while it
renders (it logs, cancels the render and re-raises), Dr.Jit turns a KeyboardInterrupt raised inside a custom
operation into a RuntimeError, and a handler restored out of order by nested or concurrent renders stays installed
with a dangling integrator. Measured in the capture's slow test: an interrupt during the check ended once in SIGSEGV
and once swallowed (exit 0). A child in its own session never sees the terminal's Ctrl-C; the parent kills it
whole (SIGKILL: no unwinding through native code), removes the temporaries of the file it was writing
(`scenes.files.atomic_write` names them after the writer's pid), says in one line what is left, and exits 130.
Every output file is written whole or not at all, so what the child finished stays valid.
"""
from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

CHILD = "PS_TOOLKIT_SUPERVISED"
"""Set in the child's environment: the command then runs its work directly."""
HELD_FILE = "PS_TOOLKIT_HELD_FD"
"""Set in the child's environment: the descriptor of a pipe (inherited by the child alone) where each output folder
the work holds (`scenes.cli.outputs.output_lock`) is written, a line each, so that a stop removes the temporaries in
every one of them, whatever its flag. A pipe, not a file: a supervisor killed outright leaves nothing behind."""
INTERRUPTED = ("interrupted: --out holds only the files finished before it (each whole), the inputs are untouched; "
               "run the command again with --overwrite")
"""The one line of a stopped command."""
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)
"""What stops a supervised run (Ctrl-C, `kill`, the terminal closing)."""


def die_with_parent(parent_pid: int) -> None:
    """Ask Linux to SIGKILL this process when its parent dies (no orphan goes on writing after its parent is
    killed); called first thing in a child."""
    if not sys.platform.startswith("linux"):
        return
    import ctypes

    pr_set_pdeathsig = 1
    try:
        ctypes.CDLL(None, use_errno=True).prctl(pr_set_pdeathsig, int(signal.SIGKILL), 0, 0, 0)
    except (OSError, AttributeError):
        return
    if os.getppid() != parent_pid:  # the parent died before prctl took effect
        os._exit(1)


def _kill_session(child: subprocess.Popen) -> None:
    """SIGKILL the child and every process it started (its session's group: the steps a pipeline runs too)."""
    try:
        os.killpg(child.pid, signal.SIGKILL)
    except (ProcessLookupError, PermissionError):
        child.kill()


def flag_value(argv: list[str], flag: str) -> str | None:
    """The value of `--flag VALUE` or `--flag=VALUE` in `argv` (the last one given), or None."""
    value = None
    for i, arg in enumerate(argv):
        if arg == flag and i + 1 < len(argv):
            value = argv[i + 1]
        elif arg.startswith(flag + "="):
            value = arg[len(flag) + 1:]
    return value


def remove_temporaries(folder: str | Path | None, pids: set[int]) -> int:
    """Remove the temporary files (`scenes.files.atomic_write`) and object folders (`.tmp-NAME.PID`) the processes
    `pids` left anywhere under `folder`, never following links; how many. A file is the toolkit's temporary only
    by its name and its writer's pid, so only the pids of the stopped work count (a user's `.notes.tmp123.txt` is
    never taken for one)."""
    from scenes.files import temporary_folder_writer, temporary_writer

    if not folder or not Path(folder).is_dir():
        return 0
    removed = 0
    for root, dirs, files in os.walk(folder):
        for name in [d for d in dirs if temporary_folder_writer(d) in pids]:  # an object folder half written
            dirs.remove(name)
            shutil.rmtree(os.path.join(root, name), ignore_errors=True)
            removed += 1
        for name in files:
            if temporary_writer(name) in pids:
                try:
                    os.unlink(os.path.join(root, name))
                    removed += 1
                except OSError:
                    pass
    return removed


def run_supervised(module: str, main: Callable[[], int], interrupted: str = INTERRUPTED,
                   argv: list[str] | None = None, command: list[str] | None = None) -> int:
    """`python -m module` (or `command`, e.g. a script's path) with Ctrl-C handled as the module doc says: in the
    child, `main()`; in the process the user started, the same command as a child in its own session, waited for.
    `interrupted` is the line printed on a stop (`--out` is read from the arguments to remove the child's
    temporaries)."""
    from scenes.cli.errors import hold_standard_streams, keep_stdout_failures_short

    hold_standard_streams()  # before the pipe below: it would take a closed descriptor's number
    if os.environ.get(CHILD) == str(os.getppid()):
        die_with_parent(os.getppid())
        return keep_stdout_failures_short(main)
    if os.environ.get(CHILD):  # a step another command's work started (a bench's wildgen.make): it ends with that
        die_with_parent(os.getppid())  # work, killed outright too (kill -9, out of memory), never an orphan writing on
    argv = sys.argv[1:] if argv is None else argv
    stop: dict[str, int] = {}
    children: list[subprocess.Popen] = []

    def on_stop(signum, _frame) -> None:
        stop.setdefault("signal", signum)
        for c in children:
            stop.setdefault("pids", {c.pid, *_group(c.pid)})  # the work and its steps, before they are killed
            _kill_session(c)

    # Handlers first (a Ctrl-C right at the start kills the child too); a signal the user's shell ignores (a run
    # under nohup, or in the background) stays ignored.
    previous = {s: signal.getsignal(s) for s in STOP_SIGNALS}
    for s in STOP_SIGNALS:
        if previous[s] is not signal.SIG_IGN:
            signal.signal(s, on_stop)
    held, told = os.pipe()  # the child tells the folders it holds; read (without waiting) once it is gone
    os.set_blocking(held, False)
    os.set_blocking(told, False)
    scratch = scratch_tmpdir(module)
    try:
        try:
            child = subprocess.Popen([*(command or [sys.executable, "-m", module]), *argv], start_new_session=True,
                                     pass_fds=(told,),
                                     env={**os.environ, CHILD: str(os.getpid()), HELD_FILE: str(told), **scratch})
            os.close(told)
            told = -1
            children.append(child)
            if stop:
                stop.setdefault("pids", {child.pid, *_group(child.pid)})
                _kill_session(child)
            code = child.wait()
        finally:
            for s, handler in previous.items():
                signal.signal(s, handler)
        if stop or code < 0:
            _clean_after(child.pid, stop.get("pids", {child.pid}), [flag_value(argv, "--out"), *_read_held(held)])
    finally:
        for fd in (held, told):
            if fd >= 0:
                os.close(fd)
        if scratch:  # whatever the work left in its temporary folder, stopped or not
            shutil.rmtree(scratch["TMPDIR"], ignore_errors=True)
    advice = interrupted.removeprefix("interrupted: ")
    if stop:
        print(interrupted, file=sys.stderr)
        return 130 if stop["signal"] == signal.SIGINT else 128 + stop["signal"]
    if code < 0:  # killed from outside (the kernel's out-of-memory killer, a kill -9)
        name = signal.Signals(-code).name
        hint = " (out of memory?)" if -code == signal.SIGKILL else ""
        print(f"{module}: the work was killed by {name}{hint}: {advice}", file=sys.stderr)
        return 128 - code
    return code


def scratch_tmpdir(prefix: str) -> dict[str, str]:
    """The environment of a work's own temporary folder (TMPDIR, made inside the user's), which its runner removes
    when the work ends however it ends: a stop ends the work outright, so its `tempfile` folders would outlive
    it. Ray keeps the user's (RAY_TMPDIR: its socket paths are limited to 107 bytes). {} where no folder can be
    made there (the work then reports the unwritable TMPDIR itself). `run_supervised` and the bench scripts'
    `bench.cli_common.run_main` use it."""
    import tempfile

    try:
        folder = tempfile.mkdtemp(prefix=f"{prefix}-")
    except OSError:
        return {}
    return {"TMPDIR": folder, "RAY_TMPDIR": os.environ.get("RAY_TMPDIR", tempfile.gettempdir())}


def _stat(pid: int | str) -> list[str]:
    """The fields of /proc/PID/stat after the command's name (state, parent, process group, ...); [] where the
    process is gone or /proc cannot be read."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[-1].split()
    except OSError:
        return []


def _read_held(fd: int) -> list[str]:
    """The folders the child wrote to the pipe `fd` (what is there now: a step still alive may keep it open)."""
    data = b""
    while True:
        try:
            chunk = os.read(fd, 65536)
        except BlockingIOError:
            break
        if not chunk:
            break
        data += chunk
    return os.fsdecode(data).splitlines()


def _group(pgid: int) -> list[int]:
    """The pids of process group `pgid` (from /proc; empty where it cannot be read)."""
    entries = os.listdir("/proc") if os.path.isdir("/proc") else []
    return [int(e) for e in entries if e.isdigit() and _stat(e)[2:3] == [str(pgid)]]


def _clean_after(pid: int, pids: set[int], folders: list[str | None]) -> None:
    """The stopped work's temporaries (those of `pids`: the work and the steps it ran, in its session, which is killed
    whole) in --out and in every folder it held; the session is waited for first, a few seconds at most."""
    import time

    deadline = time.monotonic() + 5.0
    while time.monotonic() < deadline:
        try:
            os.killpg(pid, 0)  # anything of the session left (its steps die a moment after their parent)
        except (ProcessLookupError, PermissionError):
            break
        if all(_zombie(p) for p in _group(pid)):
            break
        time.sleep(0.05)
    for folder in dict.fromkeys(f for f in folders if f):
        remove_temporaries(folder, pids)


def _zombie(pid: int) -> bool:
    """Whether process `pid` is dead but not yet reaped (or gone)."""
    return _stat(pid)[:1] in ([], ["Z"])
