"""Training checkpoints (.pt): everything needed to resume a run exactly.

A training checkpoint (`torch.save`, loadable with `weights_only=True`) holds the model description and
state, optimizer and scheduler state, the step, the torch / numpy / python RNG states, a description of
the data and the git revision. The model files themselves (shipping `.safetensors` + `.json`, and reading
the model out of a `.pt`) are `unips.models.builder`'s; their names are importable from here too.
"""

from __future__ import annotations

import random
import subprocess
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import torch
from torch import nn

from scenes.files import atomic_write
from unips.models.builder import (
    CHECKSUM_KEY,
    TRAINING_FORMAT,
    WEIGHTS_FORMAT,
    content_digest,
    load_model,
    load_state_strict,
    load_training_checkpoint,
    model_description,
    save_checkpoint,
    sidecar_path,
)

__all__ = ["TRAINING_FORMAT", "WEIGHTS_FORMAT", "git_revision", "load_model", "load_state_strict",
           "load_training_checkpoint", "model_description", "rng_states", "save_checkpoint",
           "restore_training_state", "save_training_checkpoint", "set_rng_states", "sidecar_path"]


def git_revision(repo: str | Path | None = None) -> str:
    """`git rev-parse HEAD` of the repository holding this file, or "unknown"."""
    cwd = Path(repo) if repo is not None else Path(__file__).resolve().parent
    try:
        out = subprocess.run(["git", "rev-parse", "HEAD"], cwd=cwd, capture_output=True, text=True,
                             timeout=10, check=False)
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    rev = out.stdout.strip()
    return rev if out.returncode == 0 and rev else "unknown"


# -- training checkpoints -------------------------------------------------------------------

def rng_states() -> dict[str, Any]:
    """torch / numpy / python global RNG states as tensors and plain containers."""
    np_state = np.random.get_state()
    py_state = random.getstate()
    return {
        "torch": torch.get_rng_state(),
        "numpy": {"name": np_state[0], "keys": torch.from_numpy(np_state[1].astype(np.int64)),
                  "pos": int(np_state[2]), "has_gauss": int(np_state[3]), "gauss": float(np_state[4])},
        "python": {"version": py_state[0], "state": list(py_state[1]), "gauss": py_state[2]},
    }


def set_rng_states(states: Mapping[str, Any]) -> None:
    """Inverse of `rng_states`."""
    torch.set_rng_state(states["torch"])
    n = states["numpy"]
    np.random.set_state((n["name"], n["keys"].numpy().astype(np.uint32), n["pos"], n["has_gauss"], n["gauss"]))
    p = states["python"]
    random.setstate((p["version"], tuple(p["state"]), p["gauss"]))


SCHEDULE_PROGRESS = ("last_epoch", "_step_count", "_last_lr", "_get_lr_called_within_step", "_is_initial")
"""The scheduler's entries that move with the steps; every other one is what the run's flags build."""


def _same(a: Any, b: Any) -> bool:
    """Equal as plain values (a tuple and a list of equal items are equal; NaN equals nothing)."""
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    return type(a) is type(b) and a == b


def _finite_rate(x: Any) -> bool:
    return isinstance(x, float) and np.isfinite(x) and x >= 0


