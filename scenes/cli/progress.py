"""What every command shows while it works (`Progress`, and the callback form `progress_bar`): a bar only on a
terminal, plain lines at most every `PLAIN_EVERY_S` seconds in a log.
"""
from __future__ import annotations

import sys
import threading
import time
from contextlib import contextmanager
from typing import Any, Callable, Iterator

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


class _Heartbeat:
    """The state `heartbeat` shares with the stages run inside it: the stage now running and the last line."""

    def __init__(self, command: str, out: Any, clock: Callable[[], float]) -> None:
        self.command, self.out, self.clock = command, out, clock
        self.lock = threading.Lock()
        self.last = clock()
        self.current: tuple[str, str, float] | None = None  # (name, " (about N s)", start)
        self.beats = 0

    def say(self, text: str) -> None:
        with self.lock:
            print(text, file=self.out, flush=True)
            self.last = self.clock()

    def beat(self) -> None:
        with self.lock:
            current = self.current
        if current is None:
            self.say(f"{self.command}: working, {self.clock() - self.last:.0f} s since the last line")
        else:
            name, about, t0 = current
            self.say(f"{self.command}: {name}{about}, {self.clock() - t0:.0f} s so far")
        self.beats += 1


_ACTIVE: list[_Heartbeat] = []
"""The heartbeat of the command running in this process, if any (one at a time)."""


HEARTBEAT_S = PLAIN_EVERY_S - 2.0
"""A heartbeat's interval: two seconds under the promised 10, because its thread needs the interpreter lock, which a
long call into a library can hold for a moment (bench_capture measured lines 10.2 to 11.4 s apart at exactly 10)."""


@contextmanager
def heartbeat(command: str, every_s: float = HEARTBEAT_S, stream: Any = None,
              clock: Callable[[], float] = time.monotonic) -> Iterator[None]:
    """For the whole of a command's run: never more than `every_s` seconds without a line on stderr. The stages
    run inside it (`stage`) name what is running; between them (writing outputs) the line says `working`. Without
    it, each stage keeps its own clock (silences between stages are then not covered)."""
    hb = _Heartbeat(command, sys.stderr if stream is None else stream, clock)
    stop = threading.Event()

    def tick() -> None:
        while not stop.wait(max(0.01, every_s - (hb.clock() - hb.last))):
            if hb.clock() - hb.last >= every_s:
                hb.beat()

    _ACTIVE.append(hb)
    ticker = threading.Thread(target=tick, daemon=True)
    ticker.start()
    try:
        yield
    finally:
        stop.set()
        ticker.join()
        _ACTIVE.remove(hb)


@contextmanager
def stage(command: str, name: str, estimate_s: float | None = None, every_s: float = PLAIN_EVERY_S,
          stream: Any = None, clock: Callable[[], float] = time.monotonic) -> Iterator[None]:
    """One stage of a long command, shown on stderr only once it lasts: `COMMAND: NAME (about N s), N s so far` at
    least every `every_s` seconds while it runs (a stage that reports no steps of its own, e.g. a model's forward
    pass, still shows that the command is alive), then `COMMAND: NAME done in N s`. A stage shorter than `every_s`
    prints nothing, so that a command refusing a bad input in its first seconds still says one line. Inside a
    `heartbeat` the clock is the command's (the last line of any stage); alone, the stage runs in a heartbeat of its
    own (`every_s`, `stream`, `clock`)."""
    if not _ACTIVE:  # a stage on its own is a run of its own: its heartbeat starts and ends with it
        with heartbeat(command, every_s, stream, clock), stage(command, name, estimate_s):
            yield
        return
    about = f" (about {estimate_s:.0f} s)" if estimate_s is not None else ""
    hb = _ACTIVE[-1]
    t0, before = hb.clock(), hb.beats
    with hb.lock:
        hb.current = (name, about, t0)
    try:
        yield
    finally:
        with hb.lock:
            hb.current = None
    if hb.beats > before:
        hb.say(f"{command}: {name} done in {hb.clock() - t0:.1f} s")
