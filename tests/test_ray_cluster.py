"""`wildgen.make --ray ADDRESS` on a real Ray cluster of two nodes on this machine, made as docs/generator.md
("Scaling out") tells a user to: `ray start --head` and `ray start --address HEAD:PORT`, each node its own
process group, temporary folder and one CPU, with Ray's token authentication on (as Ray 2.60 turns it on at a
head where a token exists), so every node and the driver carry RAY_AUTH_MODE=token and the token file.

Checked: the objects are spread over both nodes and the manifest says which node rendered which; the dataset is
byte for byte the dataset of a local run with worker processes; killing the second node (SIGKILL to its whole
process group: raylet, its workers, its agents) while it is inside an object still ends in the complete,
identical dataset, retried on the head, with no temporary folder left; a driver without the token is one line.
Nothing is mocked: the nodes are Ray's own processes; the driver is the CLI in a subprocess.
"""
from __future__ import annotations

import json
import os
import secrets
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import pytest

pytest.importorskip("ray")

from fixtures import REPO, assert_same_dataset, interruptible, make_cli, make_command  # noqa: E402

pytestmark = pytest.mark.slow


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _processes_under(temp: Path) -> list[int]:
    """Processes whose command line names the node's temporary folder (Ray's own, started by this test)."""
    found = []
    for proc in Path("/proc").glob("[0-9]*"):
        try:
            if str(temp).encode() in (proc / "cmdline").read_bytes():
                found.append(int(proc.name))
        except OSError:
            continue
    return found