def restore_training_state(path: str | Path, ckpt: Mapping[str, Any], optimizer: torch.optim.Optimizer,
                           scheduler: Any) -> None:
    """Load a training checkpoint's optimiser, schedule and random states into a run's fresh `optimizer` and
    `scheduler`, each checked first against what the run's own flags built them with (a resumed run's flags equal
    the checkpoint's): every hyperparameter of the optimiser's groups and of the schedule equal to the fresh ones,
    the current learning rates finite numbers >= 0, the moments finite. A hand-edited or damaged checkpoint (a NaN
    base rate, a rate written as text, beta2 of 2) would train NaN weights or fail deep in the optimiser: a
    ValueError naming `path` instead."""
    where = f"--resume: {str(path)!r}"
    damaged = "; the checkpoint is damaged: restore it, or start the run again with --overwrite"
    opt = ckpt.get("optimizer")
    groups, state = (opt.get("param_groups"), opt.get("state")) if isinstance(opt, dict) else (None, None)
    fresh = optimizer.state_dict()["param_groups"]
    if not isinstance(groups, list) or not isinstance(state, dict) or len(groups) != len(fresh) or not all(
            isinstance(g, dict) for g in groups):
        raise ValueError(f"{where}: its optimiser state is not this run's optimiser's ({len(fresh)} parameter "
                         f"group(s)){damaged}")
    for i, (g, f) in enumerate(zip(groups, fresh)):
        for key, value in f.items():
            if key == "params" or key not in g:
                continue
            if not (_finite_rate(g[key]) if key == "lr" else _same(g[key], value)):
                raise ValueError(f"{where}: optimiser group {i} holds {key} = {g[key]!r:.40}, expected "
                                 f"{'a finite rate >= 0' if key == 'lr' else repr(value)} (what the run's flags give)"
                                 f"{damaged}")
    moments = [(i, k) for i, st in state.items() if isinstance(st, dict) for k, v in st.items()
               if isinstance(v, torch.Tensor) and v.is_floating_point() and not bool(torch.isfinite(v).all())]
    if moments:  # NaN there makes every weight NaN at the first step
        raise ValueError(f"{where}: its optimiser state holds NaN or infinite values (parameter {moments[0][0]}, "
                         f"{moments[0][1]}){damaged}")
    sched, own = ckpt.get("scheduler"), scheduler.state_dict()
    bad = f"a {type(sched).__name__}, not a schedule's state" if not isinstance(sched, dict) else next(
        (f"{k} = {sched.get(k)!r:.40}, expected {v!r}" for k, v in own.items() if k not in SCHEDULE_PROGRESS and
         not _same(sched.get(k), v)), None)
    progress = sched.get("last_epoch") if isinstance(sched, dict) else None
    rates = sched.get("_last_lr", []) if isinstance(sched, dict) else []
    if bad is None and (not isinstance(progress, int) or progress < 0 or not isinstance(rates, list) or not all(
            _finite_rate(r) for r in rates)):
        bad = f"last_epoch = {progress!r:.40}, _last_lr = {rates!r:.60} (expected a step count and finite rates)"
    if bad is not None:
        raise ValueError(f"{where}: its learning-rate schedule holds {bad}{damaged}")
    try:
        optimizer.load_state_dict(opt)
        scheduler.load_state_dict(sched)
        set_rng_states(ckpt["rng"])
    except (ValueError, KeyError, TypeError, RuntimeError, IndexError, AttributeError) as exc:
        raise ValueError(f"{where}: its optimiser, schedule or random states do not fit this run "
                         f"({type(exc).__name__}: {' '.join(str(exc).split())[:160]}){damaged}") from None


def save_training_checkpoint(path: str | Path, *, model: nn.Module, optimizer: torch.optim.Optimizer,
                             scheduler: Any, step: int, data: Mapping[str, Any],
                             extra: Mapping[str, Any] | None = None) -> Path:
    """Write everything needed to resume training at `step` (atomic rename)."""
    path = Path(path)
    ckpt = {
        "format": TRAINING_FORMAT,
        **model_description(model),
        "model": {k: v.detach().cpu() for k, v in model.state_dict().items()},
        "optimizer": optimizer.state_dict(),
        "scheduler": scheduler.state_dict(),
        "step": int(step),
        "rng": rng_states(),
        "data": dict(data),
        "git_revision": git_revision(),
        "extra": dict(extra or {}),
    }
    ckpt[CHECKSUM_KEY] = content_digest(ckpt)  # compared when it is read back: a damaged byte is refused
    path.parent.mkdir(parents=True, exist_ok=True)

    def write(tmp: Path) -> None:
        try:
            torch.save(ckpt, tmp)
        except RuntimeError as exc:  # torch's zip writer reports a full disk as RuntimeError ("file write failed")
            import resource
            import shutil

            free = shutil.disk_usage(tmp.parent).free / 2**20
            first = (str(exc).splitlines() or [type(exc).__name__])[0]
            limit = resource.getrlimit(resource.RLIMIT_FSIZE)[0]  # `ulimit -f`: a file may not grow past it
            why = (f"this process may write files of at most {limit / 2**20:.1f} MiB (ulimit -f)" if limit not in
                   (resource.RLIM_INFINITY, -1) and free > 1 else f"no space left: {free:.1f} MiB free on its disk")
            detail = f" ({first:.120})" if free > 1 else ""  # torch's own words add nothing to a full disk
            raise OSError(f"could not write {str(path)!r}: {why}, not enough for the checkpoint{detail}") from None

    atomic_write(path, write)  # a kill or a full disk never leaves half a last.pt
    return path
