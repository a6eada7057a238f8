"""What this machine can hold, checked before any work: a command whose size a flag controls estimates the
bytes it needs and refuses, in one line with the estimate and the limit, what this machine cannot hold
(`check_memory`, `available_memory`); a thread count this machine cannot start is refused by its flag
(`check_threads`).
"""
from __future__ import annotations

import os
from pathlib import Path

from scenes.cli.errors import UsageError


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
    for limit, usage in (
        ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
        ("/sys/fs/cgroup/memory/memory.limit_in_bytes", "/sys/fs/cgroup/memory/memory.usage_in_bytes"),
    ):
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
        raise UsageError(
            f"{flag}: got {threads}{per}, this machine lets this process start at most {limit} more "
            f"threads; expected at most {max(1, limit // max(processes, 1))} (one per core is usually best: "
            f"{os.cpu_count() or 1})"
        )
