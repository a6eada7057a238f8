"""One training run's bookkeeping (the loop itself is `unips.train`; the process's place in a torchrun job:
`unips.distributed`): the run folder (`RUN_FILES`; `check_run`: the checks before any work; `log.jsonl`
records), the run's model, data, optimiser and schedule (`setup_run` -> `Run`; `lr_factor`: warm-up + cosine or
step decay), and its checkpoint `last.pt`: resumed from (`resume_run`: the same trajectory settings and objects,
then every state) and saved (`save_last`)."""

from __future__ import annotations

import dataclasses
import json
import logging
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Sequence

import torch

from unips.distributed import Dist, init_distributed
from unips.train_config import TRAJECTORY_KEYS, TrainConfig
from unips.train_data import Sample, count_dataset_images, curriculum_pool, data_roots, describe_data, load_samples

log = logging.getLogger(__name__)


def model_options(items: Sequence[str]) -> dict[str, Any]:
    out = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise ValueError(f"--model-option: got {item!r}, expected KEY=VALUE")
        try:
            out[key] = json.loads(value)
        except json.JSONDecodeError:
            out[key] = value
        except (RecursionError, ValueError):  # nested too deeply, or an integer of thousands of digits
            raise ValueError(f"--model-option: the value of {key!r} is not a value a model option takes") from None
    return out


def append_log(path: Path, record: dict[str, Any]) -> None:
    """Append `record` to log.jsonl as one line (a non-finite loss as null: every line stays valid JSON)."""
    from scenes.files import json_text

    with path.open("a") as f:
        f.write(json_text(record, indent=None, sort_keys=True, newline=True))


def truncate_log(path: Path, step: int) -> None:
    """Drop records written after `step` by an interrupted run (they will be written again), and a last line torn
    by a kill; a damaged line before it is a ValueError naming the file and the line."""
    if not path.exists():
        return
    from scenes.files import atomic_write_text

    lines = [line for line in path.read_text(errors="replace").splitlines() if line.strip()]
    keep = []
    for n, line in enumerate(lines, 1):
        try:
            record = json.loads(line)
        except (ValueError, RecursionError):
            if n == len(lines):  # the last record, torn by a kill while it was appended: written again
                break
            raise ValueError(f"--resume: line {n} of {str(path)!r} is not a JSON record (the run's log is damaged); "
                             "move it away to resume without it") from None
        at = record.get("step", 0) if isinstance(record, dict) else None
        if not isinstance(at, int) or isinstance(at, bool):
            what = "a JSON object" if not isinstance(record, dict) else f"a step's record (its step is {at!r:.40})"
            raise ValueError(f"--resume: line {n} of {str(path)!r} is not {what}; the run's log is damaged: move it "
                             "away to resume without it")
        if at <= step:
            keep.append(line)
    atomic_write_text(path, "".join(line + "\n" for line in keep))


