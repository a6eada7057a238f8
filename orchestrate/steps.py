"""The steps of a multi-step command (orchestrate.demo, orchestrate.train_recipe): each a real CLI run as a
subprocess, its arguments checked up front and its failure reported as one line.

- `check_step(module, argv)`: before the first step runs, every step's command line is checked in this process
  by the step's own parser and option checks (`check_args` of the module where it has one: flags, memory
  estimate, files that already exist), so that a bad value is refused at once, naming the step's flag, and not
  after the hours of the steps before it; and the folders it writes, where they lie in a folder this command
  holds, are no links (`scenes.cli.outputs.check_step_folder`).
- `run_step(cmd)`: runs one step, its standard output and error passed through as they come, except its own
  `error: ...` line, which is held back: a failed step raises `StepFailed`, whose message is that line with the
  step named, and the command reports it as its one error line (`scenes.cli.errors.report_error`), never a traceback.
  With a `deadline` (a command's time budget), a step still running then is stopped (SIGTERM, the steps keep what
  they finished; SIGKILL `STOP_GRACE_S` later) and `OutOfTime` names the budget and the step.
"""
from __future__ import annotations

import codecs
import importlib
import os
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

from scenes.cli.errors import UsageError


class StepFailed(UsageError):
    """A step exited with a non-zero status; `code` is that status, the message names the step and its error."""

    def __init__(self, message: str, code: int) -> None:
        super().__init__(message)
        self.code = code


class OutOfTime(StepFailed):
    """A step was stopped at the deadline of the command's time budget."""


STOP_GRACE_S = 5.0
"""Seconds a step stopped at its deadline has to finish its clean-up (SIGTERM) before SIGKILL."""


STEP_OUTPUTS = ("--out", "--shards", "--work")
"""The flags by which a step is told where to write."""


def check_step(module: str, argv: list[str]) -> Any:
    """Check the command line `argv` of step `module` (`python -m module argv`) without running it: the module's
    `check_args(argv)` where it has one, else its command line (`COMMAND.parse`). Raises the step's own one-line
    error (UsageError / ValueError / FileNotFoundError) prefixed with the step's name."""
    from scenes.cli.outputs import check_step_folder

    for flag, value in zip(argv, argv[1:]):  # what the step writes, inside a folder this command holds
        if flag in STEP_OUTPUTS:
            check_step_folder(value, f"step {module} ({flag})")
    mod = importlib.import_module(module)
    try:
        if hasattr(mod, "check_args"):
            return mod.check_args(argv)
        return mod.COMMAND.parse(argv)
    except (UsageError, ValueError, FileNotFoundError) as exc:
        raise UsageError(f"step {module}: {exc}") from None


def _describe(cmd: list[str]) -> str:
    """`module --out X` of a step's command line (what the error line names)."""
    module = cmd[2] if len(cmd) > 2 and cmd[1] == "-m" else os.path.basename(cmd[0])
    out = next((cmd[i + 1] for i, a in enumerate(cmd[:-1]) if a in ("--out", "--work")), None)
    return f"{module}{f' --out {out}' if out else ''}"


def toolkit_env() -> dict[str, str]:
    """The environment of a step: this one, with this toolkit's folder first on PYTHONPATH, so that a step finds
    the toolkit from the user's own folder, where the paths the user typed (relative ones too) mean what they say."""
    repo = str(Path(__file__).resolve().parents[1])
    return {**os.environ, "PYTHONPATH": os.pathsep.join([repo, *filter(None, [os.environ.get("PYTHONPATH")])])}


def run_step(cmd: list[str], partial_ok: bool = False, cwd: str | os.PathLike | None = None,
             deadline: float | None = None, out_of_time: str = "the time budget ran out") -> bool:
    """Run one step (printed first as `+ module args`). Returns True when it succeeded; with `partial_ok`, exit
    status 1 of a dataset command (some objects failed, listed by the command, the others written) returns
    False and its error line is passed through. Any other failure raises `StepFailed` with the step's own error
    line (its output is above it). A step still running at `deadline` (time.time()) is stopped: `OutOfTime`,
    whose message is `out_of_time` with the step named."""
    shown = cmd[2:] if len(cmd) > 2 and cmd[1] == "-m" else cmd
    print("+ " + " ".join(map(str, shown)), flush=True)
    if deadline is not None and time.time() >= deadline:
        raise OutOfTime(f"{out_of_time} before step {_describe(cmd)} started", 2)
    from scenes.cli.supervise import die_with_parent

    me = os.getpid()  # a step dies with the pipeline that runs it (no orphan writes on after a kill -9)
    proc = subprocess.Popen([str(c) for c in cmd], stderr=subprocess.PIPE, cwd=cwd, env=toolkit_env(),
                            preexec_fn=lambda: die_with_parent(me))
    stopped: list[float] = []
    timers = []
    if deadline is not None:
        def stop(sig_kill: bool) -> None:
            if proc.poll() is None:
                stopped.append(time.time())
                (proc.kill if sig_kill else proc.terminate)()

        for delay, hard in ((0.0, False), (STOP_GRACE_S, True)):
            timer = threading.Timer(max(0.0, deadline - time.time()) + delay, stop, args=(hard,))
            timer.daemon = True
            timer.start()
            timers.append(timer)
    try:
        held = _pass_through(proc)
        code = proc.wait()
    finally:
        for timer in timers:
            timer.cancel()
    if stopped:
        raise OutOfTime(f"{out_of_time} while step {_describe(cmd)} ran (stopped at the deadline)", 2)
    if code == 0 or (code == 1 and partial_ok):
        for line in held:
            sys.stderr.write(line + "\n")
        sys.stderr.flush()
        return code == 0
    why = held[-1][len("error:"):].strip() if held else f"exit status {code} (its output is above)"
    raise StepFailed(f"step {_describe(cmd)} failed: {why}", code if code in (1, 2) else 1)


def _pass_through(proc: subprocess.Popen) -> list[str]:
    """Copy the step's standard error to ours as it comes (progress bars included: text up to a carriage return
    is written at once), except whole lines that start with `error:`, which are returned."""
    decoder = codecs.getincrementaldecoder("utf-8")(errors="replace")
    held: list[str] = []
    pending = ""
    fd = proc.stderr.fileno()
    while True:
        chunk = os.read(fd, 65536)
        text = decoder.decode(chunk, final=not chunk)
        pending += text
        while "\n" in pending:
            line, pending = pending.split("\n", 1)
            if line.split("\r")[-1].startswith("error:"):
                head = line.rsplit("\r", 1)[0] if "\r" in line else ""
                if head:
                    sys.stderr.write(head + "\r")
                held.append(line.split("\r")[-1])
            else:
                sys.stderr.write(line + "\n")
        if "\r" in pending:  # a progress bar redrawn in place: show it now
            head, pending = pending.rsplit("\r", 1)
            sys.stderr.write(head + "\r")
        sys.stderr.flush()
        if not chunk:
            break
    if pending:
        (held.append(pending) if pending.startswith("error:") else sys.stderr.write(pending))
    proc.stderr.close()
    return held
