"""What every engine of `wildgen.parallel` (this process, local worker processes) and `wildgen.ray_engine` (Ray
tasks) shares: the contract, the retry bookkeeping, the stop signals, and a worker's process setup.

The contract, `Engine.run(cfg, out_dir, variant, indices, on_entry)`: every index ends in exactly one call
`on_entry(entry)` with a 'done', 'skipped' or 'failed' manifest entry, in completion order. A dead worker or a
transient exception (`transient`: out of memory, file system) costs the object an attempt; after `max_retries`
retries the object is recorded as failed and the run goes on (`Attempts`). Any other exception would repeat (an
object is a pure function of (config, index)) and fails the object at once. KeyboardInterrupt stops the workers
(no half-written object survives: folders appear by atomic rename) and propagates.

Each object is a pure function of (config, index): its bytes depend neither on the engine, the number of
workers nor the Dr.Jit threads per worker (scenes.renderer.render.render_film sums each pixel's samples in a fixed
order; tests/test_determinism.py, tests/test_wildgen_scale.py; docs/generator.md, "Crash safety, resume and
determinism", states the guarantee).
"""
from __future__ import annotations

import logging
import os
from collections import deque
from pathlib import Path
from typing import Callable, Protocol

from wildgen.config import GenConfig

log = logging.getLogger(__name__)

STOP_SIGNALS: list[int] = []
"""Signals (SIGINT, SIGTERM) received by this process while a run was going on, recorded by the CLI's
handlers (`wildgen.make`): an interrupt that a native call turned into an ordinary exception is still a stop."""


def transient(exc: BaseException) -> bool:
    """True for a failure that may not happen again (out of memory, a file-system error); any other exception
    of `make_object`, a pure function of (config, index), would repeat, so it is not retried."""
    import errno

    if isinstance(exc, OSError) and exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EROFS):
        return False  # a full disk or a read-only one does not heal between attempts seconds apart
    return isinstance(exc, (OSError, MemoryError)) or "out of memory" in str(exc).lower()


def importing(frame) -> bool:
    """Whether `frame` runs inside an import: Python called back by a native module while it initialises (nanobind's
    enums), where an exception cannot cross the C++ frames and aborts the process (exit -6)."""
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib"):
            return True
        frame = frame.f_back
    return False


def check_stop(exc: BaseException | None = None) -> None:
    """Raise KeyboardInterrupt (from `exc`) when a stop signal arrived: an interrupt in disguise stops the run."""
    if STOP_SIGNALS:
        raise KeyboardInterrupt from exc


def available_cores() -> int:
    """CPU cores this process may use (affinity-aware)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


def default_workers(objects: int, cores: int | None = None) -> int:
    """One worker per core, no more workers than objects."""
    cores = cores or available_cores()
    return max(1, min(cores, objects))


def threads_per_worker(workers: int, cores: int | None = None) -> int:
    """Dr.Jit threads per worker so that workers x threads does not exceed the cores."""
    cores = cores or available_cores()
    return max(1, cores // max(1, workers))


def describe_error(exc: BaseException) -> str:
    """One line: exception type and message (the manifest's 'error')."""
    msg = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {msg}" if msg else type(exc).__name__


class Engine(Protocol):
    def run(
        self, cfg: GenConfig, out_dir: Path, variant: str, indices: list[int], on_entry: Callable[[dict], None]
    ) -> None: ...


class Attempts:
    """Retry bookkeeping shared by the engines: a queue of indices, failures per index."""

    def __init__(self, indices: list[int], max_retries: int, on_entry: Callable[[dict], None]):
        if max_retries < 0:
            raise ValueError(f"--max-retries: expected a non-negative integer, got {max_retries!r}")
        self.queue: deque[int] = deque(indices)
        self.failures: dict[int, int] = {}
        self.max_retries = max_retries
        self.on_entry = on_entry
        self.succeeded = 0

    def success(self, entry: dict) -> None:
        self.succeeded += 1
        self.on_entry(entry)

    def failure(self, index: int, error: str, retry: bool = True) -> None:
        """Count a failed attempt: retry later (end of the queue) or record the object as failed (at once when
        `retry` is False: a deterministic failure)."""
        from wildgen.writer import failed_entry, index_name

        n = self.failures.get(index, 0) + 1
        self.failures[index] = n
        if retry and n <= self.max_retries:
            log.warning("object %s: attempt %d failed (%s); retrying", index_name(index), n, error)
            self.queue.append(index)
        else:
            log.error("object %s failed after %d attempts: %s", index_name(index), n, error)
            self.on_entry(failed_entry(index, error, n))


_PROCESS: dict = {}  # per worker process: variant, threads, asset libraries (set once)


def init_process(variant: str, threads: int | None, assets: str | None):
    """Set the variant and the Dr.Jit thread count once per process; return the (cached) asset library."""
    if _PROCESS.get("variant") != variant:
        from scenes.renderer.variant import choose_variant

        choose_variant(variant)
        _PROCESS["variant"] = variant
    if threads and _PROCESS.get("threads") != threads:
        import drjit as dr

        dr.set_thread_count(threads)
        _PROCESS["threads"] = threads
    libs = _PROCESS.setdefault("libs", {})
    if assets not in libs:
        from wildgen.assets import AssetLibrary

        libs[assets] = AssetLibrary.scan(assets)
    return libs[assets]
