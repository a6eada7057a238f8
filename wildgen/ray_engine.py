"""The Ray engine of `wildgen.make --ray`: one Ray task per object, on a local Ray started here or on a running
cluster (the contract and the retries: `wildgen.engine_base`). Ray is an optional extra (`RAY_INSTALL`).

On a cluster every object's manifest entry names the Ray node that rendered it (`node`, its id) and the run's
record (`run.nodes`) holds each node's host, address and object count; a node that dies mid-object costs that
object an attempt, retried on the nodes left (its temporary folder is hidden and removed at the end)."""
from __future__ import annotations

import logging
import os
import signal
import socket
import sys
import tempfile
import threading
import time
from contextlib import contextmanager
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


AUTH_HINT = ("a head started with Ray's token authentication (Ray 2.60 turns it on where a token exists) admits only "
             "nodes and drivers with RAY_AUTH_MODE=token and the head's token (~/.ray/auth_token, RAY_AUTH_TOKEN or "
             "RAY_AUTH_TOKEN_PATH); see docs/generator.md, 'Scaling out'")
"""What a driver that cannot join a cluster is told when it has not turned token authentication on."""


CONNECT_TIMEOUT_S = 20.0
"""How long `--ray HOST:PORT` (or ray://HOST:PORT) waits for the address to answer, resolving the host and opening a
TCP connection to it (`probe_address`), before the run is refused naming --ray and the address: Ray's own
ray.init() has no time-out and keeps retrying a head that does not answer for many minutes."""
RAY_HEAD_HINT = "expected the address of a running Ray head (`ray start --head` prints it)"
JOIN_TIMEOUT_S = 60.0
"""How long ray.init() may take to join a head that passed `probe_address` (it speaks gRPC) before the run is
refused: a server that answers the handshake and then nothing, or turns the driver away, keeps ray.init() retrying
without end."""


class JoinTimeout(ConnectionError):
    """ray.init() did not return within JOIN_TIMEOUT_S; its message is the whole line."""


def _bounded_init(ray, address: str, timeout: float | None = None, **kwargs) -> None:
    """ray.init(address=...) within `timeout` seconds; a ConnectionError naming --ray and the address otherwise (the
    joining thread is left behind as a daemon: Ray gives no way to stop it, and the command ends anyway)."""
    timeout = JOIN_TIMEOUT_S if timeout is None else timeout
    outcome: dict = {}

    def join() -> None:
        try:
            ray.init(address=address, **kwargs)
            outcome["ok"] = True
        except BaseException as exc:  # handed to the caller's thread as it is
            outcome["exc"] = exc

    def not_about_the_thread(record: logging.LogRecord) -> bool:  # Ray's note on joining off the main thread
        return "current thread is not the main thread" not in record.getMessage()

    said = logging.getLogger("ray._private.worker")
    said.addFilter(not_about_the_thread)
    thread = threading.Thread(target=join, name="ray-join", daemon=True)
    try:
        thread.start()
        thread.join(timeout)
    finally:
        said.removeFilter(not_about_the_thread)
    if "exc" in outcome:
        raise outcome["exc"]
    if "ok" in outcome:  # what ray.init() does on the main thread, done here: SIGTERM ends the driver cleanly
        signal.signal(signal.SIGTERM, lambda signum, _frame: sys.exit(signum))
    if "ok" not in outcome:
        raise JoinTimeout(f"--ray: {address!r} answered as a gRPC server, but no Ray driver could join it within "
                          f"{timeout:g} s (a server that is not a Ray head, or one that turns drivers away); "
                          f"{RAY_HEAD_HINT}")


def _host_port(address: str) -> tuple[str, int] | None:
    """(host, port) of 'HOST:PORT', 'ray://HOST:PORT' or '[IPv6]:PORT'; None for anything else ('auto', 'local')."""
    rest = address.split("://", 1)[1] if "://" in address else address
    host, sep, port = rest.rstrip("/").rpartition(":")
    if not sep or not host or not port.isdigit():
        return None
    return host.strip("[]"), int(port)


