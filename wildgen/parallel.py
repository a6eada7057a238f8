"""Engines that run `make_object` for many indices: in this process, in local worker processes, and the engine
choice of `wildgen.make` (`choose_engine`; Ray tasks are `wildgen.ray_engine`). The contract every engine keeps,
the retries and the determinism guarantee: `wildgen.engine_base`.

Workers are separate processes started with 'spawn' (Mitsuba and Dr.Jit hold threads and JIT state
that do not survive fork). Each one sets its Mitsuba variant and Dr.Jit thread count once, renders
one object at a time, and is replaced after `recycle_after` objects to bound memory. Local workers
die with their parent (Linux PR_SET_PDEATHSIG), so killing the driver leaves no orphan writing files.
"""
from __future__ import annotations

import logging
import os
import signal
import sys
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from scenes.cli.supervise import die_with_parent
from wildgen.config import GenConfig
from wildgen.engine_base import (
    STOP_SIGNALS,
    Attempts,
    Engine,
    available_cores,
    check_stop,
    default_workers,
    describe_error,
    init_process,
    threads_per_worker,
    transient,
)
from wildgen.ray_engine import RAY_INSTALL, RayEngine, import_ray, ray_available

__all__ = [
    "STOP_SIGNALS",
    "RAY_INSTALL",
    "Engine",
    "InProcessEngine",
    "ProcessEngine",
    "RayEngine",
    "WorkersCannotStart",
    "available_cores",
    "choose_engine",
    "default_workers",
    "describe_error",
    "import_ray",
    "ray_available",
    "threads_per_worker",
    "transient",
]
"""The engines' names, importable from here as before the split (the shared ones live in `wildgen.engine_base`,
Ray's in `wildgen.ray_engine`)."""

log = logging.getLogger(__name__)


def _signal_name(code: int | None) -> str:
    if code is not None and code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exited with code {code}"


# --------------------------------------------------------------------------- in this process


@dataclass
class InProcessEngine:
    """Render in the calling process, one object after the other (no isolation from hard crashes)."""

    max_retries: int = 2
    """Retries after a Python exception before an object is recorded as failed."""
    used: dict = field(default_factory=lambda: {"engine": "in-process"})
    """How the objects were run (recorded in the manifest)."""

    def run(
        self, cfg: GenConfig, out_dir: Path, variant: str, indices: list[int], on_entry: Callable[[dict], None]
    ) -> None:
        from scenes.renderer.variant import choose_variant
        from wildgen.assets import AssetLibrary
        from wildgen.writer import make_object

        choose_variant(variant)
        lib = AssetLibrary.scan(cfg.assets)
        attempts = Attempts(indices, self.max_retries, on_entry)
        while attempts.queue:
            index = attempts.queue.popleft()
            try:
                entry = make_object(cfg, index, out_dir, lib)
            except Exception as exc:  # one bad object must not stop the run
                check_stop(exc)  # unless it was an interrupt in disguise
                attempts.failure(index, describe_error(exc), retry=transient(exc))
                continue
            check_stop()
            attempts.success(entry)


