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
           "save_training_checkpoint", "set_rng_states", "sidecar_path"]


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
