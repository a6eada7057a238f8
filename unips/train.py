"""Train a GLC-UniPS model on object folders (CLI `python -m unips.train`).

Recipe: AdamW with linear warm-up then cosine decay (or the paper's step decay), gradient clipping,
each sample a random subset of `min_images`..`max_images` images of an object, MSE between unit
normals on (at most `canonical_points`) masked points of the canonical grid plus `pixels` random
masked pixels at the working resolution, flips / transpose / per-image RGB permutation with p = 0.5.
Validation reports the probes of `unips.probes` (all images, one image, mask only, shuffled) per
light family and the photometric gain; the best weights are chosen on the all-images error.

Many GPUs: run the same command under `torchrun --nproc_per_node N` (DistributedDataParallel; NCCL on
CUDA, gloo on CPU). The global batch `batch` is split across the N processes, so a run gives the same
trajectory up to floating-point reduction order; rank 0 validates and writes every file.

Determinism: every random choice of step `s` comes from generators seeded by `(seed, s)` (object
order by epoch from `(seed, epoch)`), and torch's global RNG (dropout, drop path) is reseeded from
`(seed, s)` before the step. A run resumed from `last.pt` therefore continues bit for bit.

Outputs in `--out RUN`: `log.jsonl` (training and validation records), `last.pt` (full training
checkpoint, every `--ckpt-every` steps and at the end), `final.safetensors` (+ .json) at the end,
`best.safetensors` (+ .json) with the lowest validation mean angular error when `--val` is given.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import logging
import math
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import torch
import torch.nn.functional as F

from scenes.config import check_choice, check_fields, config_parser, option
from scenes.config import config_from_args as parse_config


log = logging.getLogger(__name__)


# -- data -----------------------------------------------------------------------------------

@dataclass
class Sample:
    """One prepared object at the working resolution R, cached in memory."""

    name: str  # object name
    images: torch.Tensor  # (K, 3, R, R) float16 (halves the cache; values are ~1 after normalisation)
    mask: torch.Tensor  # (1, R, R) float32 in {0, 1}
    normals: torch.Tensor | None  # (3, R, R) float32 unit vectors inside the mask, 0 outside
    light_family: str | None  # lighting family from scene.json, if known

    @property
    def num_images(self) -> int:
        return int(self.images.shape[0])


def to_tensors(images: np.ndarray, mask: np.ndarray, normals: np.ndarray | None
               ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor | None]:
    """Prepared arrays (K, R, R, 3) / (R, R) / (R, R, 3) -> channels-first float32 tensors."""
    imgs = torch.from_numpy(np.ascontiguousarray(images, dtype=np.float32)).permute(0, 3, 1, 2)  # (K, 3, R, R)
    m = torch.from_numpy(np.ascontiguousarray(mask, dtype=np.float32))[None]  # (1, R, R)
    n = None
    if normals is not None:
        n = torch.from_numpy(np.ascontiguousarray(normals, dtype=np.float32)).permute(2, 0, 1)  # (3, R, R)
        n = F.normalize(n, dim=0, eps=1e-8) * m  # unit inside the mask, 0 outside
    return imgs.contiguous(), m, None if n is None else n.contiguous()


def data_roots(data: str | Path) -> list[Path]:
    """The dataset directories of a --data value: one path, or several separated by commas."""
    roots = [Path(p.strip()) for p in str(data).split(",") if p.strip()]
    if not roots:
        raise ValueError(f"--data: {str(data)!r} names no directory")
    names = [r.name for r in roots]
    if len(set(names)) != len(names):
        raise ValueError(f"--data: {str(data)!r} names two directories with the same name (object names would collide)")
    return roots


def load_samples(root: str | Path, res: int, require_normals: bool = True) -> list[Sample]:
    """Load, crop, normalise and resize every object under `root` (one dataset directory, or several
    separated by commas: their objects are pooled and named DIRNAME/OBJECT)."""
    from unips.data import find_objects, load_object
    from unips.preprocess import prepare, resize_prepared

    roots = data_roots(root)
    samples = []
    for r in roots:
        for p in find_objects(r):  # FileNotFoundError naming the path when there is none
            obj = load_object(p)
            if require_normals and obj.normals is None:
                raise ValueError(f"object {obj.name!r} in {str(r)!r} has no ground-truth normals (normal.tif)")
            prep = resize_prepared(prepare(obj, margin=4), res)
            imgs, m, n = to_tensors(prep.images, prep.mask, prep.normals)
            name = obj.name if len(roots) == 1 else f"{r.name}/{obj.name}"
            samples.append(Sample(name, imgs.to(torch.float16), m, n, obj.light_family))
    return samples


def describe_data(samples: Sequence[Sample], root: str | Path, res: int) -> dict[str, Any]:
    """Data description stored in checkpoints (and compared on resume)."""
    roots = [str(r.resolve()) for r in data_roots(root)]
    return {"root": roots[0] if len(roots) == 1 else roots, "res": res, "objects": [s.name for s in samples],
            "images": [s.num_images for s in samples]}


# -- batches --------------------------------------------------------------------------------

@dataclass
class Batch:
    """One training batch; every field on the training device."""

    images: torch.Tensor  # (B, k, 3, R, R) float32
    mask: torch.Tensor  # (B, 1, R, R) float32
    coords: torch.Tensor  # (B, N, 2) decode coordinates: canonical grid points, then random pixels
    target: torch.Tensor  # (B, N, 3) ground-truth unit normals at coords
    weight: torch.Tensor  # (B, N) 1 for a valid canonical point / random pixel, 0 for padding
    is_canonical: torch.Tensor  # (N,) bool, True for the canonical-grid part


def step_rng(seed: int, step: int, stream: int) -> np.random.Generator:
    """Generator for one purpose (`stream`) of one step, independent of everything else."""
    return np.random.default_rng([int(seed), int(step), int(stream)])


def batch_indices(seed: int, step: int, batch: int, n: int) -> list[int]:
    """Object indices of a step: consecutive slots of per-epoch permutations seeded by (seed, epoch)."""
    out = []
    for i in range(step * batch, (step + 1) * batch):
        epoch, pos = divmod(i, n)
        perm = np.random.default_rng([int(seed), 1_000_003, epoch]).permutation(n)
        out.append(int(perm[pos]))
    return out


def canonical_points(mask: torch.Tensor, normals: torch.Tensor, size: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Centres of the canonical size x size grid lying fully inside the mask.

    Returns coords `(n, 2)` and target normals `(n, 3)` (bilinear, renormalised). A point is kept
    when the bilinearly sampled mask is 1, i.e. all working-resolution neighbours are inside.
    """
    c = (2.0 * torch.arange(size, dtype=torch.float32) + 1.0) / size - 1.0
    gy, gx = torch.meshgrid(c, c, indexing="ij")
    grid = torch.stack([gx, gy], dim=-1).reshape(1, 1, -1, 2)  # (1, 1, s*s, 2)
    m = F.grid_sample(mask[None], grid, mode="bilinear", align_corners=False)[0, 0, 0]  # (s*s,)
    keep = m >= 0.999
    nrm = F.grid_sample(normals[None], grid, mode="bilinear", align_corners=False)[0, :, 0].T  # (s*s, 3)
    return grid[0, 0][keep], F.normalize(nrm[keep], dim=-1, eps=1e-8)


