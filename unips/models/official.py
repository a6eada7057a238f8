"""The authors' published checkpoint files, read into our state dicts.

The published code saves each network (or each part of one) with `torch.save(module.state_dict())` into
`.pytmodel` files, under `torch.nn.DataParallel` (every key prefixed `module.`), and loads them with
`strict=False`, which silently keeps random weights for anything missing. Here a model's registry entry says
which files hold which part (`OfficialWeights`); they are read as tensors only (`weights_only=True`, never
arbitrary pickles), the `module.` prefix dropped, and the result must match the model exactly: a missing
file, a missing or unexpected tensor or a wrong shape is a ValueError of one line that names them.

The files are never downloaded here: users fetch them from the authors' pages (`OfficialWeights.source`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Mapping

import torch

from scenes.files import not_a_file

from .contract import InputContract
from .tensors import check_weights, load_torch_file

OFFICIAL_SUFFIX = ".pytmodel"
DATA_PARALLEL_PREFIX = "module."


@dataclass(frozen=True)
class OfficialWeights:
    """Where a registered model's published weights come from and how their files map onto its state dict."""

    files: tuple[tuple[str, str], ...]
    """(glob pattern inside the checkpoint folder, prefix our keys get) per file; each pattern must match
    exactly one file."""
    source: str
    """Where users download them (the authors' page), for messages and docs."""
    licence: str
    """The weights' licence, for messages and docs."""
    inputs: InputContract
    """What the network expects of its inputs: its authors' preprocessing and limits
    (`unips.models.contract.GLC_UNIPS_INPUTS`, `SDM_UNIPS_INPUTS`)."""


def _read_state(path: Path) -> dict[str, torch.Tensor]:
    state = load_torch_file(path, "checkpoint of tensors")
    if not isinstance(state, Mapping) or not all(isinstance(v, torch.Tensor) for v in state.values()):
        raise ValueError(f"{str(path)!r}: expected a state dict (names -> tensors), got {type(state).__name__}")
    if state and all(k.startswith(DATA_PARALLEL_PREFIX) for k in state):
        state = {k[len(DATA_PARALLEL_PREFIX):]: v for k, v in state.items()}
    return dict(state)


def official_files(spec: OfficialWeights, path: str | Path) -> list[tuple[Path, str]]:
    """The files of `spec` in the checkpoint folder `path` with their key prefixes; a `.pytmodel` file itself
    when the spec has one file. FileNotFoundError (one line) when a file is missing or ambiguous."""
    path = Path(path)
    if path.is_file() and path.suffix == OFFICIAL_SUFFIX and len(spec.files) == 1:
        return [(path, spec.files[0][1])]
    if not path.is_dir():
        raise FileNotFoundError(f"--checkpoint: {str(path)!r} is not a folder of the published weights "
                                f"(expected {', '.join(p for p, _ in spec.files)} inside; from {spec.source})")
    found = []
    for pattern, prefix in spec.files:
        matches = sorted(path.glob(pattern))
        if len(matches) != 1:
            what = "no file" if not matches else f"{len(matches)} files ({', '.join(m.name for m in matches)})"
            raise FileNotFoundError(f"--checkpoint: {what} matching {pattern!r} in {str(path)!r}, expected one "
                                    f"(the published weights from {spec.source})")
        if why := not_a_file(matches[0]):  # a pipe or a device would be read forever
            raise FileNotFoundError(f"--checkpoint: {str(matches[0])!r} {why}")
        found.append((matches[0], prefix))
    return found


def read_official(spec: OfficialWeights, path: str | Path,
                  expected: Mapping[str, torch.Tensor] | None = None) -> dict[str, torch.Tensor]:
    """The state dict in our names of the published files of `spec` under `path`, each file's tensors finite and,
    where `expected` (the model's state dict) names them, of the model's kind (`check_weights`, naming the file);
    its names and shapes are not yet checked against a model: `unips.models.builder.load_state_strict` does that."""
    state: dict[str, torch.Tensor] = {}
    for file, prefix in official_files(spec, path):
        part = {prefix + key: value for key, value in _read_state(file).items()}
        check_weights(part, repr(str(file)), expected)
        state.update(part)
    return state


def holds_published_weights(path: str | Path) -> bool:
    """Whether the folder `path` holds a published `.pytmodel` file, at its top or one folder down (SDM-UniPS's
    `normal/nml.pytmodel`)."""
    path = Path(path)
    return any(path.glob("*" + OFFICIAL_SUFFIX)) or any(path.glob("*/*" + OFFICIAL_SUFFIX))


def our_model_files(path: str | Path) -> list[Path]:
    """This toolkit's own model files (`.safetensors`, `.pt`) at the top of the folder `path` or one folder down
    (a user who named the folder of a training run, or the folder above it, rather than one of its files)."""
    path = Path(path)
    return [f for pattern in ("*", "*/*") for f in sorted(path.glob(pattern))
            if f.suffix in (".safetensors", ".pt") and f.is_file()]


def is_official_path(path: str | Path) -> bool:
    """Whether `path` names published weights (a folder or a `.pytmodel` file) rather than our model files."""
    path = Path(path)
    return path.is_dir() or path.suffix == OFFICIAL_SUFFIX