def check_ray_address(address: str) -> None:
    """The form of a --ray value, before anything runs: auto, local, HOST:PORT (port 1 to 65535) or
    ray://HOST:PORT (Ray Client, which needs `ray[client]`); UsageError naming --ray otherwise. An empty value (an
    unset variable) is refused, not read as a private local cluster."""
    from scenes.cli.errors import UsageError

    if address == "local":
        return
    named = "--ray"
    if address == "auto":  # joins RAY_ADDRESS first where it is set: its form is checked, named as such
        if not os.environ.get("RAY_ADDRESS") or os.environ["RAY_ADDRESS"] in ("auto", "local"):
            return
        address, named = os.environ["RAY_ADDRESS"], "--ray auto: RAY_ADDRESS"
    target = _host_port(address)
    scheme = address.split("://", 1)[0] if "://" in address else None
    if target is None or not 1 <= target[1] <= 65535 or scheme not in (None, "ray"):
        raise UsageError(f"{named}: got {address!r}, expected auto, local, HOST:PORT (port 1 to 65535) or "
                         "ray://HOST:PORT")
    if address.startswith("ray://"):
        try:
            from ray._private.utils import get_ray_client_dependency_error  # Ray's own test of its client
        except ImportError:  # no Ray at all: refused as such where Ray is needed
            return
        if get_ray_client_dependency_error() is not None:
            raise UsageError(f"{named}: {address!r} is a Ray Client address, which needs pip install 'ray[client]'; "
                             "install it, or give the head's HOST:PORT (its GCS port, 6379 by default)")


def _reach(host: str, port: int, timeout: float) -> None:
    """Open (and close) a TCP connection to host:port; raises what socket raises."""
    socket.create_connection((host, port), timeout=timeout).close()


HTTP2_PREFACE = b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n" + bytes([0, 0, 0, 4, 0, 0, 0, 0, 0])
"""A client's HTTP/2 connection preface and an empty SETTINGS frame."""


def _speaks_grpc(host: str, port: int, timeout: float) -> bool:
    """Whether host:port answers an HTTP/2 connection preface as every gRPC server (a Ray head's GCS among them)
    does, within `timeout` seconds: a SETTINGS frame first, then the acknowledgement of the client's SETTINGS. A web
    server, a database, a silent port, or a listener that writes a SETTINGS frame and then nothing, do not."""
    deadline = time.monotonic() + timeout
    data, pos, first = b"", 0, True
    try:
        with socket.create_connection((host, port), timeout=timeout) as conn:
            conn.sendall(HTTP2_PREFACE)
            while (left := deadline - time.monotonic()) > 0:
                conn.settimeout(left)
                chunk = conn.recv(4096)
                if not chunk:
                    return False
                data += chunk
                while len(data) - pos >= 9:  # whole frame headers: length (3 bytes), type, flags, stream (4)
                    length, kind, flags = int.from_bytes(data[pos:pos + 3], "big"), data[pos + 3], data[pos + 4]
                    if first and (kind != 4 or data[pos + 5:pos + 9] != bytes(4)):  # SETTINGS on stream 0 first
                        return False
                    if not first and kind == 4 and flags & 1:  # SETTINGS with ACK: it read the client's
                        return True
                    first, pos = False, pos + 9 + length
    except OSError:
        return False
    return False


def probe_address(address: str, timeout: float | None = None) -> None:
    """Refuse a --ray address where no Ray head can answer, before ray.init() waits for it: a host that does not
    resolve, a port where nothing listens, or no answer within `timeout` seconds (default CONNECT_TIMEOUT_S; the
    host's name resolution included, in a thread of its own). Raises ConnectionError, one line naming --ray and
    the address. 'auto', 'local' and addresses without a port are Ray's to read. A loopback host is also tried
    at the address Ray itself dials for it (this machine's node address)."""
    target = _host_port(address)
    if target is None:
        return
    host, port = target
    timeout = CONNECT_TIMEOUT_S if timeout is None else timeout
    hosts = [host]
    try:
        from ray._private.services import resolve_ip_for_localhost  # Ray's own rewrite of 127.0.0.1 / localhost

        if resolve_ip_for_localhost(host) != host:
            hosts.append(resolve_ip_for_localhost(host))
    except Exception:  # a private helper of Ray: without it, the address as given
        pass
    outcome: dict = {}

    def attempt() -> None:
        errors = []
        for h in hosts:
            try:
                _reach(h, port, timeout)
                # a Ray head's port (not ray:// Client's) speaks gRPC; ray.init() retries anything else for minutes
                outcome["ok"] = "://" in address or _speaks_grpc(h, port, timeout)
                outcome.setdefault("not_grpc", not outcome["ok"])
                if outcome["ok"]:
                    return
            except OSError as exc:
                errors.append(exc)
        if errors:
            outcome["error"] = errors[0]

    thread = threading.Thread(target=attempt, name="ray-probe", daemon=True)
    thread.start()
    thread.join(2 * timeout * len(hosts))  # (a connection, then the gRPC answer, per host)
    if outcome.get("ok"):
        return
    exc = outcome.get("error")
    if outcome.get("not_grpc"):
        why = "it answers, but not as the gRPC server of a Ray head does"
    elif exc is None or isinstance(exc, (TimeoutError, socket.timeout)):
        why = f"no answer within {timeout:g} s"
    elif isinstance(exc, socket.gaierror):
        why = f"the host {host!r} does not resolve: {exc.strerror or exc}"
    elif isinstance(exc, ConnectionRefusedError):
        why = "nothing listens there: connection refused"
    else:
        why = exc.strerror or str(exc)
    err = ConnectionError(f"--ray: cannot reach {address!r} ({why}); {RAY_HEAD_HINT}")
    err.why = why  # (the reason alone, for the lost-cluster line)
    raise err