def lr_factor(cfg: TrainConfig, step: int) -> float:
    """Learning-rate multiplier of optimisation step `step` (0-based)."""
    if cfg.schedule == "step":
        return cfg.decay ** (step // cfg.decay_every)
    if cfg.warmup and step < cfg.warmup:
        return (step + 1) / cfg.warmup
    progress = min(1.0, (step - cfg.warmup) / max(1, cfg.steps - cfg.warmup))
    return cfg.min_lr_ratio + (1.0 - cfg.min_lr_ratio) * 0.5 * (1.0 + math.cos(math.pi * progress))


class TrainForward(torch.nn.Module):
    """encode + decode_pixels as one forward, so DistributedDataParallel sees the whole step."""

    def __init__(self, model: torch.nn.Module) -> None:
        super().__init__()
        self.model = model

    def forward(self, images: torch.Tensor, mask: torch.Tensor, coords: torch.Tensor) -> torch.Tensor:
        contexts = self.model.encode(images, mask)  # (B, k, C, s/4, s/4)
        return self.model.decode_pixels(contexts, images, mask, coords)  # (B, N, 3)


def load_init_weights(cfg: TrainConfig, device: torch.device) -> torch.nn.Module:
    """The model of `cfg.init_from` (weights only) on `device`, in training mode (`read_init_weights`)."""
    return read_init_weights(cfg).to(device).train()


def read_init_weights(cfg: TrainConfig, explicit: bool = False) -> torch.nn.Module:
    """The model of `cfg.init_from` (weights only, on the CPU); its name must agree with a typed --model (`explicit`,
    or not the default), and no --model-option may reshape it. Every refusal names the flag."""
    from scenes.cli.outputs import check_not_being_written
    from unips.checkpoint import load_model

    check_not_being_written(cfg.init_from, "--init-from")  # a run still training: one step of many
    try:
        model, meta = load_model(cfg.init_from)
    except (ValueError, FileNotFoundError) as exc:  # the reader's message, with the flag that named the file
        raise type(exc)(f"--init-from: {exc}") from None
    name = meta.get("model_name")
    if (explicit or cfg.model != TrainConfig.model) and cfg.model != name:
        raise ValueError(f"--model={cfg.model!r}: --init-from {cfg.init_from!r} holds a {name!r} model")
    if cfg.model_option:
        raise ValueError("--model-option: not allowed with --init-from (the weights fix the configuration)")
    return model


RUN_FILES = ("log.jsonl", "last.pt", "best.safetensors", "best.json", "final.safetensors", "final.json")
"""The files a run writes into --out (nothing else there is touched)."""

TRAIN_BYTES_PER_IMAGE = 80 * 2**20
"""Memory of one image of a training batch that does not grow with --res (the encoder's activations and their
gradients at the canonical resolution): twice the 36-40 MB measured for glc-small on the CPU."""
TRAIN_BYTES_PER_PIXEL_IMAGE = 24 * 2**10
"""Memory of one sampled pixel (--pixels) of one image of a training batch (the pixel decoder's activations and
their gradients): twice the 11.8 KB measured for glc-small on the CPU (peak memory of 2 steps at --pixels 500 and
20000, batch 4 x 4 images)."""


def check_run(cfg: TrainConfig) -> None:
    """Everything about the run folder and the size of the run, before any work: --out writable, an earlier
    run's files replaced only with --overwrite (or continued with --resume; `scenes.cli.outputs.claim_outputs`), and
    the memory of the cached samples and of one batch (`training_memory`) against what this machine has."""
    from scenes.cli.limits import check_memory, check_threads
    from scenes.cli.outputs import check_not_being_written, check_output_folder, check_replaceable, claim_outputs

    out = Path(cfg.out)
    check_output_folder(out)
    if cfg.resume:  # a resumed run replaces last.pt and the rest in place: a mounted one fails after the log grew
        check_replaceable(out, "--out", "unips.train --resume")
        # and each of them a plain file: a folder or link there was found only after the last step (sweep 41)
        claim_outputs([out / n for n in RUN_FILES if os.path.lexists(out / n)], True, owner="unips.train --resume")
    for flag, value in (("--data", cfg.data), ("--val", cfg.val)):
        for root in data_roots(value, flag) if value else []:
            check_not_being_written(root, flag)  # a dataset wildgen.make is still rendering
    check_threads(cfg.threads or None, "--threads")
    if not cfg.resume:
        claim_outputs(  # an earlier run's files: beside its log.jsonl, which every run writes from its first step
            [out / n for n in RUN_FILES], cfg.overwrite, owner="unips.train", resume="--resume to continue it",
            marker=out / "log.jsonl")
        if cfg.overwrite and (out / "log.jsonl").exists() and not _is_training_log(out / "log.jsonl"):
            raise ValueError(f"--out: {str(out / 'log.jsonl')!r} was not written by unips.train (its first line is "
                             "not a step's record); it is never replaced, even with --overwrite: move it away or use "
                             "another --out")
        best = [out / n for n in ("best.safetensors", "best.json") if os.path.lexists(out / n)]
        if cfg.overwrite and best and not _validated(out / "log.jsonl"):  # the earlier run never wrote one
            raise ValueError(f"--out: {str(best[0])!r} was not written by unips.train (the earlier run's log.jsonl "
                             "records no validation, after which it is written); it is never replaced, even with "
                             "--overwrite: move it away or use another --out")
    objects, images = count_dataset_images(cfg.data, "--data")
    if cfg.shuffle_buffer:  # streamed: only the samples in flight are decoded (loader queues and one batch)
        in_flight = min(objects, 2 * max(cfg.loader_workers, 1) + cfg.batch)
        images = -(-images * in_flight // max(objects, 1))
    if cfg.val:
        more = count_dataset_images(cfg.val, "--val")
        objects, images = objects + more[0], images + more[1]
    check_memory(training_memory(cfg, images), "--res/--batch/--max-images/--pixels",
                 f"training at {cfg.res} x {cfg.res} px on {objects} cached objects ({images} images) with batches of "
                 f"{cfg.batch} x {cfg.max_images} images, {cfg.pixels} pixels each",
                 "lower --res, --batch, --max-images or --pixels")


def _is_training_log(path: Path) -> bool:
    """Whether `path` starts as a run's log.jsonl does: a JSON object with its step."""
    try:
        with open(path, encoding="utf-8") as f:
            first = json.loads(f.readline(1 << 16))
    except (OSError, ValueError, RecursionError):
        return False
    return isinstance(first, dict) and "step" in first


def _validated(log: Path) -> bool:
    """Whether a run's log.jsonl records a validation (a best.safetensors is written only after one)."""
    try:
        with open(log, encoding="utf-8") as f:
            return any('"val"' in line and "val" in json.loads(line) for line in f)
    except (OSError, ValueError, RecursionError):
        return False


def training_memory(cfg: TrainConfig, cached_images: int) -> int:
    """Bytes of a run (a conservative estimate): the cached samples (float16 images, mask and normals at --res)
    and one batch (per image TRAIN_BYTES_PER_IMAGE, 6 float32 copies of it at --res and TRAIN_BYTES_PER_PIXEL_IMAGE
    per sampled pixel)."""
    pixels = cfg.res ** 2
    cache = cached_images * pixels * 6 + pixels * 16 * max(cached_images, 1)
    per_image = TRAIN_BYTES_PER_IMAGE + pixels * 72 + cfg.pixels * TRAIN_BYTES_PER_PIXEL_IMAGE
    return cache + cfg.batch * cfg.max_images * per_image


def prepare_run_dir(cfg: TrainConfig, dist: Dist) -> Path:
    """The run directory (checked by `check_run`); with --overwrite an earlier run's files are removed first
    (a best.safetensors of the old run must not survive a new run without --val)."""
    out = Path(cfg.out)
    if dist.main:
        try:
            out.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise ValueError(f"--out {cfg.out!r}: cannot create the run directory ({exc.strerror})") from exc
        if cfg.overwrite:
            for n in RUN_FILES:
                (out / n).unlink(missing_ok=True)
    return out


@dataclass
class Run:
    """One training run: what the loop reads and updates."""

    cfg: TrainConfig
    dist: Dist
    device: torch.device
    out: Path
    model: torch.nn.Module
    step_model: torch.nn.Module  # the model's training forward, wrapped by DistributedDataParallel under torchrun
    optimizer: torch.optim.Optimizer
    scheduler: Any
    samples: list[Sample]  # the cached training objects (empty when streaming)
    val_samples: list[Sample]
    data_desc: dict[str, Any]  # describe_data(): stored in checkpoints, compared on resume
    train_args: dict[str, Any]  # the settings that change the trajectory (TRAJECTORY_KEYS, model name)
    start: int = 0  # first step to run
    best: float = math.inf  # lowest validation error so far
    elapsed_before: float = 0.0  # training seconds of the steps a resumed run keeps (so elapsed_s counts the whole run)
    t_start: float = 0.0
    summary: dict[str, Any] = dataclasses.field(default_factory=dict)
    stream: Any = None  # streamed shards (--shuffle-buffer): this process's iterator of training samples

    @property
    def log_path(self) -> Path:
        return self.out / "log.jsonl"

    @property
    def last_path(self) -> Path:
        return self.out / "last.pt"

    def elapsed(self) -> float:
        return time.time() - self.t_start


def setup_run(cfg: TrainConfig) -> Run:
    """Processes, run directory, initial model (seeded), data, optimiser and schedule of a run."""
    from unips.models import create_model

    dist = init_distributed(cfg)
    torch.set_num_threads(cfg.threads or max(1, (os.cpu_count() or 1) // dist.world))
    device = torch.device(f"cuda:{dist.local_rank}" if cfg.device == "cuda" and dist.world > 1 else cfg.device)
    out = prepare_run_dir(cfg, dist)
    torch.manual_seed(cfg.seed)  # initial weights
    if cfg.init_from:
        model = load_init_weights(cfg, device)
    else:
        options = model_options(cfg.model_option)
        try:
            model = create_model(cfg.model, **options).to(device)
        except (TypeError, ValueError) as exc:  # a value of the wrong kind fails deep in the model's constructor
            if str(exc).startswith("--model-option"):
                raise
            raise ValueError(f"--model-option: {', '.join(cfg.model_option)} does not build {cfg.model} "
                             f"({str(exc).splitlines()[0][:160]}); expected values of each field's type") from None
    if cfg.shuffle_buffer:  # streamed shards: nothing cached, their index describes the data (`open_stream`)
        samples, data_desc = [], stream_description(cfg, dist)
    else:
        samples = load_samples(cfg.data, cfg.res)
        data_desc = describe_data(samples, cfg.data, cfg.res)
    val_samples = load_samples(cfg.val, cfg.res, arg="--val") if cfg.val and dist.main else []
    if cfg.curriculum:
        curriculum_pool([s.level for s in samples], 0, cfg.steps, cfg.curriculum_fraction)  # every level recorded
        log.info("curriculum over levels %s in the first %d of %d steps", sorted({s.level for s in samples}),
                 int(cfg.curriculum_fraction * cfg.steps), cfg.steps)
    too_few = [s.name for s in samples if s.num_images < cfg.min_images]
    too_few += [
        o for o, k in zip(data_desc["objects"], data_desc["images"]) if cfg.shuffle_buffer and k < cfg.min_images
    ]
    if too_few:
        raise ValueError(f"--min-images={cfg.min_images}: objects with fewer images: {too_few[:5]}")
    canonical = model.config.canonical_resolution
    if canonical >= cfg.res:
        log.warning("working resolution %d is not above the canonical resolution %d: the canonical grid "
                    "repeats the working pixels", cfg.res, canonical)
    train_args = {k: getattr(cfg, k) for k in TRAJECTORY_KEYS}
    train_args["model"] = getattr(model, "model_name", cfg.model)
    train_args["model_option"] = list(cfg.model_option)
    if cfg.shuffle_buffer:  # the stream's order depends on how many workers read it
        train_args["loader_workers"] = cfg.loader_workers
    step_model: torch.nn.Module = TrainForward(model)
    if dist.world > 1:
        from torch.nn.parallel import DistributedDataParallel

        step_model = DistributedDataParallel(step_model, device_ids=[device.index] if device.type == "cuda" else None)
    optimizer = torch.optim.AdamW(model.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    scheduler = torch.optim.lr_scheduler.LambdaLR(optimizer, lambda s: lr_factor(cfg, s))
    return Run(cfg, dist, device, out, model, step_model, optimizer, scheduler, samples, val_samples, data_desc,
                train_args)


def stream_description(cfg: TrainConfig, dist: Dist) -> dict[str, Any]:
    """`describe_data` of streamed shards, from their index; fewer shards than processes x loader workers refused."""
    from types import SimpleNamespace

    from unips.shard_data import check_split, resolve_shards

    shards = [s for r in data_roots(cfg.data) for s in resolve_shards(r)]
    check_split(shards, dist.world, cfg.loader_workers)
    objects = [SimpleNamespace(name=o["name"], num_images=int(o.get("images", 0))) for s in shards for o in s.objects]
    return describe_data(objects, cfg.data, cfg.res, [str(s.entry.get("sha256")) for s in shards])


def open_stream(run: Run) -> Any:
    """This process's endless iterator of streamed training samples (`unips.shard_data.stream_samples`: its rank's
    shards, shuffled, seeded by --seed), past the samples that the steps before `run.start` took (a resume)."""
    from functools import partial

    from unips.shard_data import stream_samples
    from unips.train_data import data_roots, prepare_sample

    cfg = run.cfg
    return stream_samples(data_roots(cfg.data), partial(prepare_sample, res=cfg.res), seed=cfg.seed,
                          buffer=cfg.shuffle_buffer, workers=cfg.loader_workers, world=run.dist.world,
                          skip=run.start * (cfg.batch // run.dist.world))


def resume_run(run: Run) -> None:
    """Continue from RUN/last.pt: the same trajectory settings and objects, then weights, optimiser, schedule,
    random states, step, best validation and elapsed time."""
    from scenes.files import not_a_file
    from unips.checkpoint import load_state_strict, load_training_checkpoint, restore_training_state
    from unips.train_data import data_change

    cfg = run.cfg
    if not os.path.lexists(run.last_path) and not os.path.lexists(run.log_path):  # no run there at all
        raise ValueError(f"--resume: {str(Path(cfg.out))!r} holds no run of unips.train to continue (no log.jsonl, "
                         "no last.pt); start one there without --resume")
    if not os.path.lexists(run.last_path):  # a run stopped before its first checkpoint: nothing to continue
        raise ValueError(f"--resume: {str(run.last_path)!r} does not exist (the run stopped before its first "
                         "checkpoint); start it again without --resume, with --overwrite to replace its log")
    if os.path.lexists(run.log_path) and (why := not_a_file(run.log_path)):  # the log is continued from last.pt
        raise ValueError(f"--resume: the run's log {str(run.log_path)!r} {why} (the log.jsonl unips.train writes); "
                         "restore it, or start the run again with --overwrite")
    try:
        ckpt = load_training_checkpoint(run.last_path)
    except ValueError as exc:
        raise ValueError(f"--resume: {exc}") from None
    old = ckpt["extra"].get("train_args", {})
    defaults = dataclasses.asdict(TrainConfig())
    # A resumed run keeps its weights (last.pt), so --resume takes no --init-from: its lineage is the checkpoint's.
    run.train_args["init_from"] = old.get("init_from")
    for key, value in run.train_args.items():
        saved = old.get(key, defaults.get(key))  # a key newer than the checkpoint had its default there
        if saved != value:
            raise ValueError(f"--resume: --{key.replace('_', '-')} {value!r} differs from the checkpoint's {saved!r}")
    if (change := data_change(ckpt["data"], run.data_desc)) is not None:
        raise ValueError(f"--resume: the objects in --data {cfg.data!r} differ from the checkpoint's ({change})")
    step = ckpt["step"]
    if not isinstance(step, int) or isinstance(step, bool) or not 0 <= step < 2**62:  # checked before the log is cut
        raise ValueError(f"--resume: {str(run.last_path)!r} records step {step!r:.40}, expected a whole number of "
                         "steps; the checkpoint is damaged: restore it, or start again with --overwrite")
    load_state_strict(run.model, ckpt["model"], str(run.last_path))
    restore_training_state(run.last_path, ckpt, run.optimizer, run.scheduler)
    best, elapsed = ckpt["extra"].get("best_val", math.inf), ckpt["extra"].get("elapsed_s", 0.0)
    if not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in (best, elapsed)) or math.isnan(
            best) or not math.isfinite(elapsed) or elapsed < 0:
        raise ValueError(f"--resume: {str(run.last_path)!r} records best_val {best!r:.40} and elapsed_s "
                         f"{elapsed!r:.40}, expected numbers; the checkpoint is damaged: restore it, or start again "
                         "with --overwrite")
    run.start, run.best, run.elapsed_before = int(ckpt["step"]), float(best), float(elapsed)
    if run.dist.main:
        truncate_log(run.log_path, run.start)
    log.info("resumed from %s at step %d", run.last_path, run.start)


def save_last(run: Run, step: int) -> None:
    """The full training checkpoint RUN/last.pt (rank 0)."""
    from unips.checkpoint import save_training_checkpoint

    if run.dist.main:
        save_training_checkpoint(run.last_path, model=run.model, optimizer=run.optimizer, scheduler=run.scheduler,
                                 step=step, data=run.data_desc,
                                 extra={"train_args": run.train_args, "best_val": run.best,
                                        "elapsed_s": round(run.elapsed(), 3)})
