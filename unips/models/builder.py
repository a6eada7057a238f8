"""Building a model: fresh, from its shipped weights, or from a model file (and the model file formats).

    from unips.models import create_model

    create_model("glc-test")                                   # fresh weights (random initialisation)
    create_model("glc-tiny", pretrained=True)                  # the shipped weights, eval mode
    create_model("glc-tiny", checkpoint_path="best.safetensors")  # any model file of that model, eval mode
    create_model("sdm-unips", checkpoint_path="checkpoint")     # the authors' published files, converted

Shipping format: `NAME.safetensors` holds the state dict; `NAME.json` next to it holds
`{"format": ..., "model_name": ..., "config": {...}, "extra": {...}}`, enough to rebuild the network with
the registry's factory and load the weights strictly. A training checkpoint (`.pt`, written by
`unips.checkpoint.save_training_checkpoint`) holds the same model description and state plus the
optimiser; `load_model` reads the model out of either.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any, Mapping

import torch
from torch import nn

from scenes.files import atomic_write, not_a_file, read_json, write_json

from .official import is_official_path, read_official
from .registry import build_model, official_entry, pretrained_weights
from .tensors import check_safetensors_header, check_stored_format, check_weights, load_torch_file

WEIGHTS_FORMAT = "unips-weights/1"
TRAINING_FORMAT = "unips-training/1"


def create_model(name: str, pretrained: bool = False, checkpoint_path: str | Path | None = None,
                 device: str | torch.device = "cpu", **overrides: Any) -> nn.Module:
    """Model `name` of the registry (timm's `create_model(name, pretrained=..., checkpoint_path=...)`).

    checkpoint_path: a model file (.safetensors with its .json, or a training .pt) whose recorded model is
    `name`, loaded in eval mode; or, for a model with an official entry, the authors' checkpoint folder (or
    its `.pytmodel` file), converted into the model's configuration (`load_official`: the files hold no
    config, so `overrides` may set what the published code takes at run time); pretrained: the shipped
    weights of `name` (the registry's pretrained entry; FileNotFoundError when they are not shipped, never
    fresh weights instead); neither: fresh weights with config `overrides` (training mode, as torch builds
    modules).
    """
    if checkpoint_path is None and not pretrained:
        return build_model(name, **overrides).to(device)
    path = Path(checkpoint_path) if checkpoint_path is not None else pretrained_weights(name)
    if is_official_path(path):
        return load_official(name, path, device, **overrides)
    if overrides:
        raise ValueError(
            f"overrides {', '.join(sorted(overrides))}: not allowed with weights (the file holds the config)"
        )
    model, meta = load_model(path, map_location=device)
    if meta.get("model_name") != name:
        raise ValueError(f"checkpoint_path: {str(path)!r} holds model {meta.get('model_name')!r}, not {name!r}")
    return model


def load_official(name: str, path: str | Path, device: str | torch.device = "cpu", **overrides: Any) -> nn.Module:
    """Model `name` with the authors' published weights read from `path` (a checkpoint folder, or its `.pytmodel`
    file when there is one), in eval mode. The files hold no configuration: `overrides` change the registered
    one, e.g. what the published code takes at run time (SDM-UniPS: canonical_resolution, pixel_samples).
    Nothing is left at random: a missing file, a missing, unexpected or misshaped tensor, a non-finite one or one of
    another kind than the model's (`unips.models.tensors.check_weights`, naming the file) is a ValueError
    (FileNotFoundError for files) of one line."""
    spec = official_entry(name)
    model = build_model(name, **overrides)
    load_state_strict(model, read_official(spec, path, model.state_dict()), f"checkpoint {str(path)!r}")
    return model.to(device).eval()


def convert_official(name: str, path: str | Path, out: str | Path, **overrides: Any) -> Path:
    """Read the published weights of `name` from `path` once and write them as our model file `out`
    (.safetensors with its .json sidecar, which `create_model(name, checkpoint_path=out)` reads)."""
    model = load_official(name, path, **overrides)
    return save_checkpoint(out, model, extra={"converted_from": str(Path(path).resolve()),
                                              "weights_source": official_entry(name).source,
                                              "weights_licence": official_entry(name).licence})


def sidecar_path(path: str | Path) -> Path:
    """JSON sidecar of a `.safetensors` weights file."""
    return Path(path).with_suffix(".json")


def model_description(model: nn.Module) -> dict[str, Any]:
    """`{"model_name", "config"}` of a registry-built model."""
    name = getattr(model, "model_name", None)
    config = getattr(model, "config", None)
    if not name or config is None:
        raise ValueError("model: expected a module built by unips.models.create_model "
                         "(with .model_name and .config)")
    return {"model_name": name, "config": dataclasses.asdict(config)}


def save_checkpoint(path: str | Path, model: nn.Module, extra: Mapping[str, Any] | None = None) -> Path:
    """Write the shipping weights `path` (.safetensors) and its JSON sidecar; returns `path`."""
    from safetensors.torch import save_file

    path = Path(path)
    if path.suffix != ".safetensors":
        raise ValueError(f"path: got {str(path)!r}, expected a file name ending in .safetensors")
    meta = {"format": WEIGHTS_FORMAT, **model_description(model), "extra": dict(extra or {})}
    path.parent.mkdir(parents=True, exist_ok=True)
    state = {k: v.detach().contiguous().cpu() for k, v in model.state_dict().items()}
    # Through temporary names and renames, so a reader never sees half a file (and a failure leaves none).
    atomic_write(path, lambda tmp: save_file(state, str(tmp), metadata={"model_name": meta["model_name"]}))
    write_json(sidecar_path(path), meta, indent=2, sort_keys=True)
    return path


def load_state_strict(model: nn.Module, state: Mapping[str, torch.Tensor], source: str = "checkpoint",
                      config: str = "its config") -> None:
    """Load `state` into `model`; missing / unexpected keys, shape mismatches, non-finite tensors and tensors of
    another kind than the model's (an int64 weight: `unips.models.tensors.check_weights`) raise ValueError.
    `config`: where the model's config came from (a sidecar file: either file may be the wrong one)."""
    own = model.state_dict()
    missing = [k for k in own if k not in state]
    unexpected = [k for k in state if k not in own]
    if missing or unexpected:
        def names(keys: list[str]) -> str:
            return (", ".join(keys[:5]) or "none") + (f" and {len(keys) - 5} more" if len(keys) > 5 else "")

        raise ValueError(f"{source}: state does not match the model: missing tensors {names(missing)}; unexpected "
                         f"tensors {names(unexpected)}")
    check_weights(state, source, own)  # first: an entry that is no tensor has no shape to compare
    for k, v in own.items():
        if tuple(state[k].shape) != tuple(v.shape):
            raise ValueError(f"{source}: tensor {k} has shape {'x'.join(map(str, state[k].shape))} in the file but "
                             f"{'x'.join(map(str, v.shape))} in the model built from {config}")
    model.load_state_dict(state, strict=True)


