"""Train a GLC-UniPS model on object folders (CLI `python -m unips.train`).

Recipe: AdamW with linear warm-up then cosine decay (or the paper's step decay), gradient clipping,
each sample a random subset of `min_images`..`max_images` images of an object, MSE between unit
normals on (at most `canonical_points`) masked points of the canonical grid plus `pixels` random
masked pixels at the working resolution, flips / transpose / per-image RGB permutation with p = 0.5.
Validation reports the probes of `unips.probes` (all images, one image, mask only, shuffled) per
light family and the photometric gain; the best weights are chosen on the all-images error. Samples,
batches, the loss and the probes of a validation are `unips.train_data`; the run's bookkeeping (run
folder, setup, last.pt) is `unips.train_run`; this module holds the CLI (generated from `TrainConfig`)
and the loop.

Many GPUs: run the same command under `torchrun --nproc_per_node N` (DistributedDataParallel; NCCL on
CUDA, gloo on CPU). The global batch `batch` is split across the N processes, so a run gives the same
trajectory up to floating-point reduction order; rank 0 validates and writes every file.

Determinism: every random choice of step `s` comes from generators seeded by `(seed, s)` (object
order by epoch from `(seed, epoch)`), and torch's global RNG (dropout, drop path) is reseeded from
`(seed, s)` before the step. A run resumed from `last.pt` therefore continues bit for bit.

Outputs in `--out RUN`: `log.jsonl` (training records at step 1, every `--log-every` steps and at the end;
validation records), `last.pt` (full training
checkpoint, every `--ckpt-every` steps and at the end), `final.safetensors` (+ .json) at the end,
`best.safetensors` (+ .json) with the lowest validation mean angular error when `--val` is given.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import math
import os
import sys
import time
from pathlib import Path
from typing import Any, Sequence

import torch

from scenes.cli.budget import Budget, process_start
from scenes.cli.errors import UsageError
from scenes.cli.needs import Needs
from scenes.cli.options import Command
from scenes.cli.progress import Progress
from unips.distributed import distributed_env
from unips.train_config import TrainConfig
from unips.train_data import Batch, curriculum_pool, make_batch, normal_loss, probe_samples, step_rng
from unips.train_run import Run, append_log, check_run, open_stream, resume_run, save_last, setup_run

log = logging.getLogger(__name__)


COMMAND = Command(TrainConfig, prog="python -m unips.train", description=__doc__.split("\n\n")[0], needs=(
    Needs("decay_every", lambda c, _: c.schedule == "step", "with --schedule step"),
    Needs("decay", lambda c, _: c.schedule == "step", "with --schedule step"),
    Needs("warmup", lambda c, _: c.schedule == "cosine", "with --schedule cosine (the default)"),
    Needs("min_lr_ratio", lambda c, _: c.schedule == "cosine", "with --schedule cosine (the default)"),
    Needs("loader_workers", lambda c, _: c.shuffle_buffer > 0, "with --shuffle-buffer N > 0 (streamed shards)", (0,)),
    Needs("curriculum_fraction", lambda c, _: c.curriculum, "with --curriculum"),
    *(Needs(f, lambda c, _: bool(c.val), "with --val (nothing is validated without it)")
      for f in ("val_every", "val_pixels", "val_probes"))))


def config_from_args(argv: Sequence[str] | None) -> TrainConfig:
    """The TrainConfig of a command line (validated)."""
    cfg = COMMAND.parse(argv)
    if "all" not in cfg.val_probes:
        cfg.val_probes = ["all", *cfg.val_probes]
    cfg = cfg.validate()
    if cfg.init_from and cfg.model == TrainConfig.model and "model" in COMMAND.given(argv):
        from unips.train_run import read_init_weights

        read_init_weights(cfg, explicit=True)  # --model typed at its default must name the weights' model too
    return cfg


def check_args(argv: Sequence[str]) -> TrainConfig:
    """What can be checked of a training command line before its data exist (orchestrate.train_recipe checks
    its training step with this before rendering the data, `orchestrate.steps.check_step`): the flags, the run
    folder writable, the model name registered, and --init-from read (its model name against an explicit
    --model); writes nothing."""
    from scenes.cli.limits import check_threads
    from scenes.cli.outputs import check_output_folder
    from unips.models import list_models
    from unips.train_run import read_init_weights

    cfg = config_from_args(argv)
    distributed_env()  # torchrun's variables, checked before anything is read
    check_output_folder(cfg.out)
    check_threads(cfg.threads or None, "--threads")
    if cfg.init_from:
        read_init_weights(cfg)
    elif cfg.model not in list_models():
        raise ValueError(f"--model: got {cfg.model!r}, expected one of {', '.join(list_models())}")
    return cfg


def _train_step(run: Run, step: int, autocast: Any) -> tuple[dict[str, float], int]:
    """One optimisation step: the step's batch (this rank's part), forward, loss, backward, clipping, update.
    Returns the loss parts (and gradient norm) and the number of images per sample."""
    cfg, dist = run.cfg, run.dist
    settings = dict(min_images=cfg.min_images, max_images=cfg.max_images, pixels=cfg.pixels,
                    canonical=run.model.config.canonical_resolution, augment=not cfg.no_augment,
                    canonical_max=cfg.canonical_points, interior_crop=cfg.interior_crop)
    if run.stream is not None:  # streamed: this rank's next batch / world samples, its draws seeded by (seed, rank)
        local = [next(run.stream) for _ in range(cfg.batch // dist.world)]
        batch = make_batch(local, step, seed=cfg.seed + (dist.rank << 32), batch=len(local), **settings)
    else:
        pool = (curriculum_pool([s.level for s in run.samples], step, cfg.steps, cfg.curriculum_fraction)
                if cfg.curriculum else None)
        batch = make_batch(run.samples, step, seed=cfg.seed, batch=cfg.batch, rank=dist.rank, world=dist.world,
                           pool=pool, **settings)
    batch = Batch(*(getattr(batch, f.name).to(run.device) for f in dataclasses.fields(Batch)))
    # Dropout / drop-path draw from torch's global RNG: reseed it from (seed, step, rank).
    torch.manual_seed(int(step_rng(cfg.seed, step, 1 + dist.rank).integers(2**62)))
    with autocast:
        pred = run.step_model(batch.images, batch.mask, batch.coords)  # (B, N, 3)
    loss, parts = normal_loss(pred.float(), batch)
    if not torch.isfinite(loss):
        raise ValueError(f"the loss at step {step} is not finite: the training diverged (a --lr too high for "
                         "--warmup, or weights or optimiser state that hold NaN); lower --lr, or start from a "
                         "checkpoint that is whole")
    run.optimizer.zero_grad(set_to_none=True)
    loss.backward()
    if cfg.clip_grad > 0:
        parts["grad_norm"] = float(torch.nn.utils.clip_grad_norm_(run.model.parameters(), cfg.clip_grad))
    run.optimizer.step()
    run.scheduler.step()
    return parts, int(batch.images.shape[1])


def _validation(run: Run, step: int) -> None:
    """Probe the validation objects, log the result, and keep the weights as best.safetensors when they beat the
    best so far (the all-images error)."""
    from unips.checkpoint import save_checkpoint

    cfg = run.cfg
    res = probe_samples(run.model, run.val_samples, cfg.max_images, run.device, probes=cfg.val_probes,
                        pixels=cfg.val_pixels)
    res["elapsed_s"] = round(run.elapsed(), 1)
    append_log(run.log_path, {"step": step, "val": res})
    run.summary["val"] = res
    gain = f", photometric gain {res['gain']:.2f}" if "gain" in res else ""
    log.info("step %d validation: all images %.2f deg%s", step, res["mean"], gain)
    if res["mean"] < run.best:
        run.best = res["mean"]
        save_checkpoint(
            run.out / "best.safetensors", run.model, {"step": step, "val": res, "train_args": run.train_args}
        )


def _out_of_time(run: Run, budget: Budget, *kinds: str) -> bool:
    """Whether work of `kinds` (the longest of each so far) would end past --time-limit; under torchrun every
    process stops at the same step (rank 0 decides)."""
    if budget.seconds is None:
        return False
    over = not budget.fits(*kinds)
    if run.dist.world > 1:
        import torch.distributed as tdist

        flag = torch.tensor([float(over)], device=run.device)
        tdist.broadcast(flag, src=0)
        over = bool(flag.item())
    return over


def _inputs(cfg) -> dict:
    """The folders the run reads (its --out may not lie inside them): --data's and --val's entries."""
    from unips.train_data import data_roots

    inputs = {}
    for flag, value in (("--data", cfg.data), ("--val", cfg.val)):
        for i, root in enumerate(data_roots(value, flag) if value else []):
            inputs[flag if i == 0 else f"{flag} ({root})"] = root
    return inputs


def train(cfg: TrainConfig | Sequence[str], started: float | None = None) -> dict[str, Any]:
    """Run training as configured; returns a summary dict. `started`: when --time-limit's clock started (default:
    now)."""
    from scenes.cli.outputs import output_lock
    from unips.checkpoint import save_checkpoint

    started = time.time() if started is None else started
    if not isinstance(cfg, TrainConfig):  # a command line
        cfg = config_from_args(cfg)
    cfg.validate()
    # One writer per run folder: rank 0, the process that writes every file, holds it for the whole run.
    main_rank = distributed_env().main
    with output_lock(cfg.out, inputs=_inputs(cfg)) if main_rank else contextlib.nullcontext():
        run = _start(cfg)
        done, stopped = _loop(run, started)
        if run.dist.main and (run.start < cfg.steps or not (run.out / "final.safetensors").exists()):
            save_checkpoint(run.out / "final.safetensors", run.model,
                            {"step": done if stopped else cfg.steps, "train_args": run.train_args})
        if run.dist.world > 1:
            import torch.distributed as tdist

            tdist.barrier()
            tdist.destroy_process_group()
    run.summary["best_val"] = run.best if math.isfinite(run.best) else None
    return run.summary


def _start(cfg: TrainConfig) -> Run:
    """The checks before any work, the one line saying what runs, then the run set up (and resumed)."""
    check_run(cfg)
    if distributed_env().main:  # one line before the long work, also with --no-progress
        what = cfg.init_from or cfg.model
        print(f"{'resuming' if cfg.resume else 'training'} {what} for {cfg.steps} steps (batch {cfg.batch}, "
              f"{cfg.res} px) on --data {cfg.data}; run folder {cfg.out}", flush=True)
    run = setup_run(cfg)
    if cfg.resume:
        resume_run(run)
    if cfg.shuffle_buffer:
        run.stream = open_stream(run)
    if run.start >= cfg.steps:
        log.info("nothing to do: checkpoint at step %d, --steps %d", run.start, cfg.steps)
    run.summary.update(start=run.start, steps=cfg.steps, params=sum(p.numel() for p in run.model.parameters()))
    run.t_start = time.time() - run.elapsed_before
    return run


def _loop(run: Run, started: float) -> tuple[int, bool]:
    """The steps from `run.start`: each step's log record, validation and last.pt when due, until --steps or
    --time-limit (`scenes.cli.budget`: counted from this process's start; a step, a validation and a save start
    only when the longest of each so far still fits). Returns (steps done, whether --time-limit stopped it)."""
    cfg = run.cfg
    autocast = torch.autocast(device_type=run.device.type, dtype=torch.bfloat16, enabled=cfg.precision == "bf16")
    run.model.train()
    done, stopped, saved = run.start, False, run.start
    budget = Budget(cfg.time_limit * 60 if cfg.time_limit else None, start=started)
    last_ckpt = time.time()
    with Progress("train", "step", total=cfg.steps, done=run.start,
                  enabled=not cfg.no_progress and run.dist.main) as shown:
        for step in range(run.start, cfg.steps):
            if _out_of_time(run, budget, "step", "save"):
                if done == run.start:  # not one step fits: nothing is written
                    raise UsageError(f"--time-limit: {cfg.time_limit:g} min ran out before the first step (the start "
                                     f"took {budget.spent():.1f} s); expected a limit above that")
                stopped = True
                break
            t = time.time()
            parts, k = _train_step(run, step, autocast)
            budget.timed("step", time.time() - t)
            done = step + 1
            shown.update(done, postfix={"loss": f"{parts['loss']:.4f}", "k": k})
            run.summary["last_loss"] = parts["loss"]
            # The first step's record too: the log marks the folder as a run's before any last.pt is saved (a run
            # killed then is still known as this command's by --overwrite and --resume).
            if run.dist.main and (done % cfg.log_every == 0 or done == cfg.steps or done == 1):
                append_log(run.log_path, {"step": done, **parts, "k": k, "lr": run.optimizer.param_groups[0]["lr"],
                                          "elapsed_s": round(run.elapsed(), 3)})
            if run.val_samples and (done % cfg.val_every == 0 or done == cfg.steps):  # rank 0 alone: no collective
                guess = budget.longest["step"] * max(1, math.ceil(len(run.val_samples) / max(1, cfg.batch)))
                if budget.seconds is not None and not budget.fits("validation", "save", first_guess=guess):
                    log.info("validation at step %d skipped: --time-limit %g min would be passed", done, cfg.time_limit)
                else:
                    t = time.time()
                    _validation(run, done)
                    budget.timed("validation", time.time() - t)
            now = time.time()
            if (done % cfg.ckpt_every == 0 or done == cfg.steps
                    or (cfg.ckpt_minutes and now - last_ckpt >= cfg.ckpt_minutes * 60)):
                save_last(run, done)
                budget.timed("save", time.time() - now)
                last_ckpt, saved = time.time(), done
    if stopped:
        if saved != done or not (run.out / "last.pt").exists():
            save_last(run, done)
        log.info("--time-limit %g min reached: stopped at step %d of %d", cfg.time_limit, done, cfg.steps)
        run.summary["stopped_at"] = done
    return done, stopped


STOPPED = ("interrupted: --out keeps the last whole checkpoint (last.pt, once one was written: every --ckpt-every "
           "steps and --ckpt-minutes) and the log up to it; continue with --resume (without a last.pt, start again)")
"""The one line of a stopped training."""


def main(argv: Sequence[str] | None = None) -> int:
    """CLI entry point; returns the process exit status."""
    from scenes.cli.errors import INPUT_ERRORS, report_error

    started = process_start() if argv is None else time.time()  # the command's clock; a call from Python: the call's
    try:
        cfg = config_from_args(argv)
        logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
        summary = train(cfg, started)
    except INPUT_ERRORS as exc:
        return report_error(exc)
    except OSError as exc:  # e.g. a full disk while writing a checkpoint: one line naming the file
        return report_error(exc, code=1)
    except KeyboardInterrupt:  # under torchrun (unsupervised): Ctrl-C reaches every worker; rank 0 says it
        if os.environ.get("RANK", "0") == "0":
            print(STOPPED, file=sys.stderr)
        return 130
    msg = f"trained steps {summary['start']}..{summary.get('stopped_at', summary['steps'])}"
    msg += " (--time-limit reached)" if "stopped_at" in summary else ""
    msg += f", last loss {summary.get('last_loss')}"
    if summary.get("best_val") is not None:
        msg += f", best validation mean angular error {summary['best_val']:.2f} deg"
    print(msg)
    best = ", best.safetensors (+ .json)" if summary.get("best_val") is not None else ""
    print(f"wrote {Path(cfg.out) / 'final.safetensors'} (+ .json){best}, last.pt and log.jsonl")
    return 0


if __name__ == "__main__":  # Ctrl-C stops the work whole, in one line (scenes.cli.supervise)
    from scenes.cli.supervise import run_supervised

    # Under torchrun each process is one of its workers: torchrun stops them itself, and one line per rank would say
    # "interrupted" where another rank had failed.
    from unips.distributed import under_torchrun

    sys.exit(main() if under_torchrun() else run_supervised("unips.train", main, STOPPED))