def _worker_main(
    conn, cfg: GenConfig, out_dir: str, variant: str, threads: int | None, parent_pid: int, log_level: int
) -> None:
    """Body of a local worker process: receive indices, send back entries, until None or EOF."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent decides how to stop on Ctrl-C
    die_with_parent(parent_pid)
    logging.basicConfig(level=log_level, format="%(levelname)s %(name)s: %(message)s")
    try:
        lib = init_process(variant, threads, cfg.assets)
    except BaseException as exc:  # report and exit: the parent decides whether to give up
        conn.send(("init_error", None, describe_error(exc)))
        return
    from wildgen.writer import make_object

    while True:
        try:
            index = conn.recv()
        except (EOFError, OSError):
            return
        if index is None:
            return
        try:
            entry = make_object(cfg, index, Path(out_dir), lib)
        except Exception as exc:  # reported to the parent, which retries or records the failure
            log.debug("object %d failed:\n%s", index, traceback.format_exc())
            conn.send(("error" if transient(exc) else "fatal", index, describe_error(exc)))
            continue
        conn.send(("ok", index, entry))


# --------------------------------------------------------------------------- local processes


@dataclass
class _Worker:
    proc: object
    conn: object
    index: int | None = None
    tasks: int = 0
    retiring: bool = False


class WorkersCannotStart(RuntimeError):
    """Worker processes die or fail before rendering anything."""


@dataclass
class ProcessEngine:
    """A pool of spawned worker processes, one object at a time each, crash-isolated and recycled."""

    workers: int | None = None
    """Worker processes (None: one per core, at most one per object)."""
    threads: int | None = None
    """Dr.Jit threads per worker (None: cores // workers, at least 1)."""
    max_retries: int = 2
    """Retries after an exception or a dead worker before an object is recorded as failed."""
    recycle_after: int = 50
    """Objects a worker renders before it is replaced by a fresh process (bounds memory growth)."""
    stop_timeout: float = 5.0
    """Seconds to wait for a terminated worker before SIGKILL."""
    used: dict = field(default_factory=dict)
    """Filled by run(): the worker and thread counts actually used."""

    def run(
        self, cfg: GenConfig, out_dir: Path, variant: str, indices: list[int], on_entry: Callable[[dict], None]
    ) -> None:
        import multiprocessing as mp

        if self.recycle_after is not None and self.recycle_after < 1:
            raise ValueError(f"--recycle-after: expected a positive integer, got {self.recycle_after!r}")
        n_workers = min(self.workers or default_workers(len(indices)), max(1, len(indices)))
        threads = self.threads or threads_per_worker(n_workers)
        self.used.update(
            engine="processes", workers=n_workers, threads_per_worker=threads, recycle_after=self.recycle_after
        )
        worker_args = (cfg, str(Path(out_dir).resolve()), variant, threads, os.getpid(),
                       logging.getLogger().getEffectiveLevel())
        pool = _Pool(
            self, mp.get_context("spawn"), worker_args, Attempts(indices, self.max_retries, on_entry), n_workers
        )
        try:
            while pool.attempts.queue or any(w.index is not None for w in pool.workers):
                pool.round()
        finally:
            if sys.exc_info()[0] is not None:
                self._collect_finished(pool.workers, pool.attempts)
            self._stop(pool.workers)

    @staticmethod
    def _collect_finished(pool: list[_Worker], attempts: Attempts) -> None:
        """On an interrupt, record results that workers already sent (their folders are complete)."""
        for w in pool:
            try:
                while w.conn.poll():
                    kind, _, payload = w.conn.recv()
                    if kind == "ok":
                        w.index = None
                        attempts.success(payload)
            except (EOFError, OSError):
                continue

    def _stop(self, pool: list[_Worker]) -> None:
        """Stop every worker: ask idle ones to exit, terminate busy ones, kill what does not stop."""
        for w in pool:
            try:
                if w.index is None and w.proc.is_alive():
                    w.conn.send(None)
                elif w.proc.is_alive():
                    w.proc.terminate()
            except OSError:
                pass
        deadline = time.monotonic() + self.stop_timeout
        for w in pool:
            w.proc.join(max(0.0, deadline - time.monotonic()))
            if w.proc.is_alive():
                w.proc.kill()
                w.proc.join()
            w.conn.close()


@dataclass
class _Pool:
    """One run of a `ProcessEngine`: its worker processes, the objects' attempts, and the workers that failed to
    start (too many before any object is rendered: `WorkersCannotStart`)."""

    engine: "ProcessEngine"
    ctx: Any  # the 'spawn' multiprocessing context
    worker_args: tuple  # (cfg, out_dir, variant, threads, parent pid, log level) of `_worker_main`
    attempts: Attempts
    n_workers: int
    workers: list[_Worker] = field(default_factory=list)
    start_failures: list[str] = field(default_factory=list)

    def round(self) -> None:
        """Start workers up to `n_workers`, hand each idle one the next object, then wait for a message or a
        worker's end and handle what arrived."""
        from multiprocessing.connection import wait

        while self.attempts.queue and sum(not w.retiring for w in self.workers) < self.n_workers:
            self.start()
        for w in self.workers:
            if w.index is None and not w.retiring and self.attempts.queue:
                w.index = self.attempts.queue.popleft()
                try:
                    w.conn.send(w.index)
                except OSError:
                    pass  # dead already: its end is handled below
        ready = set(wait([w.conn for w in self.workers] + [w.proc.sentinel for w in self.workers]))
        for w in list(self.workers):
            dead = False
            if w.conn in ready or w.proc.sentinel in ready:
                try:
                    while w.conn.poll():
                        self.handle(w, w.conn.recv())
                except (EOFError, OSError):
                    dead = True
            if dead or not w.proc.is_alive():
                self.bury(w)

    def start(self) -> _Worker:
        parent_conn, child_conn = self.ctx.Pipe()
        proc = self.ctx.Process(target=_worker_main, args=(child_conn, *self.worker_args), daemon=True,
                                name="wildgen-worker")
        proc.start()
        child_conn.close()  # so that recv() in the parent sees EOF when the worker dies
        w = _Worker(proc, parent_conn)
        self.workers.append(w)
        return w

    def start_failed(self, reason: str) -> None:
        self.start_failures.append(reason)
        if (self.attempts.succeeded == 0 and not self.attempts.failures
                and len(self.start_failures) > 2 * self.n_workers + 1):
            raise WorkersCannotStart(f"worker processes cannot start: {reason}")

    def handle(self, w: _Worker, message: tuple) -> None:
        kind, index, payload = message
        if kind == "init_error":
            if w.index is not None:
                self.attempts.queue.appendleft(w.index)  # not the object's fault
                w.index = None
            w.retiring = True
            self.start_failed(payload)
            return
        w.index, w.tasks = None, w.tasks + 1
        if kind == "ok":
            self.attempts.success(payload)
        else:
            self.attempts.failure(index, payload, retry=kind != "fatal")
        if self.engine.recycle_after and w.tasks >= self.engine.recycle_after:
            w.retiring = True  # bound memory growth: a fresh process takes over
            try:
                w.conn.send(None)
            except OSError:
                pass

    def bury(self, w: _Worker) -> None:
        """A worker process has ended: charge its object if it was busy, forget it."""
        w.proc.join(self.engine.stop_timeout)
        if w.proc.is_alive():  # closed its pipe but hangs in exit
            w.proc.kill()
            w.proc.join()
        code = w.proc.exitcode
        if w.index is not None:
            hint = " (out of memory?)" if code == -signal.SIGKILL else ""
            self.attempts.failure(w.index, f"worker process {_signal_name(code)}{hint}")
            w.index = None
        elif not w.retiring and w.tasks == 0:
            self.start_failed(f"worker {_signal_name(code)} before its first object")
        w.conn.close()
        self.workers.remove(w)


def choose_engine(variant: str, ray: str | None = None, workers: int | None = None, threads: int | None = None,
                  max_retries: int = 2, recycle_after: int = 50) -> Engine:
    """The engine `wildgen.make` runs with: Ray when an address (or 'auto') is given, this process with
    workers=0, else local worker processes (one per core by default, one with a cuda variant)."""
    if ray is not None:
        return RayEngine(address=ray, threads=threads or 1, max_retries=max_retries, recycle_after=recycle_after)
    if workers == 0:
        return InProcessEngine(max_retries=max_retries)
    # On a GPU one process keeps the device busy; more would only add CUDA contexts.
    workers = workers if workers is not None else (1 if variant.startswith("cuda") else None)
    return ProcessEngine(workers=workers, threads=threads, max_retries=max_retries, recycle_after=recycle_after)