def _build(meta: Mapping[str, Any], source: str) -> nn.Module:
    if not isinstance(meta, Mapping):
        raise ValueError(f"{source}: expected a JSON object with model_name and config, got {type(meta).__name__}")
    for key in ("model_name", "config"):
        if key not in meta:
            raise ValueError(f"{source}: missing key {key!r} (expected model_name and config)")
    if not isinstance(meta["config"], Mapping):
        raise ValueError(f"{source}: 'config' must be a JSON object, got {type(meta['config']).__name__}")
    try:
        model = build_model(meta["model_name"], **meta["config"])
    except (TypeError, KeyError, ValueError) as exc:  # unknown model name, config keys or values
        raise ValueError(f"{source}: cannot build model {meta['model_name']!r} from its config ({exc})") from None
    except (MemoryError, RuntimeError) as exc:  # a config asking for more memory than the machine has
        raise ValueError(f"{source}: the network its config describes cannot be built here ({_first_line(exc)}); "
                         "expected the config the weights were trained with") from None
    import dataclasses

    if missing := [f.name for f in dataclasses.fields(model.config) if f.name not in meta["config"]]:
        raise ValueError(f"{source}: its config lacks {missing[0]!r}" + (f" (and {len(missing) - 1} more)" if
                         len(missing) > 1 else "") + "; expected every field the weights were trained with (a "
                         "default need not be theirs), as this toolkit writes them")
    return model


def _first_line(exc: BaseException) -> str:
    """`Type: first line` of a decoder's exception; torch's advice about `weights_only` (never to be followed
    for an untrusted file) is left out."""
    text = str(exc).strip().splitlines()
    if not text or "weights_only" in text[0]:
        return type(exc).__name__
    return f"{type(exc).__name__}: {text[0][:160]}"


def load_model(path: str | Path, map_location: str | torch.device = "cpu") -> tuple[nn.Module, dict[str, Any]]:
    """Rebuild a model from shipping weights (.safetensors + .json) or a training checkpoint (.pt).

    Returns `(model in eval mode, meta)`; meta holds model_name, config and extra (and, for a
    training checkpoint, step, data and git_revision).
    """
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"model file {str(path)!r} is a folder; expected a weights file (.safetensors or .pt)")
    if why := not_a_file(path):
        raise FileNotFoundError(f"model file {str(path)!r} {why}")
    if path.suffix == ".pt":
        ckpt = load_training_checkpoint(path, map_location=map_location)
        model = _build(ckpt, str(path))
        load_state_strict(model, ckpt["model"], str(path))
        meta = {k: ckpt[k] for k in ("model_name", "config", "step", "data", "git_revision", "extra") if k in ckpt}
        return model.to(map_location).eval(), meta
    if path.suffix != ".safetensors":
        raise ValueError(f"path: got {str(path)!r}, expected a .safetensors or .pt file")
    check_stored_format(path, "safetensors")
    side = sidecar_path(path)
    if why := not_a_file(side):
        raise FileNotFoundError(f"model sidecar {str(side)!r} {why} (needed next to {str(path)!r})")
    try:
        meta = read_json(side)
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ValueError(f"{str(side)!r}: not valid JSON ({exc})") from exc
    if isinstance(meta, Mapping) and "format" in meta and meta["format"] != WEIGHTS_FORMAT:
        raise ValueError(f"{str(side)!r}: format {meta['format']!r}; this toolkit reads {WEIGHTS_FORMAT!r} (a newer "
                         "toolkit wrote it?)")
    from safetensors import safe_open

    model = _build(meta, str(side))
    check_safetensors_header(path)
    try:
        with safe_open(str(path), "pt", device=str(map_location)) as f:  # tensors and their record, in one opening
            state = {k: f.get_tensor(k) for k in f.keys()}
            written = (f.metadata() or {}).get("model_name")  # the weights' own name of their network
    except Exception as exc:  # safetensors raises its own error type (and others) for corrupt files
        raise ValueError(f"{str(path)!r}: not a readable .safetensors weights file ({_first_line(exc)})") from exc
    if written is not None and written != meta["model_name"]:
        raise ValueError(f"{str(side)!r} says model {meta['model_name']!r}, but {str(path)!r} holds the weights of "
                         f"{written!r}: the sidecar belongs to other weights")
    load_state_strict(model, state, str(path), config=f"the config of {str(side)!r}")
    return model.to(map_location).eval(), meta


