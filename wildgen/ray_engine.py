"""The Ray engine of `wildgen.make --ray`: one Ray task per object, on a local Ray started here or on a running
cluster (the contract and the retries: `wildgen.engine_base`). Ray is an optional extra (`RAY_INSTALL`)."""
from __future__ import annotations

import logging
import socket
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

from wildgen.config import GenConfig
from wildgen.engine_base import Attempts, available_cores, describe_error, init_process, transient

RAY_INSTALL = "pip install 'unips-toolkit[ray]' (or: pip install 'ray>=2.9')"


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
        lib = init_process(variant, threads, cfg.assets)
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
        attempts = Attempts(indices, self.max_retries, on_entry)
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
