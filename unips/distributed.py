"""This process's place in a multi-process training run (`Dist`): from the variables torchrun sets
(`distributed_env`, checked), joined to the other processes by torchrun's rendezvous (`under_torchrun`) or, for
processes started by hand with those variables, by a bounded wait (`_joined_store`)."""

from __future__ import annotations

import contextlib
import os
from dataclasses import dataclass
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from unips.train_config import TrainConfig


@dataclass
class Dist:
    """This process's place in a torchrun job (rank 0 of 1 without one)."""

    rank: int = 0
    world: int = 1
    local_rank: int = 0

    @property
    def main(self) -> bool:
        return self.rank == 0


TORCHRUN_VARIABLES = ("WORLD_SIZE", "RANK", "LOCAL_RANK", "MASTER_ADDR", "MASTER_PORT")
"""What torchrun sets for each process of a multi-process run (`distributed_env` checks them)."""


def distributed_env() -> Dist:
    """This process's place in a torchrun run, from the variables torchrun sets (a single process without them);
    one ValueError naming the variable where they are not integers in range or one is missing."""
    env = os.environ

    def number(name: str, default: str, low: int) -> int:
        text = env.get(name, default)
        if not (text.strip().isascii() and text.strip().isdigit()):  # int() would take '1_0', ' +1'; not '²'
            raise ValueError(f"environment variable {name}={text!r}: expected an integer (torchrun sets it)")
        value = int(text)
        if value < low:
            raise ValueError(f"environment variable {name}={text!r}: expected {low} or more")
        return value

    world = number("WORLD_SIZE", "1", 1)
    rank, local = number("RANK", "0", 0), number("LOCAL_RANK", "0", 0)
    if world > 1 and (missing := [v for v in TORCHRUN_VARIABLES if v not in env]):
        raise ValueError(f"environment variable WORLD_SIZE={world} without {', '.join(missing)}: start a "
                         "multi-process run with torchrun, which sets them all")
    for name, value in (("RANK", rank), ("LOCAL_RANK", local)):  # a process's place lies inside the run
        if value >= world:
            raise ValueError(f"environment variable {name}={value}: expected below WORLD_SIZE={world}")
    if local > rank:  # RANK = node x processes per node + LOCAL_RANK: never below it
        raise ValueError(f"environment variable LOCAL_RANK={local}: expected at most RANK={rank} (a process's rank "
                         "on its node is a part of its rank in the run; torchrun sets both)")
    if world > 1 and not env["MASTER_ADDR"].strip():  # torch's store would print a C++ trace, then time out
        raise ValueError("environment variable MASTER_ADDR='': expected the host of rank 0 (torchrun sets it)")
    if world > 1 and not 1 <= number("MASTER_PORT", "0", 0) <= 65535:
        raise ValueError(f"environment variable MASTER_PORT={env['MASTER_PORT']!r}: expected a port, 1 to 65535")
    return Dist(rank, world, local) if world > 1 else Dist()


def init_distributed(cfg: TrainConfig) -> Dist:
    d = distributed_env()
    if d.world <= 1:
        return d
    import torch.distributed as dist

    rank, world, local = d.rank, d.world, d.local_rank
    if cfg.batch % world:
        raise ValueError(f"--batch={cfg.batch}: expected a multiple of the {world} torchrun processes")
    if not dist.is_initialized():
        backend = "nccl" if cfg.device.startswith("cuda") else "gloo"
        if under_torchrun():  # torchrun's rendezvous gathered the processes already
            dist.init_process_group(backend=backend)
        else:
            dist.init_process_group(backend=backend, store=_joined_store(rank, world), rank=rank, world_size=world)
    return Dist(rank, world, local)


TORCHRUN_AGENT = ("TORCHELASTIC_RUN_ID", "TORCHELASTIC_RESTART_COUNT", "GROUP_RANK", "LOCAL_WORLD_SIZE")
"""Variables torchrun's agent sets beside `TORCHRUN_VARIABLES`: all of them, a process torchrun started."""


def under_torchrun() -> bool:
    """Whether torchrun started this process (its rendezvous gathered the run; it supervises the process). One of
    its variables copied by hand into a lone process is not torchrun: that process joins by `_joined_store`'s
    bounded wait, under the toolkit's own supervisor (torch's rendezvous would wait 30 minutes, silently)."""
    return all(os.environ.get(v) for v in TORCHRUN_AGENT)


JOIN_TIMEOUT_S = 300.0
"""How long processes started by hand (the torchrun variables set without torchrun) wait for one another before
the run is refused; `UNIPS_JOIN_TIMEOUT_S` sets it. Under torchrun its own rendezvous waits instead."""


def _joined_store(rank: int, world: int):
    """The process group's store once all `world` processes reached MASTER_ADDR:MASTER_PORT; a ValueError naming
    the variables after the bounded wait (torch's default is to wait 30 minutes, silently)."""
    from datetime import timedelta

    import torch.distributed as dist

    env = os.environ
    text = env.get("UNIPS_JOIN_TIMEOUT_S", str(JOIN_TIMEOUT_S))
    try:
        wait = float(text)
        if not 0 < wait < 1e6:
            raise ValueError
    except ValueError:
        raise ValueError(f"environment variable UNIPS_JOIN_TIMEOUT_S={text!r}: expected seconds, above 0") from None
    where = f"MASTER_ADDR={env['MASTER_ADDR']} MASTER_PORT={env['MASTER_PORT']}"
    try:
        with _native_stderr_held():
            store = dist.TCPStore(env["MASTER_ADDR"], int(env["MASTER_PORT"]), world, is_master=rank == 0,
                                  timeout=timedelta(seconds=wait), wait_for_workers=True)
    except (RuntimeError, OSError) as exc:  # DistStoreError / DistNetworkError are RuntimeErrors
        raise ValueError(f"environment variable WORLD_SIZE={world}: process RANK={rank} did not meet the other "
                         f"{world - 1} at {where} within {wait:g} s ({str(exc).splitlines()[0][:120]}); start every "
                         "rank, or start the run with torchrun (UNIPS_JOIN_TIMEOUT_S sets the wait)") from None
    store.set_timeout(timedelta(minutes=30))  # the joined run's collectives wait as long as torch's default
    return store


@contextlib.contextmanager
def _native_stderr_held():
    """Hold what torch's C++ side writes to the process's stderr (file descriptor 2) while the store is joined: each
    retry of an address that does not resolve or answer is a log line, and its failure a C++ stack trace of 30
    frames, before the one line that says what went wrong. Released (not shown) when the block ends."""
    import sys
    import tempfile

    sys.stderr.flush()
    saved = os.dup(2)
    try:
        with tempfile.TemporaryFile() as held:
            os.dup2(held.fileno(), 2)
            try:
                yield
            finally:
                os.dup2(saved, 2)
    finally:
        os.close(saved)
