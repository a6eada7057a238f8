"""`unips.train` under torchrun on two nodes (`--nnodes 2 --nproc-per-node 1`, both on this machine, c10d
rendezvous on the loopback, gloo) gives the same weights as one node with the same world size
(`--nnodes 1 --nproc-per-node 2`): what docs/model.md says a second machine needs and changes."""
from __future__ import annotations

import hashlib
import json
import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _train_argv(train_dataset, out: Path) -> list[str]:
    return ["-m", "unips.train", "--data", str(train_dataset["train"]), "--model", "glc-test", "--out", str(out),
            "--batch", "2", "--res", "32", "--pixels", "100", "--max-images", "4", "--threads", "1", "--no-progress",
            "--steps", "3", "--log-every", "1", "--seed", "7"]


def _launch(nodes: int, per_node: int, rank: int, endpoint: str, argv: list[str]) -> subprocess.Popen:
    cmd = [sys.executable, "-m", "torch.distributed.run", "--nnodes", str(nodes), "--nproc-per-node", str(per_node),
           "--node-rank", str(rank), "--rdzv-backend", "c10d", "--rdzv-endpoint", endpoint, "--rdzv-id", "nodes-test",
           "--local-addr", "127.0.0.1", "--max-restarts", "0", *argv]
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    return subprocess.Popen(cmd, cwd=REPO, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _finish(procs: list[subprocess.Popen]) -> None:
    try:
        outs = [p.communicate(timeout=300) for p in procs]
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
    for p, (_, err) in zip(procs, outs):
        assert p.returncode == 0, err[-2000:]


def _weights(out: Path) -> dict:
    from safetensors.torch import load_file

    return load_file(out / "final.safetensors")


@pytest.mark.slow
def test_two_nodes_give_the_weights_of_one_node_with_the_same_world_size(train_dataset, tmp_path) -> None:
    one, two = tmp_path / "one_node", tmp_path / "two_nodes"
    _finish([_launch(1, 2, 0, f"127.0.0.1:{_free_port()}", _train_argv(train_dataset, one))])
    endpoint = f"127.0.0.1:{_free_port()}"
    _finish([_launch(2, 1, rank, endpoint, _train_argv(train_dataset, two)) for rank in (0, 1)])

    logs = [[json.loads(x) for x in (o / "log.jsonl").read_text().splitlines()] for o in (one, two)]
    assert [r["step"] for r in logs[1]] == [1, 2, 3]  # rank 0 alone writes, once per step
    assert [r["loss"] for r in logs[0]] == [r["loss"] for r in logs[1]]
    a, b = _weights(one), _weights(two)
    assert a.keys() == b.keys()
    different = [k for k in a if not (a[k] == b[k]).all()]
    assert not different, different[:5]
    digests = [hashlib.sha256((o / "final.safetensors").read_bytes()).hexdigest() for o in (one, two)]
    assert digests[0] == digests[1]