def random_pixels(mask: torch.Tensor, normals: torch.Tensor, count: int,
                  rng: np.random.Generator) -> tuple[torch.Tensor, torch.Tensor]:
    """`count` random masked pixels (with replacement only if fewer exist): coords `(count, 2)`, normals."""
    from unips.models.glc import pixel_centre_coords

    h, w = mask.shape[-2:]
    idx = torch.nonzero(mask[0].reshape(-1) > 0.5)[:, 0].numpy()
    pick = rng.choice(idx, size=count, replace=len(idx) < count)
    ys, xs = torch.from_numpy(pick // w), torch.from_numpy(pick % w)
    return pixel_centre_coords(ys, xs, h, w), normals[:, ys, xs].T


def make_batch(samples: Sequence[Sample], step: int, *, seed: int, batch: int, min_images: int,
               max_images: int, pixels: int, canonical: int, augment: bool = True,
               canonical_max: int = 0, interior_crop: float = 0.0, rank: int = 0, world: int = 1) -> Batch:
    """The batch of `step`, a pure function of (samples, step, seed and the settings).

    `canonical_max` > 0 keeps a random subset of at most that many canonical-grid points per object.
    `interior_crop` is the probability that an object is replaced by a square cut from inside its mask
    (`unips.augment.interior_crop`); at 0 no draw is made, so older runs keep their trajectories.
    With `world` > 1 processes, rank `rank` gets objects rank, rank + world, ... of the global batch
    (every random draw is made for the whole batch, so the union over ranks is the 1-process batch).
    """
    from unips.augment import apply_augmentation, interior_crop as cut_interior, sample_augmentation

    idx = batch_indices(seed, step, batch, len(samples))
    rng = step_rng(seed, step, 0)
    k_max = min(max_images, min(samples[i].num_images for i in idx))
    k = int(rng.integers(min_images, k_max + 1))
    imgs, masks, can, rnd = [], [], [], []
    for j, i in enumerate(idx):
        s = samples[i]
        subset = np.sort(rng.choice(s.num_images, size=k, replace=False))
        x = s.images[torch.from_numpy(subset)].to(torch.float32)
        m, n = s.mask, s.normals
        if augment:
            x, m, n = apply_augmentation(sample_augmentation(rng, k), x, m, n)
        if interior_crop > 0 and rng.random() < interior_crop:
            cut = cut_interior(x, m, n, rng)
            if cut is not None:
                x, m, n = cut
        cc, cn = canonical_points(m, n, canonical)
        if 0 < canonical_max < cc.shape[0]:
            keep = torch.from_numpy(np.sort(rng.choice(cc.shape[0], size=canonical_max, replace=False)))
            cc, cn = cc[keep], cn[keep]
        rp = random_pixels(m, n, pixels, rng)
        if j % world != rank:
            continue  # drawn anyway so that every rank's generator stays in step
        imgs.append(x)
        masks.append(m)
        can.append((cc, cn))
        rnd.append(rp)
    n_can = max(1, max(c.shape[0] for c, _ in can))
    coords, target, weight = [], [], []
    for (cc, cn), (rc, rn) in zip(can, rnd):
        pad = n_can - cc.shape[0]
        wc = torch.cat([torch.ones(cc.shape[0]), torch.zeros(pad)])
        # Pad with copies of the first random pixel (weight 0) so all samples share N.
        cc = torch.cat([cc, rc[:1].expand(pad, 2)])
        cn = torch.cat([cn, rn[:1].expand(pad, 3)])
        coords.append(torch.cat([cc, rc]))
        target.append(torch.cat([cn, rn]))
        weight.append(torch.cat([wc, torch.ones(rc.shape[0])]))
    is_can = torch.cat([torch.ones(n_can, dtype=torch.bool), torch.zeros(pixels, dtype=torch.bool)])
    return Batch(torch.stack(imgs), torch.stack(masks), torch.stack(coords), torch.stack(target),
                 torch.stack(weight), is_can)


def normal_loss(pred: torch.Tensor, batch: Batch) -> tuple[torch.Tensor, dict[str, float]]:
    """MSE between unit normals, averaged separately on the canonical grid and the random pixels."""
    err = ((pred - batch.target) ** 2).mean(dim=-1) * batch.weight  # (B, N)
    wc, wr = batch.weight[:, batch.is_canonical], batch.weight[:, ~batch.is_canonical]
    lc = err[:, batch.is_canonical].sum() / wc.sum().clamp_min(1.0)
    lr = err[:, ~batch.is_canonical].sum() / wr.sum().clamp_min(1.0)
    loss = lc + lr
    return loss, {"loss": float(loss.detach()), "loss_canonical": float(lc.detach()), "loss_random": float(lr.detach())}


# -- validation -----------------------------------------------------------------------------

@torch.no_grad()
def validate(model: torch.nn.Module, samples: Sequence[Sample], max_images: int, device: torch.device,
             probes: Sequence[str] = ("all",), pixels: int = 0, seed: int = 0) -> dict[str, Any]:
    """Probe errors (degrees) over the validation objects, overall and per light family.

    Each object uses its first `max_images` images at the working resolution; `pixels` > 0 scores a
    fixed seeded subset of that many masked pixels per object. Returns `unips.probes.summarise`'s
    dict plus "mean" (all images, the model-selection figure) and per-object errors.
    """
    from unips.probes import probe_object, summarise

    was_training = model.training
    model.eval()
    per_object = {}
    for i, s in enumerate(samples):
        per_object[s.name] = probe_object(model, s.images[:max_images], s.mask, s.normals, probes=probes,
                                          pixels=pixels, seed=seed + i, device=device)
    model.train(was_training)
    res = summarise(per_object, {s.name: s.light_family for s in samples})
    res["probes"] = res.pop("mean")
    res["mean"] = res["probes"]["all"]
    res["objects"] = per_object
    return res


# -- configuration ----------------------------------------------------------------------------

@dataclass
class TrainConfig:
    """Everything that determines a training run; the CLI fills it (`python -m unips.train --help`)."""

    data: str = option("", required=True)
    """Training dataset directory (object folders with ground-truth normals), or several separated by commas
    (pooled, e.g. sets rendered with different seeds)."""
    out: str = option("", required=True)
    """Run directory: log.jsonl, last.pt, best.safetensors and final.safetensors (+ .json sidecars)."""
    val: str | None = None
    """Validation dataset directory (object folders with normal.tif); held-out assets, test-like settings."""
    model: str = "glc-small"
    """Registered model name (`unips.models.list_models()`); with `init_from`, the weights' model."""
    init_from: str | None = None
    """Weights (.safetensors or .pt) to start from: weights only, with fresh optimiser, schedule and data."""
    steps: int = option(2000, minimum=1)
    """Total optimisation steps."""
    batch: int = option(4, minimum=1)
    """Objects per step (the global batch, split across processes under torchrun)."""
    lr: float = option(5e-4, above=0)
    """Peak AdamW learning rate."""
    weight_decay: float = option(0.05, minimum=0)
    """AdamW weight decay."""
    schedule: str = option("cosine", choices=("cosine", "step"))
    """'cosine': linear warm-up over `warmup` steps then cosine decay to `min_lr_ratio` * lr; 'step': x`decay` every `decay_every` steps."""
    warmup: int = option(100, minimum=0)
    """Warm-up steps of the cosine schedule."""
    min_lr_ratio: float = option(0.05, minimum=0, maximum=1)
    """Final learning rate of the cosine schedule as a fraction of `lr`."""
    decay_every: int = option(1000, minimum=1)
    """Steps between decays of the step schedule."""
    decay: float = option(0.8, above=0, maximum=1)
    """Learning-rate factor at each decay of the step schedule."""
    clip_grad: float = option(1.0, minimum=0)
    """Gradient clipping by global norm (0: off)."""
    max_images: int = option(10, minimum=1)
    """Most images per training sample (and images per validation object)."""
    min_images: int = option(1, minimum=1)
    """Fewest images per training sample (1 keeps single-image inputs in the training distribution)."""
    pixels: int = option(1000, minimum=1)
    """Random masked pixels per object at the working resolution."""
    canonical_points: int = option(1000, minimum=0)
    """At most this many masked canonical-grid points per object in the loss (0: all of them)."""
    res: int = option(128, minimum=1)
    """Working resolution of the cached crops (the test resolution; above the canonical resolution)."""
    seed: int = 0
    """Seed of every random choice (initial weights, objects, image subsets, pixels, augmentation)."""
    resume: bool = False
    """Continue from RUN/last.pt, bit for bit."""
    overwrite: bool = False
    """Start afresh in a run directory that already holds a run (its files are replaced)."""
    val_every: int = option(200, minimum=1)
    """Steps between validations."""
    val_pixels: int = option(2000, minimum=0)
    """Masked pixels scored per validation object (a fixed seeded subset; 0: all)."""
    val_probes: list[str] = option(default_factory=lambda: ["all", "one", "mask", "shuffled"], metavar="P1,P2")
    """Probes of every validation (`unips.probes.PROBES`); 'all' is always included."""
    ckpt_every: int = option(200, minimum=1)
    """Steps between last.pt saves."""
    log_every: int = option(10, minimum=1)
    """Steps between training records in log.jsonl."""
    threads: int = option(0, minimum=0)
    """torch CPU threads (0: all cores, divided among local processes under torchrun)."""
    device: str = "cpu"
    """torch device ('cpu', 'cuda'; under torchrun each process takes cuda:LOCAL_RANK)."""
    precision: str = option("fp32", choices=("fp32", "bf16"))
    """'fp32' or 'bf16' (autocast of the forward pass; for GPUs)."""
    no_augment: bool = False
    """Disable flips / transpose / RGB permutation."""
    interior_crop: float = option(0.0, minimum=0, maximum=1)
    """Probability that a training sample is a square cut from inside the object's mask and resized to the working resolution: no outline, so the normals must come from the images."""
    no_progress: bool = False
    """No progress bar."""
    model_option: list[str] = option(default_factory=list, repeat=True, sep="", metavar="KEY=VALUE")
    """Model config overrides KEY=VALUE (JSON value), e.g. uniform_context=true; repeatable."""

    def validate(self) -> "TrainConfig":
        """Raise ValueError naming the first bad field as its CLI flag."""
        from unips.probes import PROBES

        if not self.data:
            raise ValueError("--data: required (a dataset directory)")
        if not self.out:
            raise ValueError("--out: required (a run directory)")
        check_fields(self)
        if self.min_images > self.max_images:
            raise ValueError(f"--min-images={self.min_images} exceeds --max-images={self.max_images}")
        for p in self.val_probes:
            check_choice(p, "--val-probes", PROBES)
        if self.resume and self.overwrite:
            raise ValueError("--resume and --overwrite: expected at most one of them")
        if self.resume and self.init_from:
            raise ValueError("--resume and --init-from: expected at most one of them (a resumed run keeps its weights)")
        return self


# Settings that change the trajectory: a resumed run must use the same values.
TRAJECTORY_KEYS = ("model", "init_from", "batch", "lr", "weight_decay", "schedule", "warmup", "min_lr_ratio",
                   "decay_every", "decay", "clip_grad", "max_images", "min_images", "pixels", "canonical_points",
                   "seed", "res", "no_augment", "precision", "interior_crop")


def build_parser() -> argparse.ArgumentParser:
    """The CLI of `TrainConfig`: one flag per field, help from the field's docstring."""
    return config_parser(TrainConfig, prog="python -m unips.train", description=__doc__.split("\n\n")[0])


def config_from_args(args: argparse.Namespace) -> TrainConfig:
    """The TrainConfig of parsed CLI arguments (validated)."""
    cfg = parse_config(TrainConfig, args)
    if "all" not in cfg.val_probes:
        cfg.val_probes = ["all", *cfg.val_probes]
    return cfg.validate()


def _model_options(items: Sequence[str]) -> dict[str, Any]:
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise ValueError(f"--model-option: got {item!r}, expected KEY=VALUE")
        try:
            out[key] = json.loads(value)
        except json.JSONDecodeError:
            out[key] = value
    return out


def _append_log(path: Path, record: dict[str, Any]) -> None:
    with path.open("a") as f:
        f.write(json.dumps(record, sort_keys=True) + "\n")


def _truncate_log(path: Path, step: int) -> None:
    """Drop records written after `step` by an interrupted run (they will be written again)."""
    if not path.exists():
        return
    keep = [line for line in path.read_text().splitlines() if line.strip() and json.loads(line).get("step", 0) <= step]
    path.write_text("".join(line + "\n" for line in keep))


def lr_factor(cfg: TrainConfig, step: int) -> float:
    """Learning-rate multiplier of optimisation step `step` (0-based)."""
    if cfg.schedule == "step":
        return cfg.decay ** (step // cfg.decay_every)
    if cfg.warmup and step < cfg.warmup:
        return (step + 1) / cfg.warmup
    progress = min(1.0, (step - cfg.warmup) / max(1, cfg.steps - cfg.warmup))
    return cfg.min_lr_ratio + (1.0 - cfg.min_lr_ratio) * 0.5 * (1.0 + math.cos(math.pi * progress))


class _TrainForward(torch.nn.Module):
    """encode + decode_pixels as one forward, so DistributedDataParallel sees the whole step."""

    def __init__(self, model: torch.nn.Module) -> None:
        super().__init__()
        self.model = model

    def forward(self, images: torch.Tensor, mask: torch.Tensor, coords: torch.Tensor) -> torch.Tensor:
        contexts = self.model.encode(images, mask)  # (B, k, C, s/4, s/4)
        return self.model.decode_pixels(contexts, images, mask, coords)  # (B, N, 3)


@dataclass
class _Dist:
    """This process's place in a torchrun job (rank 0 of 1 without one)."""

    rank: int = 0
    world: int = 1
    local_rank: int = 0

    @property
    def main(self) -> bool:
        return self.rank == 0


def _init_distributed(cfg: TrainConfig) -> _Dist:
    world = int(os.environ.get("WORLD_SIZE", "1"))
    if world <= 1:
        return _Dist()
    import torch.distributed as dist

    rank, local = int(os.environ["RANK"]), int(os.environ.get("LOCAL_RANK", "0"))
    if cfg.batch % world:
        raise ValueError(f"--batch={cfg.batch}: expected a multiple of the {world} torchrun processes")
    if not dist.is_initialized():
        dist.init_process_group(backend="nccl" if cfg.device.startswith("cuda") else "gloo")
    return _Dist(rank, world, local)


def _load_init_weights(cfg: TrainConfig, device: torch.device) -> torch.nn.Module:
    """The model of `cfg.init_from` (weights only); its name must agree with an explicit --model."""
    from unips.checkpoint import load_model

    model, meta = load_model(cfg.init_from)
    name = meta.get("model_name")
    if cfg.model != TrainConfig.model and cfg.model != name:
        raise ValueError(f"--model={cfg.model!r}: --init-from {cfg.init_from!r} holds a {name!r} model")
    if cfg.model_option:
        raise ValueError("--model-option: not allowed with --init-from (the weights fix the configuration)")
    return model.to(device).train()


def _prepare_run_dir(cfg: TrainConfig, dist: _Dist) -> Path:
    """The run directory; a previous run in it is kept unless --resume or --overwrite says otherwise."""
    out = Path(cfg.out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"--out {cfg.out!r}: exists and is not a directory")
    ours = ("log.jsonl", "last.pt", "best.safetensors", "best.json", "final.safetensors", "final.json")
    old = [n for n in ours if (out / n).exists()]
    if old and not cfg.resume and not cfg.overwrite:
        raise ValueError(f"--out {cfg.out!r}: already holds a run ({', '.join(old)}); "
                         "expected --resume to continue it or --overwrite to replace it")
    if dist.main:
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ValueError(f"--out {cfg.out!r}: cannot create the run directory ({exc.strerror})") from exc
        if cfg.overwrite:
            for n in old:
                (out / n).unlink()
    return out


def train(cfg: TrainConfig | argparse.Namespace) -> dict[str, Any]:
    """Run training as configured; returns a summary dict."""
    from tqdm import tqdm

    from unips.checkpoint import (load_state_strict, load_training_checkpoint, save_checkpoint,
                                  save_training_checkpoint, set_rng_states)
    from unips.models import create_model

    if isinstance(cfg, argparse.Namespace):
        cfg = config_from_args(cfg)
    cfg.validate()
    dist = _init_distributed(cfg)
    torch.set_num_threads(cfg.threads or max(1, (os.cpu_count() or 1) // dist.world))
    device = torch.device(f"cuda:{dist.local_rank}" if cfg.device == "cuda" and dist.world > 1 else cfg.device)
    out = _prepare_run_dir(cfg, dist)
    log_path, last_path = out / "log.jsonl", out / "last.pt"

    torch.manual_seed(cfg.seed)  # initial weights
    if cfg.init_from:
        model = _load_init_weights(cfg, device)
    else:
        model = create_model(cfg.model, **_model_options(cfg.model_option)).to(device)
    samples = load_samples(cfg.data, cfg.res)
    val_samples = load_samples(cfg.val, cfg.res) if cfg.val and dist.main else []
    too_few = [s.name for s in samples if s.num_images < cfg.min_images]
    if too_few:
        raise ValueError(f"--min-images={cfg.min_images}: objects with fewer images: {too_few[:5]}")
    canonical = model.config.canonical_resolution
    if canonical >= cfg.res:
        log.warning("working resolution %d is not above the canonical resolution %d: the canonical grid "
                    "repeats the working pixels", cfg.res, canonical)
    data_desc = describe_data(samples, cfg.data, cfg.res)
    train_args = {k: getattr(cfg, k) for k in TRAJECTORY_KEYS}
    train_args["model"] = getattr(model, "model_name", cfg.model)
    train_args["model_option"] = list(cfg.model_option)

    step_model: torch.nn.Module = _TrainForward(model)
    if dist.world > 1:
        from torch.nn.parallel import DistributedDataParallel

        step_model = DistributedDataParallel(step_model, device_ids=[device.index] if device.type == "cuda" else None)
    optimizer = torch.optim.AdamW(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    scheduler = torch.optim.lr_scheduler.LambdaLR(optimizer, lambda s: lr_factor(cfg, s))
    start, best = 0, math.inf
    # Training seconds of the steps a resumed run keeps (from last.pt), so that `elapsed_s` in the log
    # counts the whole run's time, not the time since the last resume.
    elapsed_before = 0.0
    if cfg.resume:
        ckpt = load_training_checkpoint(last_path)
        old = ckpt["extra"].get("train_args", {})
        defaults = dataclasses.asdict(TrainConfig())
        # A resumed run keeps its weights (last.pt), so --resume takes no --init-from: the run's lineage
        # is the checkpoint's.
        train_args["init_from"] = old.get("init_from")
        for key, value in train_args.items():
            saved = old.get(key, defaults.get(key))  # a key newer than the checkpoint had its default there
            if saved != value:
                raise ValueError(f"--resume: {key}={value!r} differs from the checkpoint's {saved!r}")
        if ckpt["data"].get("objects") != data_desc["objects"]:
            raise ValueError(f"--resume: the objects in --data {cfg.data!r} differ from the checkpoint's")
        load_state_strict(model, ckpt["model"], str(last_path))
        optimizer.load_state_dict(ckpt["optimizer"])
        scheduler.load_state_dict(ckpt["scheduler"])
        set_rng_states(ckpt["rng"])
        start, best = int(ckpt["step"]), float(ckpt["extra"].get("best_val", math.inf))
        elapsed_before = float(ckpt["extra"].get("elapsed_s", 0.0))
        if dist.main:
            _truncate_log(log_path, start)
        log.info("resumed from %s at step %d", last_path, start)
    if start >= cfg.steps:
        log.info("nothing to do: checkpoint at step %d, --steps %d", start, cfg.steps)

    summary: dict[str, Any] = {"start": start, "steps": cfg.steps, "params": sum(p.numel() for p in model.parameters())}
    t_start = time.time() - elapsed_before

    def save_last(step: int) -> None:
        if dist.main:
            save_training_checkpoint(last_path, model=model, optimizer=optimizer, scheduler=scheduler, step=step,
                                     data=data_desc, extra={"train_args": train_args, "best_val": best,
                                                            "elapsed_s": round(time.time() - t_start, 3)})

    def run_validation(step: int) -> None:
        nonlocal best
        res = validate(model, val_samples, cfg.max_images, device, probes=cfg.val_probes, pixels=cfg.val_pixels)
        res["elapsed_s"] = round(time.time() - t_start, 1)
        _append_log(log_path, {"step": step, "val": res})
        summary["val"] = res
        gain = f", photometric gain {res['gain']:.2f}" if "gain" in res else ""
        log.info("step %d validation: all images %.2f deg%s", step, res["mean"], gain)
        if res["mean"] < best:
            best = res["mean"]
            save_checkpoint(out / "best.safetensors", model, {"step": step, "val": res, "train_args": train_args})

    autocast = torch.autocast(device_type=device.type, dtype=torch.bfloat16, enabled=cfg.precision == "bf16")
    model.train()
    bar = tqdm(range(start, cfg.steps), initial=start, total=cfg.steps, disable=cfg.no_progress or not dist.main,
               dynamic_ncols=True, desc="train")
    for step in bar:
        batch = make_batch(samples, step, seed=cfg.seed, batch=cfg.batch, min_images=cfg.min_images,
                           max_images=cfg.max_images, pixels=cfg.pixels, canonical=canonical,
                           augment=not cfg.no_augment, canonical_max=cfg.canonical_points,
                           interior_crop=cfg.interior_crop, rank=dist.rank, world=dist.world)
        batch = Batch(*(getattr(batch, f.name).to(device) for f in dataclasses.fields(Batch)))
        # Dropout / drop-path draw from torch's global RNG: reseed it from (seed, step, rank).
        torch.manual_seed(int(step_rng(cfg.seed, step, 1 + dist.rank).integers(2**62)))
        with autocast:
            pred = step_model(batch.images, batch.mask, batch.coords)  # (B, N, 3)
        loss, parts = normal_loss(pred.float(), batch)
        if not torch.isfinite(loss):
            raise FloatingPointError(f"non-finite loss at step {step}")
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        if cfg.clip_grad > 0:
            parts["grad_norm"] = float(torch.nn.utils.clip_grad_norm_(model.parameters(), cfg.clip_grad))
        optimizer.step()
        scheduler.step()
        done = step + 1
        bar.set_postfix(loss=f"{parts['loss']:.4f}", k=batch.images.shape[1])
        summary["last_loss"] = parts["loss"]
        if dist.main and (done % cfg.log_every == 0 or done == cfg.steps):
            _append_log(log_path, {"step": done, **parts, "k": int(batch.images.shape[1]),
                                   "lr": optimizer.param_groups[0]["lr"], "elapsed_s": round(time.time() - t_start, 3)})
        if val_samples and (done % cfg.val_every == 0 or done == cfg.steps):
            run_validation(done)
        if done % cfg.ckpt_every == 0 or done == cfg.steps:
            save_last(done)
    bar.close()
    if dist.main and (start < cfg.steps or not (out / "final.safetensors").exists()):
        save_checkpoint(out / "final.safetensors", model, {"step": cfg.steps, "train_args": train_args})
    if dist.world > 1:
        import torch.distributed as tdist

        tdist.barrier()
        tdist.destroy_process_group()
    summary["best_val"] = best if math.isfinite(best) else None
    return summary


def main(argv: Sequence[str] | None = None) -> int:
    """CLI entry point; returns the process exit status."""
    from scenes.cli import INPUT_ERRORS, report_error

    try:
        args = build_parser().parse_args(argv)
        logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
        summary = train(config_from_args(args))
    except INPUT_ERRORS as exc:
        return report_error(exc)
    msg = f"trained steps {summary['start']}..{summary['steps']}, last loss {summary.get('last_loss')}"
    if summary.get("best_val") is not None:
        msg += f", best validation mean angular error {summary['best_val']:.2f} deg"
    print(msg)
    return 0


if __name__ == "__main__":
    sys.exit(main())
