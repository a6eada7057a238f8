"""Inference as a library: build or load a network, run it on a `PSObject`, or run a classical baseline.

    from unips.inference import create_model, load_network, predict_object

    model = create_model("glc-tiny", pretrained=True)             # the shipped weights, eval mode
    model = create_model("glc-tiny", checkpoint="best.safetensors")  # any weights file of that model
    net = load_network(None)                                       # shipped weights + where they came from
    normals = predict_object(obj, "model", net=net)                # (H, W, 3), zero outside the mask

`create_model` follows timm's `create_model(name, pretrained=..., checkpoint_path=...)`: without weights it
is `unips.models.create_model` (random initialisation). Weights files are read by
`unips.checkpoint.load_model` (a `.safetensors` with its `.json`, or a training `.pt`); a file whose
config or tensor shapes do not match is refused. The CLI `unips.predict` and `orchestrate.benchmark` use
this module; nothing here parses arguments or writes files.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from scenes.cli import UsageError
from unips.data import PSObject

METHODS = ("model", "least-squares", "sh-uncalibrated")
DEFAULT_WEIGHTS = "weights/glc-tiny.safetensors"  # inside the unips package
SHIPPED = {"glc-tiny": DEFAULT_WEIGHTS}
"""Model names with shipped weights (`pretrained=True`)."""


def default_checkpoint(name: str = "glc-tiny") -> Path:
    """Path of the shipped weights of `name` (default: the shipped model); UsageError when they are not
    shipped (yet)."""
    from importlib import resources

    if name not in SHIPPED:
        raise ValueError(f"pretrained: no shipped weights for {name!r} (shipped: {', '.join(SHIPPED)})")
    ref = resources.files("unips").joinpath(SHIPPED[name])
    if not ref.is_file():
        raise UsageError(f"no shipped weights yet (unips/{SHIPPED[name]} is missing); "
                         "pass --checkpoint PATH to a .safetensors or .pt model file")
    return Path(str(ref))


@dataclass
class LoadedModel:
    """A network ready for inference and where it came from."""

    model: Any  # torch.nn.Module in eval mode on `device`
    meta: dict[str, Any]  # from unips.checkpoint.load_model
    checkpoint: Path  # the file it was loaded from
    device: str  # torch device string


def load_network(checkpoint: str | Path | None, device: str = "cpu") -> LoadedModel:
    """Load a model file (or the shipped default when `checkpoint` is None) onto `device`."""
    import torch

    from unips.checkpoint import load_model

    if device.startswith("cuda") and not torch.cuda.is_available():
        raise UsageError(f"--device {device}: CUDA is not available on this machine")
    path = Path(checkpoint) if checkpoint is not None else default_checkpoint()
    model, meta = load_model(path, map_location=device)
    return LoadedModel(model=model.eval(), meta=dict(meta), checkpoint=path, device=device)


def create_model(name: str, pretrained: bool = False, checkpoint: str | Path | None = None,
                 device: str = "cpu", **overrides: Any):
    """A network by registry name (timm style).

    checkpoint: a weights file of this model (its recorded name must be `name`), loaded in eval mode;
    pretrained: the shipped weights of `name`; neither: fresh weights with config `overrides`.
    """
    if checkpoint is not None or pretrained:
        if overrides:
            raise ValueError(f"overrides {sorted(overrides)}: not allowed with weights (the file holds the config)")
        net = load_network(checkpoint if checkpoint is not None else default_checkpoint(name), device)
        got = net.meta.get("model_name")
        if got is not None and got != name:
            raise ValueError(f"checkpoint: {str(net.checkpoint)!r} holds model {got!r}, not {name!r}")
        return net.model
    from unips.models import create_model as build

    return build(name, **overrides).to(device)


def run_model(net: LoadedModel, obj: PSObject, res: int | None = None, margin: int = 4) -> np.ndarray:
    """Normals (H, W, 3) of `obj` from the network, in the original frame, zero outside the mask."""
    import torch

    from unips.preprocess import prepare, resize_prepared, uncrop

    prepared = prepare(obj, margin=margin)
    work = resize_prepared(prepared, res) if res is not None else prepared
    images = torch.from_numpy(np.ascontiguousarray(work.images.transpose(0, 3, 1, 2)))[None]  # (1, K, 3, R, R)
    mask = torch.from_numpy(work.mask.astype(np.float32))[None, None]  # (1, 1, R, R)
    with torch.no_grad():
        out = net.model(images.to(net.device), mask.to(net.device))  # (1, 3, R, R)
    if tuple(out.shape) != (1, 3) + work.mask.shape:
        raise ValueError(f"model: returned shape {tuple(out.shape)}, expected (1, 3, {work.resolution}, "
                         f"{work.resolution})")
    n = out[0].permute(1, 2, 0).float().cpu().numpy()  # (R, R, 3)
    if not np.all(np.isfinite(n)):
        raise ValueError(f"model: produced non-finite normals for {obj.name}")
    norm = np.linalg.norm(n, axis=2, keepdims=True)
    n = np.where(work.mask[..., None] & (norm > 1e-8), n / np.maximum(norm, 1e-12), 0.0).astype(np.float32)
    return uncrop(n, prepared.crop, mask=obj.mask)


def predict_object(obj: PSObject, method: str, net: LoadedModel | None = None,
                   res: int | None = None) -> np.ndarray:
    """(H, W, 3) unit normals of `obj` by `method` (zero outside the mask)."""
    if method == "model":
        if net is None:
            raise ValueError("net: --method model needs a loaded network")
        return run_model(net, obj, res=res)
    from unips.baselines import run_baseline

    return run_baseline(method, obj)