CHECKSUM_KEY = "checksum"
"""The training checkpoint's record of its own contents (`content_digest`), written last and compared on reading."""


def content_digest(ckpt: Mapping[str, Any]) -> str:
    """SHA-256 of a training checkpoint's contents (every tensor's dtype, shape and bytes, every other value's
    repr, in key order; the checksum itself left out): one flipped bit of a weight, an optimiser moment or a
    random state changes it. Torch's own reader checks none of these bytes."""
    import hashlib

    h = hashlib.sha256()

    def walk(value: Any) -> None:
        if isinstance(value, torch.Tensor):
            t = value.detach().cpu().contiguous()
            h.update(f"T{t.dtype}{tuple(t.shape)}".encode())
            h.update(t.reshape(-1).view(torch.uint8).numpy().tobytes() if t.numel() else b"")
        elif isinstance(value, Mapping):
            h.update(b"{")
            for k in sorted(value, key=str):
                if k != CHECKSUM_KEY:
                    h.update(repr(k).encode())
                    walk(value[k])
            h.update(b"}")
        elif isinstance(value, (list, tuple)):
            h.update(b"[")
            for v in value:
                walk(v)
            h.update(b"]")
        else:
            h.update(repr(value).encode())

    walk(ckpt)
    return h.hexdigest()


def load_training_checkpoint(path: str | Path, map_location: str | torch.device = "cpu") -> dict[str, Any]:
    """Read a training checkpoint written by `unips.checkpoint.save_training_checkpoint`, checked against the
    checksum of its contents it holds (one written before checksums has none) and for non-finite weights."""
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"training checkpoint {str(path)!r} is a folder; expected a .pt file")
    if why := not_a_file(path):
        raise FileNotFoundError(f"training checkpoint {str(path)!r} {why}")
    check_stored_format(path, "torch")
    ckpt = load_torch_file(path, "training checkpoint", map_location)
    if not isinstance(ckpt, dict) or ckpt.get("format") != TRAINING_FORMAT:
        raise ValueError(f"{str(path)!r}: not a training checkpoint (expected format {TRAINING_FORMAT!r})")
    missing = [k for k in ("model_name", "config", "model", "optimizer", "scheduler", "step", "rng", "data", "extra")
               if k not in ckpt]
    if missing:
        raise ValueError(f"{str(path)!r}: training checkpoint lacks {', '.join(missing)}")
    if odd := next((k for k in ("model", "data", "extra") if not isinstance(ckpt[k], dict)), None):
        raise ValueError(f"{str(path)!r}: the training checkpoint's {odd!r} is a {type(ckpt[odd]).__name__}, expected "
                         "a mapping as unips.train writes it; the checkpoint is damaged")
    try:
        digest = content_digest(ckpt) if CHECKSUM_KEY in ckpt else None
    except (NotImplementedError, RuntimeError) as exc:  # a meta tensor (no data), a sparse layout: no weights
        raise ValueError(f"{str(path)!r}: holds a tensor whose bytes cannot be read ({str(exc).splitlines()[0][:80]}); "
                         "expected a training checkpoint as unips.train writes it") from None
    if digest is not None and digest != ckpt[CHECKSUM_KEY]:
        raise ValueError(f"{str(path)!r}: the training checkpoint is damaged: its contents differ from the checksum "
                         "written with them (a changed byte); resume from a good copy or start afresh with --overwrite")
    bad = next((k for k, v in ckpt["model"].items() if torch.is_tensor(v) and v.is_floating_point()
                and not bool(torch.isfinite(v).all())), None)
    if bad is not None:
        raise ValueError(f"{str(path)!r}: the training checkpoint's weight {bad} holds NaN or infinite values; "
                         "resume from a good copy or start afresh with --overwrite")
    return ckpt
