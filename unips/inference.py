"""Inference as a library: load a network, run it on a `PSObject`, or run a classical baseline.

    from unips.inference import load_network, predict_object

    net = load_network(None)                          # the shipped model's weights + where they came from
    net = load_network("best.safetensors")            # any model file (.safetensors with its .json, or .pt)
    normals = predict_object(obj, "model", net=net)   # (H, W, 3), zero outside the mask

Building a model by name (fresh, shipped or from a file) is `unips.models.create_model`; the shipped
model is `unips.models.DEFAULT_MODEL`, its weights the registry's pretrained entry. A model file whose
config or tensor shapes do not match is refused. The CLI `unips.predict` and `orchestrate.benchmark`
use this module; nothing here parses arguments or writes files.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from scenes.cli.errors import UsageError
from unips.data import PSObject

METHODS = ("model", "least-squares", "sh-uncalibrated")
TTA_VIEWS = (1, 2, 4, 8)
"""Allowed numbers of test-time augmentation views (`unips.augment.DIHEDRAL`'s first N; the same as
`unips.models.contract.VIEWS`, kept here so that this module imports without torch)."""
DEFAULT_TTA = 2
"""Views by default for our models (their contract's `views`, `unips.models.contract.UNIPS_INPUTS`; the published
networks' contracts say 1): the object and its mirror image. The most views that keep the prediction time
budgets on 2 CPU cores (96 DiLiGenT images at full size under 60 s, 10 images at 256 px under 10 s);
on the fixed validation set 1 / 2 / 4 / 8 views gave 14.86 / 14.59 / 14.48 / 14.41 deg."""


def model_contract(model: str | None) -> Any:
    """The data contract (`unips.models.InputContract`) of the registered network `model`; ours
    (`UNIPS_INPUTS`, a model file's network being read from the file later) when None."""
    if model is None:
        from unips.models.contract import UNIPS_INPUTS

        return UNIPS_INPUTS
    from unips.models import input_contract

    return input_contract(model)


@dataclass
class LoadedModel:
    """A network ready for inference and where it came from."""

    model: Any  # torch.nn.Module in eval mode on `device`
    meta: dict[str, Any]  # from unips.models.load_model
    checkpoint: Path  # the file it was loaded from
    device: str  # torch device string


    @property
    def contract(self) -> Any:
        """What it expects of its inputs (`unips.models.InputContract`), from its registry entry."""
        return model_contract(self.meta["model_name"])


def check_device(device: str, flag: str = "--device") -> None:
    """A torch device this machine can compute on (cpu, cuda, cuda:N, mps), refused in one line otherwise, before
    any work (torch would fail later, in the weights' reader or the first step, without naming the flag)."""
    import re

    import torch

    from scenes.cli.errors import UsageError

    m = re.fullmatch(r"cpu|cuda(?::(\d+))?|mps", device)
    if m is None:
        raise UsageError(f"{flag}: got {device!r}, expected cpu, cuda, cuda:N or mps")
    if device.startswith("cuda"):
        count = torch.cuda.device_count() if torch.cuda.is_available() else 0
        if count == 0 or (m[1] is not None and int(m[1]) >= count):
            raise UsageError(f"{flag}: got {device!r}, but torch sees {count} GPU(s) here; expected cpu"
                             + (f" or cuda:0 to cuda:{count - 1}" if count else ""))
    elif device == "mps" and not (hasattr(torch.backends, "mps") and torch.backends.mps.is_available()):
        raise UsageError(f"{flag}: got 'mps', but torch sees no Apple GPU here; expected cpu")


def check_model_name(model: str | None, flag: str = "--model") -> None:
    """A registered network name (or None); one UsageError naming the flag and the known models otherwise."""
    if model is None:
        return
    from unips.models import list_models  # torch: imported only when a network is named

    if model not in list_models():
        raise UsageError(f"{flag}: {model!r} is not registered; known models: {', '.join(list_models())}")


def load_network(checkpoint: str | Path | None, device: str = "cpu", model: str | None = None,
                 flag: str = "--checkpoint") -> LoadedModel:
    """Load a model file (or, when `checkpoint` is None, the shipped weights of `model`, default `DEFAULT_MODEL`)
    onto `device`. A folder (or `.pytmodel` file) of the authors' published weights needs `model`, the registered
    network that reads it (e.g. "glc-unips", "sdm-unips"); with a model file, `model` must be the file's. `flag`: the
    option that named `checkpoint`, in errors."""
    import torch

    from unips.models import DEFAULT_MODEL, create_model, load_model, pretrained_weights
    from unips.models.official import holds_published_weights, is_official_path, our_model_files

    if device.startswith("cuda") and not torch.cuda.is_available():
        raise UsageError(f"--device {device}: CUDA is not available on this machine")
    try:
        path = Path(checkpoint) if checkpoint is not None else pretrained_weights(model or DEFAULT_MODEL)
    except (KeyError, ValueError, FileNotFoundError) as exc:  # no shipped weights: said as the flag, with the way out
        raise UsageError(f"--model {model or DEFAULT_MODEL}: {str(exc).removeprefix('pretrained: ')}; give its weights "
                         "with --checkpoint") from None
    if checkpoint is not None:  # a run's checkpoint while it trains: one step of many, not the run's model
        from scenes.cli.outputs import check_not_being_written

        check_not_being_written(path, flag)
    if is_official_path(path):
        if path.is_dir() and not holds_published_weights(path):  # a run's folder, or no weights at all
            ours = our_model_files(path)
            names = ", ".join(repr(str(f.relative_to(path))) for f in ours[:3]) + (", ..." if len(ours) > 3 else "")
            hint = (f"; it holds {len(ours)} of this toolkit's model files ({names}): give one, e.g. --checkpoint "
                    f"{str(ours[0])!r}") if ours else ""
            raise UsageError(f"--checkpoint {str(path)!r} is a folder without published weights (no *.pytmodel file "
                             f"in it); expected a model file (.safetensors or .pt) or the authors' checkpoint "
                             f"folder{hint}")
        if model is None:
            raise UsageError(f"--checkpoint {str(path)!r} is a folder of published weights: name the network "
                             "that reads it with --model (--model glc-unips or sdm-unips)")
        net = create_model(model, checkpoint_path=path, device=device)
        meta = {"model_name": model, "config": dataclasses.asdict(net.config), "extra": {"published_weights": True}}
        return LoadedModel(model=net, meta=meta, checkpoint=path, device=device)
    try:
        net, meta = load_model(path, map_location=device)
    except (FileNotFoundError, ValueError) as exc:  # said as the flag the file came from
        flag = flag if checkpoint is not None else f"--model {model or DEFAULT_MODEL}"
        raise type(exc)(f"{flag}: {exc}") from None
    if model is not None and meta.get("model_name") != model:
        raise UsageError(f"--model {model}: {str(path)!r} holds model {meta.get('model_name')!r}")
    return LoadedModel(model=net.eval(), meta=dict(meta), checkpoint=path, device=device)


def load_ablation(path: str, net: LoadedModel) -> LoadedModel:
    """The --ablation-checkpoint network: the benchmarked network's kind, never the very same weights (compared
    tensor by tensor: the same tensors saved again, or as a .pt, are the same network)."""
    import torch

    ablation = load_network(path, flag="--ablation-checkpoint")
    ours, theirs = net.model.state_dict(), ablation.model.state_dict()
    if ours.keys() == theirs.keys() and all(torch.equal(ours[k], theirs[k].to(ours[k].device)) for k in ours):
        raise ValueError(f"--ablation-checkpoint: {path!r} holds the same weights as the model benchmarked "
                         f"({str(net.checkpoint)!r}): its column would repeat the model's; expected the network "
                         "trained with uniform contexts")
    if (theirs := ablation.meta.get("model_name")) != (ours := net.meta.get("model_name")):
        raise ValueError(f"--ablation-checkpoint: holds {theirs!r}, not {ours!r}, the network benchmarked; "
                         "expected the same network trained with uniform contexts")
    return ablation


def check_tta(tta: int, name: str = "tta") -> int:
    """`tta` if it is an allowed number of views, else ValueError naming `name` (a CLI passes its flag)
    and the allowed ones."""
    if isinstance(tta, bool) or not isinstance(tta, (int, np.integer)) or int(tta) not in TTA_VIEWS:
        raise ValueError(f"{name}: got {tta!r}, expected one of {', '.join(map(str, TTA_VIEWS))} (views of the object)")
    return int(tta)


def model_normals(model: Any, images: Any, mask: Any, tta: int = 1, views: list | None = None) -> Any:
    """Unnormalised mean network output `(3, R, R)` over the first `tta` views of `unips.augment.DIHEDRAL`.

    images `(K, 3, R, R)`, mask `(1, R, R)` (torch tensors on the model's device). Each view is the
    object flipped / transposed as in training; its prediction is taken back to the original frame
    (`invert_normals`) before averaging, so a network that were exactly equivariant would give its
    single-view answer. Costs `tta` forward passes. `views`, a list: each view's unit normals `(3, R, R)` in the
    original frame are appended to it (the network's disagreement with itself, `unips.expected_error`).
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
            if views is not None:
                views.append(n / n.norm(dim=0, keepdim=True).clamp_min(1e-12))
            total = n if total is None else total + n
    return total


def _weights_flag(net: LoadedModel) -> str:
    """The flag a network's weights came from, for its messages."""
    from unips.models import DEFAULT_MODEL, pretrained_weights

    try:
        shipped = net.checkpoint.resolve() == pretrained_weights(net.meta.get("model_name") or DEFAULT_MODEL).resolve()
    except (KeyError, ValueError, OSError):  # a network with no shipped weights
        shipped = False
    return f"--model {net.meta.get('model_name')}" if shipped else "--checkpoint"


def scalable_patch(net: LoadedModel) -> int:
    """The side of `net`'s `--scalable` sub-images (its contract's `patch`); UsageError when it has none."""
    if net.contract.patch is None:
        raise UsageError(f"--scalable: only for the SDM-UniPS networks (inputs 'sdm-unips'), not "
                         f"{net.meta.get('model_name')!r}")
    return net.contract.patch


def run_model(net: LoadedModel, obj: PSObject, res: int | None = None, margin: int | None = None,
              tta: int = DEFAULT_TTA, patch: int | None = None, views: list | None = None) -> np.ndarray:
    """Normals (H, W, 3) of `obj` from the network, in the original frame, zero outside the mask.

    `tta` > 1 averages the predictions of that many flipped / transposed views (`model_normals`). A model whose
    contract names a published preprocessing ("glc-unips", "sdm-unips") gets it instead (`run_published`);
    `margin`: the crop's, by default the contract's; `patch` (SDM-UniPS only): its `--scalable` sub-images' side;
    `views`, a list: each view's own map (H, W, 3) in the original frame is appended to it."""
    import torch

    from unips.preprocess import prepare, resize_prepared, uncrop

    contract = net.contract
    if patch is not None:
        scalable_patch(net)
    if contract.published:
        return run_published(net, obj, res=res, tta=tta, patch=patch, views=views)

    prepared = prepare(obj, margin=contract.margin if margin is None else margin)
    work = resize_prepared(prepared, res, "--res") if res is not None else prepared
    images = torch.from_numpy(np.ascontiguousarray(work.images.transpose(0, 3, 1, 2)))  # (K, 3, R, R)
    mask = torch.from_numpy(work.mask.astype(np.float32))[None]  # (1, R, R)
    each: list = []
    out = model_normals(net.model, images.to(net.device), mask.to(net.device), tta, each)  # (3, R, R)

    def back(t: Any) -> np.ndarray:  # (3, R, R) -> unit (H, W, 3) in the original frame
        n = t.permute(1, 2, 0).cpu().numpy()  # (R, R, 3)
        if not np.all(np.isfinite(n)):
            raise ValueError(f"{_weights_flag(net)}: the network {str(net.checkpoint)!r} produced non-finite normals "
                             f"for {obj.name} (weights that overflow on these images: damaged or not trained?)")
        norm = np.linalg.norm(n, axis=2, keepdims=True)
        n = np.where(work.mask[..., None] & (norm > 1e-8), n / np.maximum(norm, 1e-12), 0.0).astype(np.float32)
        return uncrop(n, prepared.crop, mask=obj.mask)

    if views is not None:
        views.extend(back(v) for v in each)
    return back(out)


def run_published(net: LoadedModel, obj: PSObject, res: int | None = None, tta: int = 1,
                  patch: int | None = None, rng: Any = None, views: list | None = None) -> np.ndarray:
    """Normals (H, W, 3) of `obj` through its authors' preprocessing: UniPS's (`unips.glc_preprocess`) or
    SDM-UniPS's (`unips.sdm_preprocess`); `res` replaces the published working side (for SDM-UniPS a multiple of the
    model's canonical resolution), `tta` > 1 averages flipped / transposed views as for the other models (the
    published code has none). `patch` (SDM-UniPS only): predict the working image as its interleaved sub-images of
    this side (`unips.sdm_preprocess.scalable_forward`; the published `--scalable` is `SDM_PATCH`); `rng`: what
    shuffles the decoder's pixels (default: seeded with 0 for each view); `views`: as `run_model`'s."""
    import functools

    import torch

    from unips.glc_preprocess import glc_crop, glc_inputs
    from unips.sdm_preprocess import scalable_forward, sdm_crop, sdm_inputs, sdm_output

    contract = net.contract
    sdm = contract.preprocess == "sdm-unips"
    crop = sdm_crop(obj.mask, margin=contract.margin) if sdm else glc_crop(obj.mask, contract.side, contract.margin)
    canonical = net.model.config.canonical_resolution
    if res is not None:
        if sdm and res % canonical:
            raise UsageError(f"--res {res}: {net.meta['model_name']} needs a multiple of its canonical "
                             f"resolution {canonical}")
        crop = dataclasses.replace(crop, side=res)
    forward = functools.partial(net.model, rng=rng) if sdm and rng is not None else net.model
    if patch is not None:
        if not sdm or patch % canonical:
            raise ValueError(f"patch: {patch} needs an SDM-UniPS network and a multiple of its canonical resolution "
                             f"{canonical}")
        if crop.side % patch:
            raise UsageError(f"--res {crop.side}: --scalable needs a multiple of its patch side {patch}")
        forward = functools.partial(scalable_forward, net.model, patch=patch, rng=rng)
    load_inputs = sdm_inputs if sdm else glc_inputs
    images, mask = load_inputs(obj, crop, max_images=contract.max_images)
    x = torch.from_numpy(np.ascontiguousarray(images.transpose(0, 3, 1, 2))).to(net.device)  # (K, 3, S, S)
    each: list = []
    out = model_normals(forward, x, torch.from_numpy(mask)[None].to(net.device), tta, each)  # (3, S, S)

    def back(t: Any) -> np.ndarray:  # (3, S, S) -> (H, W, 3) in the original frame
        n = t.permute(1, 2, 0).cpu().numpy() * mask[..., None]
        if not np.all(np.isfinite(n)):
            raise ValueError(f"{_weights_flag(net)}: the network {str(net.checkpoint)!r} produced non-finite normals "
                             f"for {obj.name} (weights that overflow on these images: damaged or not trained?)")
        return sdm_output(n, crop, obj.mask)

    if views is not None:
        views.extend(back(v) for v in each)
    return back(out)


MODEL_BYTES_PER_IMAGE = 25 * 2**20
"""Memory of the network per input image that does not grow with the resolution (the encoder works at the
canonical resolution)."""
SDM_ENCODER_BYTES = 1024
"""Memory of SDM-UniPS's encoder per image and pixel it sees (its working side squared plus the canonical 256
squared: it runs on all the interleaved tiles and the resized image at once): ConvNeXt's first stage and the
UPerNet fusion at a quarter of the resolution (up to 1024 channels of float32 per quarter-resolution pixel) and the
context maps; an estimate from their shapes."""


def prediction_memory(method: str, shape: tuple[int, int], num_images: int, work_res: int, tta: int = DEFAULT_TTA,
                      inputs: str = "unips", patch: int | None = None) -> int:
    """Bytes one object needs to be predicted (a conservative estimate, about 1.5 to 2 times the peak measured
    on the CPU for the shipped model at 256 to 2048 px): its K float32 RGB images of `shape` (H, W) as read, and for the
    model, per working pixel (`work_res`^2: the crop's side or --res) the images in 2 + 2 x `tta` copies (crop, resize,
    each view and its masked copy) and 64 bytes of mask and output, plus MODEL_BYTES_PER_IMAGE per image. The classical
    baselines hold about three copies of the images. The published UniPS and SDM-UniPS (`inputs`, their contract's
    preprocess: "glc-unips", "sdm-unips") add their decoder's chunk of 10000 pixels: three feed-forward activations of
    1024 floats per pixel and image (an estimate from their shapes, not a measurement); SDM-UniPS its encoder
    (`SDM_ENCODER_BYTES`) at the side it sees: `work_res`, or with `--scalable` the `patch` side of its sub-images (the
    whole working images are still held)."""
    h, w = int(shape[0]), int(shape[1])
    images = num_images * h * w * 12
    if method != "model":
        return 3 * images
    pixels = int(work_res) ** 2
    chunk = 10000 * num_images * 1024 * 4 * 3 if inputs != "unips" else 0
    if inputs == "sdm-unips":
        seen = int(patch or work_res)
        chunk += num_images * (seen ** 2 + 256 ** 2) * SDM_ENCODER_BYTES
    return images + num_images * MODEL_BYTES_PER_IMAGE + pixels * (12 * num_images * (2 + 2 * tta) + 64) + chunk


def predict_object(obj: PSObject, method: str, net: LoadedModel | None = None,
                   res: int | None = None, tta: int = DEFAULT_TTA, patch: int | None = None) -> np.ndarray:
    """(H, W, 3) unit normals of `obj` by `method` (zero outside the mask); `tta`: views, `patch`: the side of
    SDM-UniPS's `--scalable` sub-images, model only."""
    if method == "model":
        if net is None:
            raise ValueError("net: --method model needs a loaded network")
        return run_model(net, obj, res=res, tta=tta, patch=patch)
    from unips.baselines import run_baseline

    return run_baseline(method, obj)
