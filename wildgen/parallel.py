"""Engines that run `make_object` for many indices: in this process, in local worker processes, on Ray.

All engines share one contract, `run(cfg, out_dir, variant, indices, on_entry)`: every index ends in
exactly one call `on_entry(entry)` with a 'done', 'skipped' or 'failed' manifest entry, in completion
order. A dead worker or a transient exception (`transient`: out of memory, file system) costs the object
an attempt; after `max_retries` retries the object is recorded as failed and the run goes on. Any other
exception would repeat (an object is a pure function of (config, index)) and fails the object at once. KeyboardInterrupt stops the workers (no
half-written object survives: folders appear by atomic rename) and propagates.

Workers are separate processes started with 'spawn' (Mitsuba and Dr.Jit hold threads and JIT state
that do not survive fork). Each one sets its Mitsuba variant and Dr.Jit thread count once, renders
one object at a time, and is replaced after `recycle_after` objects to bound memory. Local workers
die with their parent (Linux PR_SET_PDEATHSIG), so killing the driver leaves no orphan writing files.

Each object is a pure function of (config, index): its bytes depend neither on the engine, the number of
workers nor the Dr.Jit threads per worker (scenes.render.render_film sums each pixel's samples in a fixed
order; tests/test_determinism.py, tests/test_wildgen_scale.py; docs/generator.md, "Crash safety, resume and
determinism", states the guarantee).
"""
from __future__ import annotations

import logging
import os
import signal
import socket
import sys
import time
import traceback
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Protocol

from wildgen.config import GenConfig

log = logging.getLogger(__name__)

RAY_INSTALL = "pip install 'unips-toolkit[ray]' (or: pip install 'ray>=2.9')"

STOP_SIGNALS: list[int] = []
"""Signals (SIGINT, SIGTERM) received by this process while a run was going on, recorded by the CLI's
handlers (`wildgen.make`): an interrupt that a native call turned into an ordinary exception is still a stop."""


def transient(exc: BaseException) -> bool:
    """True for a failure that may not happen again (out of memory, a file-system error); any other exception
    of `make_object`, a pure function of (config, index), would repeat, so it is not retried."""
    return isinstance(exc, (OSError, MemoryError)) or "out of memory" in str(exc).lower()


def _check_stop(exc: BaseException | None = None) -> None:
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


def _signal_name(code: int | None) -> str:
    if code is not None and code < 0:
        try:
            return f"killed by {signal.Signals(-code).name}"
        except ValueError:
            return f"killed by signal {-code}"
    return f"exited with code {code}"


class Engine(Protocol):
    def run(self, cfg: GenConfig, out_dir: Path, variant: str, indices: list[int], on_entry: Callable[[dict], None]) -> None:
        ...


class _Attempts:
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


# --------------------------------------------------------------------------- in this process


@dataclass
class InProcessEngine:
    """Render in the calling process, one object after the other (no isolation from hard crashes)."""

    max_retries: int = 2
    """Retries after a Python exception before an object is recorded as failed."""
    used: dict = field(default_factory=lambda: {"engine": "in-process"})
    """How the objects were run (recorded in the manifest)."""

    def run(self, cfg: GenConfig, out_dir: Path, variant: str, indices: list[int], on_entry: Callable[[dict], None]) -> None:
        from scenes.variant import choose_variant
        from wildgen.assets import AssetLibrary
        from wildgen.writer import make_object

        choose_variant(variant)
        lib = AssetLibrary.scan(cfg.assets)
        attempts = _Attempts(indices, self.max_retries, on_entry)
        while attempts.queue:
            index = attempts.queue.popleft()
            try:
                entry = make_object(cfg, index, out_dir, lib)
            except Exception as exc:  # one bad object must not stop the run
                _check_stop(exc)  # unless it was an interrupt in disguise
                attempts.failure(index, describe_error(exc), retry=transient(exc))
                continue
            _check_stop()
            attempts.success(entry)


# --------------------------------------------------------------------------- worker-side setup

_PROCESS: dict = {}  # per worker process: variant, threads, asset libraries (set once)


def _init_process(variant: str, threads: int | None, assets: str | None):
    """Set the variant and the Dr.Jit thread count once per process; return the (cached) asset library."""
    if _PROCESS.get("variant") != variant:
        from scenes.variant import choose_variant

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


