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
TTA_VIEWS = (1, 2, 4, 8)
"""Allowed numbers of test-time augmentation views (`unips.augment.DIHEDRAL`'s first N)."""
DEFAULT_TTA = 2
"""Views by default: the object and its mirror image. The most views that keep the issue-12 prediction
budgets on 2 CPU cores (96 DiLiGenT images at full size under 60 s, 10 images at 256 px under 10 s);
on the fixed validation set 1 / 2 / 4 / 8 views gave 14.86 / 14.59 / 14.48 / 14.41 deg."""
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


def check_tta(tta: int, name: str = "tta") -> int:
    """`tta` if it is an allowed number of views, else ValueError naming `name` (a CLI passes its flag)
    and the allowed ones."""
    if isinstance(tta, bool) or not isinstance(tta, (int, np.integer)) or int(tta) not in TTA_VIEWS:
        raise ValueError(f"{name}: got {tta!r}, expected one of {', '.join(map(str, TTA_VIEWS))} (views of the object)")
    return int(tta)


def model_normals(model: Any, images: Any, mask: Any, tta: int = 1) -> Any:
    """Unnormalised mean network output `(3, R, R)` over the first `tta` views of `unips.augment.DIHEDRAL`.

    images `(K, 3, R, R)`, mask `(1, R, R)` (torch tensors on the model's device). Each view is the
    object flipped / transposed as in training; its prediction is taken back to the original frame
    (`invert_normals`) before averaging, so a network that were exactly equivariant would give its
    single-view answer. Costs `tta` forward passes.
    """
    import torch

    from unips.augment import DIHEDRAL, apply_augmentation, invert_normals

    total = None
    with torch.no_grad():
        for aug in DIHEDRAL[:check_tta(tta)]:
            x, m, _ = apply_augmentation(aug, images, mask)
            out = model(x[None], m[None])  # (1, 3, R', R')
            if tuple(out.shape) != (1, 3) + tuple(m.shape[-2:]):
                raise ValueError(f"model: returned shape {tuple(out.shape)}, expected (1, 3, "
                                 f"{m.shape[-2]}, {m.shape[-1]})")
            n = invert_normals(aug, out[0].float())
            if tta > 1:  # unit vectors before averaging: no view weighs more for a longer raw output
                n = n / n.norm(dim=0, keepdim=True).clamp_min(1e-12)
            total = n if total is None else total + n
    return total


def run_model(net: LoadedModel, obj: PSObject, res: int | None = None, margin: int = 4,
              tta: int = DEFAULT_TTA) -> np.ndarray:
    """Normals (H, W, 3) of `obj` from the network, in the original frame, zero outside the mask.

    `tta` > 1 averages the predictions of that many flipped / transposed views (`model_normals`)."""
    import torch

    from unips.preprocess import prepare, resize_prepared, uncrop

    prepared = prepare(obj, margin=margin)
    work = resize_prepared(prepared, res) if res is not None else prepared
    images = torch.from_numpy(np.ascontiguousarray(work.images.transpose(0, 3, 1, 2)))  # (K, 3, R, R)
    mask = torch.from_numpy(work.mask.astype(np.float32))[None]  # (1, R, R)
    out = model_normals(net.model, images.to(net.device), mask.to(net.device), tta)  # (3, R, R)
    n = out.permute(1, 2, 0).cpu().numpy()  # (R, R, 3)
    if not np.all(np.isfinite(n)):
        raise ValueError(f"model: produced non-finite normals for {obj.name}")
    norm = np.linalg.norm(n, axis=2, keepdims=True)
    n = np.where(work.mask[..., None] & (norm > 1e-8), n / np.maximum(norm, 1e-12), 0.0).astype(np.float32)
    return uncrop(n, prepared.crop, mask=obj.mask)


def predict_object(obj: PSObject, method: str, net: LoadedModel | None = None,
                   res: int | None = None, tta: int = DEFAULT_TTA) -> np.ndarray:
    """(H, W, 3) unit normals of `obj` by `method` (zero outside the mask); `tta`: views, model only."""
    if method == "model":
        if net is None:
            raise ValueError("net: --method model needs a loaded network")
        return run_model(net, obj, res=res, tta=tta)
    from unips.baselines import run_baseline

    return run_baseline(method, obj)
