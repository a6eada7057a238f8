"""The configuration of a training run (`TrainConfig`): the dataclass the `python -m unips.train` command line is
generated from (a flag per documented field, `scenes.cli.options`), its checks, and the settings a resumed run must
keep."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Annotated, Literal

from scenes.checks import check_choice
from scenes.cli.options import REQUIRED, CommaList, UseAppendAction, arg, check_fields, option
from unips.models.zoo import DEFAULT_TRAIN_MODEL


@dataclass
class TrainConfig:
    """Everything that determines a training run; the CLI fills it (`python -m unips.train --help`)."""

    data: str = REQUIRED
    """Training dataset directory (object folders with ground-truth normals), or several separated by commas
    (pooled, e.g. sets rendered with different seeds); or WebDataset shards of wildgen.export:
    'SHARDS/{000000..000099}.tar' or the SHARDS folder."""
    out: str = REQUIRED
    """Run directory: log.jsonl, last.pt, best.safetensors and final.safetensors (+ .json sidecars)."""
    val: str | None = None
    """Validation dataset directory (object folders with normal.tif), or its shards as --data takes them; held-out
    assets, test-like settings."""
    model: str = DEFAULT_TRAIN_MODEL
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
    schedule: Literal["cosine", "step"] = "cosine"
    """'cosine': linear warm-up over `warmup` steps then cosine decay to `min_lr_ratio` * lr; 'step': x`decay`
    every `decay_every` steps."""
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
    """Working resolution of the cached crops (the test resolution; normally above the model's canonical
    resolution: at or below it training warns that the canonical grid repeats the working pixels)."""
    seed: int = option(0, minimum=0, maximum=2**32 - 1)
    """Seed of every random choice (initial weights, objects, image subsets, pixels, augmentation)."""
    resume: bool = False
    """Continue from RUN/last.pt, bit for bit."""
    overwrite: bool = False
    """Start afresh in a run directory that already holds a run (its files are replaced)."""
    val_every: int = option(200, minimum=1)
    """Steps between validations."""
    val_pixels: int = option(2000, minimum=0)
    """Masked pixels scored per validation object (a fixed seeded subset; 0: all)."""
    val_probes: Annotated[list[str], CommaList, arg(metavar="P1,P2")] = option(
        default_factory=lambda: ["all", "one", "mask", "shuffled"]
    )
    """Probes of every validation (`unips.probes.PROBES`); 'all' is always included."""
    ckpt_every: int = option(200, minimum=1)
    """Steps between last.pt saves."""
    ckpt_minutes: float = option(0.0, minimum=0)
    """Also save last.pt every this many minutes of training (0: only every --ckpt-every steps)."""
    time_limit: float = option(0.0, minimum=0)
    """Wall-time budget of this command in minutes, counted from its start (0: no limit): a step, a validation and a
    save start only while the longest of each so far still fits; at the step reached last.pt and final.safetensors
    are written as at the end; --steps still sets the schedule."""
    log_every: int = option(10, minimum=1)
    """Steps between training records in log.jsonl."""
    threads: int = option(0, minimum=0)
    """torch CPU threads (0: all cores, divided among local processes under torchrun)."""
    device: str = "cpu"
    """torch device ('cpu', 'cuda'; under torchrun each process takes cuda:LOCAL_RANK)."""
    precision: Literal["fp32", "bf16"] = "fp32"
    """'fp32' or 'bf16' (autocast of the forward pass; for GPUs)."""
    no_augment: bool = False
    """Disable flips / transpose / RGB permutation."""
    interior_crop: float = option(0.0, minimum=0, maximum=1)
    """Probability that a training sample is a square cut from inside the object's mask and resized to the working
    resolution: no outline, so the normals must come from the images."""
    no_progress: bool = False
    """No progress bar."""
    model_option: Annotated[list[str], UseAppendAction, arg(metavar="KEY=VALUE")] = field(default_factory=list)
    """Model config overrides KEY=VALUE (JSON value), e.g. uniform_context=true; repeatable."""
    shuffle_buffer: int = option(0, minimum=0)
    """Shards only. 0: read every object into memory, as from folders (the same batches as the folders the shards
    came from); N > 0: stream the shards (data larger than memory), split across processes and loader workers,
    shuffled through a buffer of N objects per worker (unips.shard_data)."""
    loader_workers: int = option(2, minimum=0)
    """Worker processes decoding the streamed shards (with --shuffle-buffer; 0: in the training process)."""
    curriculum: bool = False
    """Train from simple to complex: the first --curriculum-fraction of the steps is split into one stage per
    complexity level present in the data (scene.json `level`, `wildgen.make --level`); stage j draws only objects
    of the j lowest levels, then every object is drawn. Every object needs a recorded level."""
    curriculum_fraction: float = option(0.5, above=0, maximum=1)
    """Fraction of the steps over which the curriculum adds the levels one by one (with --curriculum)."""

    def validate(self) -> "TrainConfig":
        """Raise ValueError naming the first bad field as its CLI flag."""
        from unips.probes import PROBES

        if not self.data:
            raise ValueError("--data: required (a dataset directory)")
        if not self.out:
            raise ValueError("--out: required (a run directory)")
        check_fields(self)
        from unips.inference import check_device

        check_device(self.device)  # before any data is read (torch failed in the first step)
        if self.min_images > self.max_images:
            raise ValueError(f"--min-images={self.min_images} exceeds --max-images={self.max_images}")
        for p in self.val_probes:
            check_choice(p, "--val-probes", PROBES)
        if self.resume and self.overwrite:
            raise ValueError("--resume and --overwrite: expected at most one of them")
        if self.resume and self.init_from:
            raise ValueError("--resume and --init-from: expected at most one of them (a resumed run keeps its weights)")
        if self.curriculum and self.shuffle_buffer:
            raise ValueError("--curriculum: needs every object in memory to choose them by level, "
                             f"got --shuffle-buffer {self.shuffle_buffer} (use --shuffle-buffer 0)")
        if self.shuffle_buffer:
            from unips.shard_data import is_shard_source
            from unips.train_data import data_roots

            folders = [str(r) for r in data_roots(self.data) if not is_shard_source(r)]
            if folders:
                raise ValueError(
                    f"--shuffle-buffer: streams WebDataset shards, {folders[0]!r} in --data is not a shard "
                    "source (export it with python -m wildgen.export, or use --shuffle-buffer 0)"
                )
        return self


# Settings that change the trajectory: a resumed run must use the same values.
TRAJECTORY_KEYS = ("model", "init_from", "batch", "lr", "weight_decay", "schedule", "warmup", "min_lr_ratio",
                   "decay_every", "decay", "clip_grad", "max_images", "min_images", "pixels", "canonical_points",
                   "seed", "res", "no_augment", "precision", "interior_crop", "shuffle_buffer", "curriculum",
                   "curriculum_fraction")


