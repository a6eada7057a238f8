"""Train a GLC-UniPS model on object folders (CLI `python -m unips.train`).

Recipe (paper): AdamW, step learning-rate decay, each sample a random subset of 2..K images of an
object, MSE between unit normals on all masked pixels of the canonical grid plus `--pixels` random
masked pixels at the working resolution, flips / transpose / per-image RGB permutation with p = 0.5.

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

from scenes.objfolder import angular_errors_chw as angular_errors

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


def load_samples(root: str | Path, res: int, require_normals: bool = True) -> list[Sample]:
    """Load, crop, normalise and resize every object under `root` (helper B's loaders)."""
    from unips.data import find_objects, load_object
    from unips.preprocess import prepare, resize_prepared

    samples = []
    for p in find_objects(root):  # FileNotFoundError naming the path when there is none
        obj = load_object(p)
        if require_normals and obj.normals is None:
            raise ValueError(f"object {obj.name!r} in {str(root)!r} has no ground-truth normals (normal.tif)")
        prep = resize_prepared(prepare(obj, margin=4), res)
        imgs, m, n = to_tensors(prep.images, prep.mask, prep.normals)
        samples.append(Sample(obj.name, imgs.to(torch.float16), m, n, obj.light_family))
    return samples


def describe_data(samples: Sequence[Sample], root: str | Path, res: int) -> dict[str, Any]:
    """Data description stored in checkpoints (and compared on resume)."""
    return {"root": str(Path(root).resolve()), "res": res, "objects": [s.name for s in samples],
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
               max_images: int, pixels: int, canonical: int, augment: bool = True) -> Batch:
    """The batch of `step`, a pure function of (samples, step, seed and the settings)."""
    from unips.augment import apply_augmentation, sample_augmentation

    idx = batch_indices(seed, step, batch, len(samples))
    rng = step_rng(seed, step, 0)
    k_max = min(max_images, min(samples[i].num_images for i in idx))
    k = int(rng.integers(min_images, k_max + 1))
    imgs, masks, can, rnd = [], [], [], []
    for i in idx:
        s = samples[i]
        subset = np.sort(rng.choice(s.num_images, size=k, replace=False))
        x = s.images[torch.from_numpy(subset)].to(torch.float32)
        m, n = s.mask, s.normals
        if augment:
            x, m, n = apply_augmentation(sample_augmentation(rng, k), x, m, n)
        imgs.append(x)
        masks.append(m)
        can.append(canonical_points(m, n, canonical))
        rnd.append(random_pixels(m, n, pixels, rng))
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
def validate(model: torch.nn.Module, samples: Sequence[Sample], max_images: int,
             device: torch.device) -> dict[str, Any]:
    """Mean angular error (degrees) over all validation objects and per light family.

    Each object uses its first `max_images` images, predicted at the working resolution.
    """
    was_training = model.training
    model.eval()
    per_family: dict[str, list[float]] = {}
    per_object = {}
    for s in samples:
        x = s.images[:max_images].to(torch.float32)[None].to(device)
        pred = model(x, s.mask[None].to(device))[0].cpu()
        e = float(angular_errors(pred, s.normals, s.mask).mean())
        per_object[s.name] = e
        per_family.setdefault(s.light_family or "unknown", []).append(e)
    model.train(was_training)
    errs = list(per_object.values())
    return {"mean": float(np.mean(errs)), "n": len(errs),
            "families": {k: float(np.mean(v)) for k, v in sorted(per_family.items())},
            "objects": per_object}


# -- training loop --------------------------------------------------------------------------

# Settings that change the trajectory: a resumed run must use the same values.
TRAJECTORY_KEYS = ("model", "batch", "lr", "weight_decay", "decay_every", "decay", "max_images",
                   "min_images", "pixels", "seed", "res", "no_augment")


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m unips.train", description=__doc__.split("\n\n")[0])
    p.add_argument("--data", required=True, help="training dataset directory (object folders)")
    p.add_argument("--val", default=None, help="validation dataset directory (with normal.tif)")
    p.add_argument("--model", default="glc-tiny", help="registered model name (default glc-tiny)")
    p.add_argument("--out", required=True, help="run directory (log.jsonl, last.pt, best/final weights)")
    p.add_argument("--steps", type=int, default=2000, help="total optimisation steps (default 2000)")
    p.add_argument("--batch", type=int, default=4, help="objects per step (default 4)")
    p.add_argument("--lr", type=float, default=5e-4, help="AdamW learning rate (default 5e-4)")
    p.add_argument("--weight-decay", type=float, default=0.05, help="AdamW weight decay (default 0.05)")
    p.add_argument("--decay-every", type=int, default=1000, help="steps between lr decays (default 1000)")
    p.add_argument("--decay", type=float, default=0.8, help="lr factor at each decay (default 0.8)")
    p.add_argument("--max-images", type=int, default=8, help="most images per sample (default 8)")
    p.add_argument("--min-images", type=int, default=2, help="fewest images per sample (default 2)")
    p.add_argument("--pixels", type=int, default=2500, help="random masked pixels per object (default 2500)")
    p.add_argument("--res", type=int, default=64, help="working resolution of the cached crops (default 64)")
    p.add_argument("--seed", type=int, default=0, help="seed of every random choice (default 0)")
    p.add_argument("--resume", action="store_true", help="continue from RUN/last.pt (bit for bit)")
    p.add_argument("--val-every", type=int, default=200, help="steps between validations (default 200)")
    p.add_argument("--ckpt-every", type=int, default=200, help="steps between last.pt saves (default 200)")
    p.add_argument("--log-every", type=int, default=10, help="steps between log.jsonl records (default 10)")
    p.add_argument("--threads", type=int, default=0, help="torch CPU threads (default: all cores)")
    p.add_argument("--device", default="cpu", help="torch device (default cpu)")
    p.add_argument("--no-augment", action="store_true", help="disable flips / transpose / RGB permutation")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.add_argument("--model-option", action="append", default=[], metavar="KEY=VALUE",
                   help="override a model config field (JSON value), e.g. uniform_context=true")
    return p


def _check_args(a: argparse.Namespace) -> None:
    positive = ("steps", "batch", "decay_every", "max_images", "min_images", "pixels", "res", "val_every",
                "ckpt_every", "log_every")
    for name in positive:
        if getattr(a, name) < 1:
            raise ValueError(f"--{name.replace('_', '-')}: got {getattr(a, name)}, expected >= 1")
    if a.min_images > a.max_images:
        raise ValueError(f"--min-images={a.min_images} exceeds --max-images={a.max_images}")
    if not a.lr > 0:
        raise ValueError(f"--lr: got {a.lr}, expected > 0")
    if a.weight_decay < 0:
        raise ValueError(f"--weight-decay: got {a.weight_decay}, expected >= 0")
    if not 0 < a.decay <= 1:
        raise ValueError(f"--decay: got {a.decay}, expected in (0, 1]")
    if a.threads < 0:
        raise ValueError(f"--threads: got {a.threads}, expected >= 0 (0 = all cores)")


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


def train(args: argparse.Namespace) -> dict[str, Any]:
    """Run training as configured by the parsed CLI arguments; returns a summary dict."""
    from tqdm import tqdm

    from unips.checkpoint import (load_state_strict, load_training_checkpoint, save_checkpoint,
                                  save_training_checkpoint, set_rng_states)
    from unips.models import create_model

    _check_args(args)
    torch.set_num_threads(args.threads or os.cpu_count() or 1)
    device = torch.device(args.device)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    log_path, last_path = out / "log.jsonl", out / "last.pt"

    torch.manual_seed(args.seed)  # initial weights
    model = create_model(args.model, **_model_options(args.model_option)).to(device)
    samples = load_samples(args.data, args.res)
    val_samples = load_samples(args.val, args.res) if args.val else []
    too_few = [s.name for s in samples if s.num_images < args.min_images]
    if too_few:
        raise ValueError(f"--min-images={args.min_images}: objects with fewer images: {too_few[:5]}")
    data_desc = describe_data(samples, args.data, args.res)
    train_args = {k: getattr(args, k) for k in TRAJECTORY_KEYS}
    train_args["model_option"] = list(args.model_option)

    optimizer = torch.optim.AdamW(model.parameters(), lr=args.lr, weight_decay=args.weight_decay)
    scheduler = torch.optim.lr_scheduler.StepLR(optimizer, step_size=args.decay_every, gamma=args.decay)
    start, best = 0, math.inf
    if args.resume:
        ckpt = load_training_checkpoint(last_path)
        old = ckpt["extra"].get("train_args", {})
        for key, value in train_args.items():
            if old.get(key) != value:
                raise ValueError(f"--resume: {key}={value!r} differs from the checkpoint's {old.get(key)!r}")
        if ckpt["data"].get("objects") != data_desc["objects"]:
            raise ValueError(f"--resume: the objects in --data {args.data!r} differ from the checkpoint's")
        load_state_strict(model, ckpt["model"], str(last_path))
        optimizer.load_state_dict(ckpt["optimizer"])
        scheduler.load_state_dict(ckpt["scheduler"])
        set_rng_states(ckpt["rng"])
        start, best = int(ckpt["step"]), float(ckpt["extra"].get("best_val", math.inf))
        _truncate_log(log_path, start)
        log.info("resumed from %s at step %d", last_path, start)
    elif log_path.exists():
        log_path.unlink()
    if start >= args.steps:
        log.info("nothing to do: checkpoint at step %d, --steps %d", start, args.steps)

    canonical = model.config.canonical_resolution
    summary: dict[str, Any] = {"start": start, "steps": args.steps, "params": sum(p.numel() for p in model.parameters())}

    def save_last(step: int) -> None:
        save_training_checkpoint(last_path, model=model, optimizer=optimizer, scheduler=scheduler, step=step,
                                 data=data_desc, extra={"train_args": train_args, "best_val": best})

    def run_validation(step: int) -> None:
        nonlocal best
        res = validate(model, val_samples, args.max_images, device)
        _append_log(log_path, {"step": step, "val": res})
        summary["val"] = res
        if res["mean"] < best:
            best = res["mean"]
            save_checkpoint(out / "best.safetensors", model, {"step": step, "val": res, "train_args": train_args})

    model.train()
    bar = tqdm(range(start, args.steps), initial=start, total=args.steps, disable=args.no_progress,
               dynamic_ncols=True, desc="train")
    t0 = time.time()
    for step in bar:
        batch = make_batch(samples, step, seed=args.seed, batch=args.batch, min_images=args.min_images,
                           max_images=args.max_images, pixels=args.pixels, canonical=canonical,
                           augment=not args.no_augment)
        batch = Batch(*(getattr(batch, f.name).to(device) for f in dataclasses.fields(Batch)))
        # Dropout / drop-path draw from torch's global RNG: reseed it from (seed, step).
        torch.manual_seed(int(step_rng(args.seed, step, 1).integers(2**62)))
        contexts = model.encode(batch.images, batch.mask)  # (B, k, C, s/4, s/4)
        pred = model.decode_pixels(contexts, batch.images, batch.mask, batch.coords)  # (B, N, 3)
        loss, parts = normal_loss(pred, batch)
        if not torch.isfinite(loss):
            raise FloatingPointError(f"non-finite loss at step {step}")
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
        scheduler.step()
        done = step + 1
        bar.set_postfix(loss=f"{parts['loss']:.4f}", k=batch.images.shape[1])
        summary["last_loss"] = parts["loss"]
        if done % args.log_every == 0 or done == args.steps:
            _append_log(log_path, {"step": done, **parts, "k": int(batch.images.shape[1]),
                                   "lr": optimizer.param_groups[0]["lr"], "elapsed_s": round(time.time() - t0, 3)})
        if val_samples and (done % args.val_every == 0 or done == args.steps):
            run_validation(done)
        if done % args.ckpt_every == 0 or done == args.steps:
            save_last(done)
    bar.close()
    if start < args.steps or not (out / "final.safetensors").exists():
        save_checkpoint(out / "final.safetensors", model, {"step": args.steps, "train_args": train_args})
    summary["best_val"] = best if math.isfinite(best) else None
    return summary


def main(argv: Sequence[str] | None = None) -> int:
    """CLI entry point; returns the process exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    try:
        summary = train(args)
    except (ValueError, FileNotFoundError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    msg = f"trained steps {summary['start']}..{summary['steps']}, last loss {summary.get('last_loss')}"
    if summary.get("best_val") is not None:
        msg += f", best validation mean angular error {summary['best_val']:.2f} deg"
    print(msg)
    return 0


if __name__ == "__main__":
    sys.exit(main())