def probe_ray(address: str | None) -> None:
    """`probe_address` of a --ray value; 'auto' (or none) joins RAY_ADDRESS first when it is set, so that one is
    probed, named as such."""
    if address in (None, "auto") and os.environ.get("RAY_ADDRESS"):
        try:
            probe_address(os.environ["RAY_ADDRESS"])
        except ConnectionError as exc:
            raise ConnectionError(str(exc).replace("--ray:", f"--ray {address or 'auto'}: RAY_ADDRESS", 1)) from None
    elif address:
        probe_address(address)


WAIT_S = 5.0
"""The driver waits this long for a result before it checks that the head still answers (`ClusterLost`)."""
ALIVE_TIMEOUT_S = 3.0
"""How long a head that ran this job may take to answer that check."""


class ClusterLost(ConnectionError):
    """The head of the cluster a run joined stopped answering mid-run. Without this check Ray's own core worker
    waits 60 s for it, prints a log line and ends the process; the objects finished by then are in the manifest
    and re-running the command resumes."""


def _this_node() -> dict:
    """The Ray node this task runs on: its id, host name and address."""
    import ray

    return {"id": ray.get_runtime_context().get_node_id(), "host": socket.gethostname(),
            "ip": ray.util.get_node_ip_address()}


def _ray_make_object(
    cfg: GenConfig, out_dir: str, variant: str, threads: int | None, index: int
) -> tuple[str, object, dict]:
    """Ray task: one object in a Ray worker process (variant and threads set on its first task)."""
    node = _this_node()
    try:
        lib = init_process(variant, threads, cfg.assets)
        from wildgen.writer import make_object

        return "ok", make_object(cfg, index, Path(out_dir), lib), node
    except Exception as exc:  # reported to the driver, which retries or records the failure
        return ("error" if transient(exc) else "fatal"), f"{describe_error(exc)} (on {node['host']})", node


