"""Wall-time budgets of commands (`unips.train --time-limit`, `orchestrate.gpu_session --minutes`,
`orchestrate.train_recipe --minutes`): counted from the start of the process (its interpreter start and imports
included, as a user's clock counts them), each stage asks what is left before it starts and stops when the
next piece of work (the longest seen so far) would not fit.
"""
from __future__ import annotations

import os
import time
from dataclasses import dataclass, field

_IMPORTED = time.time()
END_SHARE = 0.05
"""Share of a budget kept after its last piece of work: the last files and the process's exit."""
END_MIN_S = 2.0
"""Seconds kept after the last piece of work at the least: the process's exit has a cost of its own (torch's and
the supervisor's teardown, about 1.5 s on two busy cores), which a share of a short budget does not cover."""


def end_reserve(seconds: float) -> float:
    """The seconds of a budget of `seconds` kept for what follows its last piece of work."""
    return min(max(END_SHARE * seconds, END_MIN_S), seconds / 4)


def process_start() -> float:
    """When this process started (seconds since the epoch): Linux's record of it (/proc), else the time this
    module was first imported. A supervised command's work (`scenes.cli.supervise`) counts from its supervisor's
    start, the process the user started."""
    from scenes.cli.supervise import CHILD

    parent = os.getppid()
    who = str(parent) if os.environ.get(CHILD) == str(parent) else "self"
    try:
        with open(f"/proc/{who}/stat") as f:
            ticks = int(f.read().rsplit(")", 1)[1].split()[19])  # field 22: start time, clock ticks after boot
        with open("/proc/stat") as f:
            boot = next(int(line.split()[1]) for line in f if line.startswith("btime "))
        return min(_IMPORTED, boot + ticks / os.sysconf("SC_CLK_TCK"))
    except (OSError, ValueError, IndexError, StopIteration):
        return _IMPORTED


@dataclass
class Budget:
    """`seconds` of wall time from `start` (None: no limit). `fits(kind)` says whether one more piece of work of
    that kind (a step, a validation, a save) still fits, from the longest one of that kind timed so far
    (`timed`); a kind never timed is estimated by `first_guess`. `end_reserve` of the budget is kept for what
    follows the last piece (the last files, the process's exit)."""

    seconds: float | None
    start: float = field(default_factory=process_start)
    longest: dict = field(default_factory=dict)

    @property
    def deadline(self) -> float:
        return float("inf") if self.seconds is None else self.start + self.seconds

    def left(self) -> float:
        return self.deadline - time.time()

    def spent(self) -> float:
        return time.time() - self.start

    def timed(self, kind: str, seconds: float) -> None:
        self.longest[kind] = max(self.longest.get(kind, 0.0), seconds)

    def fits(self, *kinds: str, first_guess: float = 0.0) -> bool:
        """Whether work of these kinds, one after the other, ends before the deadline."""
        need = sum(self.longest.get(k, first_guess) for k in kinds)
        return time.time() + need < self.deadline - end_reserve(self.seconds or 0.0)