def _parents() -> dict[int, tuple[int, int]]:
    """pid -> (parent pid, process group) of every living process (zombies left out)."""
    found = {}
    for proc in Path("/proc").glob("[0-9]*"):
        try:
            fields = (proc / "stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if fields[0] not in ("Z", "X"):
            found[int(proc.name)] = (int(fields[1]), int(fields[2]))
    return found


@dataclass
class Node:
    """One `ray start --block` in its own process group. Its processes: that group and their descendants (the
    raylet puts each worker process in a group of its own)."""

    proc: subprocess.Popen
    temp: Path
    log: Path

    def processes(self) -> set[int]:
        table = _parents()
        mine = {pid for pid, (_, group) in table.items() if group == self.proc.pid}
        grew = True
        while grew:
            more = {pid for pid, (parent, _) in table.items() if parent in mine} - mine
            mine |= more
            grew = bool(more)
        return mine

    def kill(self) -> None:
        """SIGKILL every process of the node at once: as if its machine went away."""
        for pid in self.processes():
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        self.proc.wait(30)


def start_node(args: list[str], env: dict, timeout: float = 120) -> Node:
    """Start a Ray node with `ray start --block ARGS` (its own short temporary folder: Ray's socket paths must stay
    under 108 characters) and wait until it says it runs."""
    temp = Path(tempfile.mkdtemp(prefix="rc", dir="/tmp"))
    log = temp.with_suffix(".log")
    ray_cli = [sys.executable, "-m", "ray.scripts.scripts"]
    with open(log, "w") as out:
        proc = subprocess.Popen(
            [
                *ray_cli,
                "start",
                "--block",
                *args,
                "--num-cpus",
                "1",
                "--node-ip-address",
                "127.0.0.1",
                "--temp-dir",
                str(temp),
                "--object-store-memory",
                str(128 * 2**20),
                "--disable-usage-stats",
            ],
            env=env,
            stdout=out,
            stderr=subprocess.STDOUT,
            start_new_session=True,
        )
    node = Node(proc, temp, log)
    t0 = time.monotonic()
    while "Ray runtime started" not in log.read_text():
        if proc.poll() is not None or time.monotonic() - t0 > timeout:
            text = log.read_text()[-3000:]
            node.kill()
            raise AssertionError(f"ray start {' '.join(args)} did not start:\n{text}")
        time.sleep(0.2)
    return node


@dataclass
class Cluster:
    address: str
    env: dict  # what every node and the driver need: RAY_AUTH_MODE=token and the token's file
    head: Node
    second: Node
    ids: dict  # Ray's node id of each: {"head": id, "second": id}


NODE_IDS = """
import json, ray
ray.init(address="{address}", logging_level="ERROR")
print(json.dumps({{("second" if "second_node" in n["Resources"] else "head"): n["NodeID"]
                  for n in ray.nodes() if n["Alive"]}}))
"""


@pytest.fixture(scope="module")
def cluster(tmp_path_factory):
    token = tmp_path_factory.mktemp("auth") / "auth_token"
    token.write_text(secrets.token_hex(32))
    env = {**os.environ, "RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN_PATH": str(token), "RAY_USAGE_STATS_ENABLED": "0",
           "PYTHONPATH": str(REPO)}
    env.pop("RAY_ADDRESS", None)
    port = _free_port()
    head = start_node(["--head", "--port", str(port), "--include-dashboard", "false"], env)
    nodes = [head]
    try:
        nodes.append(start_node(["--address", f"127.0.0.1:{port}", "--resources", '{"second_node": 1}'], env))
        address = f"127.0.0.1:{port}"
        r = subprocess.run([sys.executable, "-c", NODE_IDS.format(address=address)], env=env, capture_output=True,
                           text=True, timeout=120)
        ids = json.loads(r.stdout.strip().splitlines()[-1])
        assert set(ids) == {"head", "second"}, r.stderr[-2000:]
        yield Cluster(address, env, head, nodes[1], ids)
    finally:
        for node in reversed(nodes):
            node.kill()
            for pid in _processes_under(node.temp):  # none expected: a node's processes stay in its group
                os.kill(pid, signal.SIGKILL)
            shutil.rmtree(node.temp, ignore_errors=True)
            node.log.unlink(missing_ok=True)


@pytest.fixture(scope="module")
def reference(tmp_path_factory) -> Path:
    """The same dataset made on this machine alone, with 2 local worker processes."""
    out = tmp_path_factory.mktemp("cluster_ref") / "ds"
    r = make_cli(out, "--workers", "2")
    assert r.returncode == 0, r.stderr
    return out


def run_on(cluster: Cluster, out: Path, timeout: float = 600) -> subprocess.CompletedProcess:
    return subprocess.run(make_command(out, "--ray", cluster.address), cwd=REPO, env=cluster.env, capture_output=True,
                          text=True, timeout=timeout)


def nodes_of(out: Path) -> tuple[list[str], dict]:
    """Each object's node (manifest order) and the run's record of the nodes."""
    manifest = json.loads((out / "manifest.json").read_text())
    return [e["node"] for e in manifest["objects"]], manifest["run"]["nodes"]


def test_objects_spread_over_both_nodes_and_the_bytes_are_a_local_runs(cluster, reference, tmp_path):
    out = tmp_path / "ds"
    r = run_on(cluster, out)
    assert r.returncode == 0, r.stderr
    assert "ray, 2 CPUs" in r.stdout
    per_object, nodes = nodes_of(out)
    assert set(per_object) == set(cluster.ids.values()), per_object  # both nodes rendered objects
    assert set(nodes) == set(per_object)
    print(
        "objects per node:",
        {("head" if k == cluster.ids["head"] else "second"): v["objects"] for k, v in nodes.items()},
    )
    assert sorted(n["objects"] for n in nodes.values()) == sorted(per_object.count(k) for k in nodes)
    assert_same_dataset(reference, out)


def test_a_driver_without_the_token_is_one_line(cluster, tmp_path):
    env = {k: v for k, v in cluster.env.items() if not k.startswith("RAY_AUTH")}
    r = subprocess.run(make_command(tmp_path / "ds", "--ray", cluster.address), cwd=REPO, env=env, capture_output=True,
                       text=True, timeout=300)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, lines
    assert lines[0].startswith(f"error: --ray: cannot join the Ray cluster at '{cluster.address}'")
    print(lines[0])
    assert "RAY_AUTH_MODE=token" in lines[0] and "Traceback" not in r.stderr
    assert not list((tmp_path / "ds").glob("*.data"))


def busy_on(node: Node, out: Path, driver: subprocess.Popen, timeout: float = 300) -> str:
    """Stop (SIGSTOP) a Ray worker of `node` while it is inside an object (its temporary folder, named with its
    pid, exists); the object's folder name."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < timeout and driver.poll() is None:
        workers = node.processes()
        for tmp in out.glob(".tmp-*.data.*"):
            pid = int(tmp.name.rsplit(".", 1)[1])
            if pid not in workers:
                continue
            try:
                os.kill(pid, signal.SIGSTOP)
            except ProcessLookupError:
                continue
            if tmp.exists():
                return tmp.name[len(".tmp-"):].rsplit(".", 1)[0]
            os.kill(pid, signal.SIGCONT)
        time.sleep(0.005)
    raise AssertionError("no worker of the second node caught inside an object")


def test_killing_a_node_mid_object_ends_in_the_same_dataset(cluster, reference, tmp_path):
    """Runs last in this module: the second node does not come back."""
    out = tmp_path / "ds"
    proc = subprocess.Popen(make_command(out, "--ray", cluster.address), cwd=REPO, env=cluster.env, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, preexec_fn=interruptible)
    try:
        caught = busy_on(cluster.second, out, proc)
        cluster.second.kill()  # the node's raylet, its workers and agents: as if the machine went away
        time.sleep(0.5)
        assert not cluster.second.processes()
        stdout, stderr = proc.communicate(timeout=600)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, stderr
    assert "attempt 1 failed" in stderr  # the object the node was rendering was tried again
    print("killed the second node inside", caught, "->", next(x for x in stderr.splitlines() if "attempt 1" in x)[:300])
    assert not list(out.glob(".tmp-*"))
    assert_same_dataset(reference, out)
    manifest = json.loads((out / "manifest.json").read_text())
    node_of = {e["folder"]: e["node"] for e in manifest["objects"]}
    assert node_of[caught] == cluster.ids["head"]  # the object the dead node held was rendered again on the head
    assert set(node_of.values()) <= set(cluster.ids.values())


def test_losing_the_whole_cluster_mid_run_is_one_line_and_the_run_resumes(cluster, reference, tmp_path):
    """Runs after the second node's death: the head too goes away while objects are being made. One line naming
    --ray, status 1, within seconds (Ray itself would wait 60 s and end the process with a log line of its own); the
    objects finished by then are recorded, and the same command without --ray makes the rest: the same dataset."""
    out = tmp_path / "ds"
    proc = subprocess.Popen(make_command(out, "--ray", cluster.address), cwd=REPO, env=cluster.env, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, preexec_fn=interruptible)
    try:
        t0 = time.monotonic()
        while not list(out.glob("*.data")) and proc.poll() is None and time.monotonic() - t0 < 300:
            time.sleep(0.1)
        cluster.head.kill()
        killed = time.monotonic()
        _, stderr = proc.communicate(timeout=120)
        waited = time.monotonic() - killed
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 1, stderr
    lines = [line for line in stderr.strip().splitlines() if "attempt 1 failed" not in line]
    assert len(lines) == 1 and lines[0].startswith(f"error: --ray: the Ray cluster at '{cluster.address}' stopped "
                                                   "answering mid-run"), stderr
    assert waited < 45, waited
    finished = json.loads((out / "manifest.json").read_text())["objects"]
    assert all((out / e["folder"]).is_dir() for e in finished)
    r = make_cli(out, "--workers", "0")
    assert r.returncode == 0, r.stderr
    assert f"{len(finished)} already complete" in r.stdout
    assert_same_dataset(reference, out)