@contextmanager
def _held_stderr():
    """Hold what is written to file descriptor 2 inside the block (C++ included), yielding a function that returns
    it so far: written out afterwards, unless the block raises ConnectionError (whose one line says what matters)."""
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as tmp:
        def text() -> str:
            tmp.seek(0)
            return tmp.read().decode(errors="replace")

        os.dup2(tmp.fileno(), 2)
        keep = True
        try:
            yield text
        except ConnectionError:
            keep = False
            raise
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            if keep:
                sys.stderr.write(text())
                sys.stderr.flush()


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
    """Filled by run(): how Ray was reached, its CPUs, and the nodes that rendered objects (`nodes`)."""
    joined: bool | None = field(default=None, repr=False)
    """Set by prepare(): whether this engine started or joined Ray (and so ends it after run())."""

    def prepare(self) -> None:
        """Join (or start) Ray before the dataset's manifest is written: an address that admits no driver is refused
        with nothing written."""
        self.joined = self._connect(import_ray())

    def _connect(self, ray) -> bool:
        """Join or start Ray; True when this call started a local instance (shut down at the end)."""
        if ray.is_initialized():
            return False
        quiet = {"logging_level": logging.WARNING, "log_to_driver": True}
        if self.address and self.address != "auto":
            probe_address(self.address)  # ray.init() would wait for a silent address for many minutes
            with _held_stderr() as held:  # Ray's C++ core warns once a second while it retries to reach the head
                try:
                    _bounded_init(ray, self.address, **quiet)
                except JoinTimeout:
                    raise
                except (ConnectionError, RuntimeError, ray.exceptions.RayError) as exc:
                    why = " ".join(str(exc).split())[:300]
                    if "InvalidAuthToken" in held() + why:
                        why += ", the head refused this driver's token"
                    token = os.environ.get("RAY_AUTH_MODE", "").lower() == "token"
                    raise ConnectionError(f"--ray: cannot join the Ray cluster at {self.address!r} ({why})"
                                          + ("" if token else f"; {AUTH_HINT}")) from None
            return True  # ray.shutdown() only disconnects from a remote cluster
        probe_ray(self.address)
        try:
            ray.init(address="auto", **quiet)
            return True
        except ConnectionError:
            pass
        ray.init(num_cpus=self.local_cpus or available_cores(), include_dashboard=False,
                 object_store_memory=256 * 1024**2, **quiet)
        self.used["started_local"] = True
        return True

    def run(
        self, cfg: GenConfig, out_dir: Path, variant: str, indices: list[int], on_entry: Callable[[dict], None]
    ) -> None:
        ray = import_ray()
        from ray.exceptions import RayError

        if self.recycle_after is not None and self.recycle_after < 1:
            raise ValueError(f"--recycle-after: expected a positive integer, got {self.recycle_after!r}")
        connected = self._connect(ray) if self.joined is None else self.joined
        self.joined = None
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
                ready, _ = ray.wait(list(pending), num_returns=1, timeout=WAIT_S)
                if not ready:
                    self._check_head()
                for ref in ready:
                    index = pending.pop(ref)
                    try:
                        kind, payload, node = ray.get(ref)
                    except RayError as exc:  # worker crashed, node lost, out of memory
                        self._check_head()  # a lost head is not the object's failure
                        attempts.failure(index, describe_error(exc).split("\n")[0][:500])
                        continue
                    if kind == "ok":
                        attempts.success(self._on_node(payload, node))
                    else:
                        attempts.failure(index, payload, retry=kind != "fatal")
        except ClusterLost:
            # Nothing more can be asked of a cluster without its head (cancel and shutdown would wait for it).
            self.used["lost"] = True
            raise
        finally:
            if self.used.get("lost"):
                pass
            elif pending and sys.exc_info()[0] is not None:  # interrupted: keep what has finished already
                try:
                    for ref in ray.wait(list(pending), num_returns=len(pending), timeout=0)[0]:
                        pending.pop(ref)
                        kind, payload, node = ray.get(ref, timeout=1)
                        if kind == "ok":
                            attempts.success(self._on_node(payload, node))
                except Exception:  # best effort: an unrecorded object is simply rendered again on resume
                    pass
            for ref in pending if not self.used.get("lost") else ():
                try:
                    ray.cancel(ref, force=True)
                except Exception:  # already finished or the cluster is gone
                    pass
            if connected and not self.used.get("lost"):
                ray.shutdown()

    def _check_head(self) -> None:
        """Raise ClusterLost when the head of the cluster joined (an explicit --ray address, or RAY_ADDRESS that
        'auto' joined) no longer answers."""
        joined = self.address if self.address not in (None, "auto") else (
            None if self.used.get("started_local") else os.environ.get("RAY_ADDRESS"))
        if not joined or _host_port(joined) is None:
            return  # a local Ray: it lives and dies with this machine
        try:
            probe_address(joined, timeout=ALIVE_TIMEOUT_S)
        except ConnectionError as exc:
            raise ClusterLost(f"--ray: the Ray cluster at {joined!r} stopped answering mid-run "
                              f"({getattr(exc, 'why', exc)}); the "
                              "objects finished so far are kept in --out (manifest.json): run the same command "
                              "again to render the rest, on a running cluster or without --ray") from None

    def _on_node(self, entry: dict, node: dict) -> dict:
        """The manifest entry of an object with the node that rendered it; the node counted in `used['nodes']`."""
        seen = self.used.setdefault("nodes", {}).setdefault(node["id"], {"host": node["host"], "ip": node["ip"],
                                                                       "objects": 0})
        seen["objects"] += 1
        return {**entry, "node": node["id"]}