def _die_with_parent(parent_pid: int) -> None:
    """Ask Linux to SIGKILL this process when its parent dies (no orphans writing into the dataset)."""
    if not sys.platform.startswith("linux"):
        return
    import ctypes

    PR_SET_PDEATHSIG = 1
    try:
        ctypes.CDLL(None, use_errno=True).prctl(PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
    except (OSError, AttributeError):
        return
    if os.getppid() != parent_pid:  # the parent died before prctl took effect
        os._exit(1)


def _worker_main(conn, cfg: GenConfig, out_dir: str, variant: str, threads: int | None, parent_pid: int, log_level: int) -> None:
    """Body of a local worker process: receive indices, send back entries, until None or EOF."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # the parent decides how to stop on Ctrl-C
    _die_with_parent(parent_pid)
    logging.basicConfig(level=log_level, format="%(levelname)s %(name)s: %(message)s")
    try:
        lib = _init_process(variant, threads, cfg.assets)
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

    def run(self, cfg: GenConfig, out_dir: Path, variant: str, indices: list[int], on_entry: Callable[[dict], None]) -> None:
        import multiprocessing as mp
        from multiprocessing.connection import wait

        if self.recycle_after is not None and self.recycle_after < 1:
            raise ValueError(f"--recycle-after: expected a positive integer, got {self.recycle_after!r}")
        n_workers = min(self.workers or default_workers(len(indices)), max(1, len(indices)))
        threads = self.threads or threads_per_worker(n_workers)
        self.used.update(engine="processes", workers=n_workers, threads_per_worker=threads, recycle_after=self.recycle_after)
        ctx = mp.get_context("spawn")
        attempts = _Attempts(indices, self.max_retries, on_entry)
        pool: list[_Worker] = []
        start_failures: list[str] = []
        out = str(Path(out_dir).resolve())
        level = logging.getLogger().getEffectiveLevel()

        def start() -> _Worker:
            parent_conn, child_conn = ctx.Pipe()
            proc = ctx.Process(target=_worker_main, args=(child_conn, cfg, out, variant, threads, os.getpid(), level),
                               daemon=True, name="wildgen-worker")
            proc.start()
            child_conn.close()  # so that recv() in the parent sees EOF when the worker dies
            w = _Worker(proc, parent_conn)
            pool.append(w)
            return w

        def start_failed(reason: str) -> None:
            start_failures.append(reason)
            if attempts.succeeded == 0 and not attempts.failures and len(start_failures) > 2 * n_workers + 1:
                raise WorkersCannotStart(f"worker processes cannot start: {reason}")

        def handle(w: _Worker, message: tuple) -> None:
            kind, index, payload = message
            if kind == "init_error":
                if w.index is not None:
                    attempts.queue.appendleft(w.index)  # not the object's fault
                    w.index = None
                w.retiring = True
                start_failed(payload)
                return
            w.index, w.tasks = None, w.tasks + 1
            if kind == "ok":
                attempts.success(payload)
            else:
                attempts.failure(index, payload, retry=kind != "fatal")
            if self.recycle_after and w.tasks >= self.recycle_after:
                w.retiring = True  # bound memory growth: a fresh process takes over
                try:
                    w.conn.send(None)
                except OSError:
                    pass

        def bury(w: _Worker) -> None:
            """A worker process has ended: charge its object if it was busy, forget it."""
            w.proc.join(self.stop_timeout)
            if w.proc.is_alive():  # closed its pipe but hangs in exit
                w.proc.kill()
                w.proc.join()
            code = w.proc.exitcode
            if w.index is not None:
                hint = " (out of memory?)" if code == -signal.SIGKILL else ""
                attempts.failure(w.index, f"worker process {_signal_name(code)}{hint}")
                w.index = None
            elif not w.retiring and w.tasks == 0:
                start_failed(f"worker {_signal_name(code)} before its first object")
            w.conn.close()
            pool.remove(w)

        try:
            while attempts.queue or any(w.index is not None for w in pool):
                while attempts.queue and sum(not w.retiring for w in pool) < n_workers:
                    start()
                for w in pool:
                    if w.index is None and not w.retiring and attempts.queue:
                        w.index = attempts.queue.popleft()
                        try:
                            w.conn.send(w.index)
                        except OSError:
                            pass  # dead already: its end is handled below
                ready = set(wait([w.conn for w in pool] + [w.proc.sentinel for w in pool]))
                for w in list(pool):
                    dead = False
                    if w.conn in ready or w.proc.sentinel in ready:
                        try:
                            while w.conn.poll():
                                handle(w, w.conn.recv())
                        except (EOFError, OSError):
                            dead = True
                    if dead or not w.proc.is_alive():
                        bury(w)
        finally:
            if sys.exc_info()[0] is not None:
                self._collect_finished(pool, attempts)
            self._stop(pool)

    @staticmethod
    def _collect_finished(pool: list[_Worker], attempts: _Attempts) -> None:
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


# --------------------------------------------------------------------------- Ray


def import_ray():
    """Import Ray or raise ImportError with the install command."""
    try:
        import ray
    except ImportError as exc:
        raise ImportError(f"--ray needs Ray, an optional extra: {RAY_INSTALL}") from exc
    return ray


def ray_available() -> bool:
    """True when Ray can be imported (imports it: only call this when Ray is about to be used)."""
    try:
        import_ray()
    except ImportError:
        return False
    return True


def _ray_make_object(cfg: GenConfig, out_dir: str, variant: str, threads: int | None, index: int) -> tuple[str, object, str]:
    """Ray task: one object in a Ray worker process (variant and threads set on its first task)."""
    host = socket.gethostname()
    try:
        lib = _init_process(variant, threads, cfg.assets)
        from wildgen.writer import make_object

        return "ok", make_object(cfg, index, Path(out_dir), lib), host
    except Exception as exc:  # reported to the driver, which retries or records the failure
        return ("error" if transient(exc) else "fatal"), f"{describe_error(exc)} (on {host})", host


@dataclass
class RayEngine:
    """One Ray task per object, on a local Ray started here or on a running cluster.

    The output folder must be visible at the same path from every node (a shared filesystem);
    workers write object folders directly, only the driver writes the manifest.
    """

    address: str | None = "auto"
    """'auto' or None: join the cluster this machine belongs to, else start a local Ray; or 'HOST:PORT' / 'ray://...'."""
    threads: int | None = 1
    """Dr.Jit threads (and Ray CPUs) per task."""
    max_retries: int = 2
    """Retries after an exception or a lost worker before an object is recorded as failed."""
    recycle_after: int = 50
    """Tasks a Ray worker process runs before Ray replaces it (max_calls)."""
    local_cpus: int | None = None
    """CPUs of a local Ray started here (None: all cores)."""
    used: dict = field(default_factory=dict)
    """Filled by run(): how Ray was reached and its CPUs."""

    def _connect(self, ray) -> bool:
        """Join or start Ray; True when this call started a local instance (shut down at the end)."""
        if ray.is_initialized():
            return False
        quiet = {"logging_level": logging.WARNING, "log_to_driver": True}
        if self.address and self.address != "auto":
            ray.init(address=self.address, **quiet)
            return True  # ray.shutdown() only disconnects from a remote cluster
        try:
            ray.init(address="auto", **quiet)
            return True
        except ConnectionError:
            pass
        ray.init(num_cpus=self.local_cpus or available_cores(), include_dashboard=False,
                 object_store_memory=256 * 1024**2, **quiet)
        self.used["started_local"] = True
        return True

    def run(self, cfg: GenConfig, out_dir: Path, variant: str, indices: list[int], on_entry: Callable[[dict], None]) -> None:
        ray = import_ray()
        from ray.exceptions import RayError

        if self.recycle_after is not None and self.recycle_after < 1:
            raise ValueError(f"--recycle-after: expected a positive integer, got {self.recycle_after!r}")
        connected = self._connect(ray)
        threads = self.threads or 1
        attempts = _Attempts(indices, self.max_retries, on_entry)
        pending: dict = {}
        try:
            cpus = int(ray.cluster_resources().get("CPU", 1))
            self.used.update(engine="ray", ray=ray.__version__, cluster_cpus=cpus, threads_per_task=threads)
            task = ray.remote(num_cpus=threads, max_retries=0, max_calls=self.recycle_after or 0)(_ray_make_object)
            window = max(2, 2 * max(1, cpus // threads))  # enough queued work, without flooding the scheduler
            out = str(Path(out_dir).resolve())
            while attempts.queue or pending:
                while attempts.queue and len(pending) < window:
                    index = attempts.queue.popleft()
                    pending[task.remote(cfg, out, variant, threads, index)] = index
                ready, _ = ray.wait(list(pending), num_returns=1)
                for ref in ready:
                    index = pending.pop(ref)
                    try:
                        kind, payload, _host = ray.get(ref)
                    except RayError as exc:  # worker crashed, node lost, out of memory
                        attempts.failure(index, describe_error(exc).split("\n")[0][:500])
                        continue
                    if kind == "ok":
                        attempts.success(payload)
                    else:
                        attempts.failure(index, payload, retry=kind != "fatal")
        finally:
            if pending and sys.exc_info()[0] is not None:  # interrupted: keep what has finished already
                try:
                    for ref in ray.wait(list(pending), num_returns=len(pending), timeout=0)[0]:
                        pending.pop(ref)
                        kind, payload, _host = ray.get(ref, timeout=1)
                        if kind == "ok":
                            attempts.success(payload)
                except Exception:  # best effort: an unrecorded object is simply rendered again on resume
                    pass
            for ref in pending:
                try:
                    ray.cancel(ref, force=True)
                except Exception:  # already finished or the cluster is gone
                    pass
            if connected:
                ray.shutdown()


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
