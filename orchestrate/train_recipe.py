"""The reproducible training recipe: data, held-out split, training, the ship decision, evaluation.

    python -m orchestrate.train_recipe --work /tmp/recipe [--assets ../shared/assets] [--model NAME]
                                       [--init-from WEIGHTS] [--train-seed 5000[,SEED...]] [--train-objects 800]
                                       [--steps 4000] [--threads 2] [--ablation] [--ship]

1. Split the asset folder: the last quarter of the meshes and the last fifth of the HDR maps (sorted by
   name, rounded up; with ../shared/assets: 5 of 19 meshes, 7 of 35 maps) are held out for validation
   and test; texture sets are shared (there are only eight).
2. Render with `wildgen.make`, the PS-Wild light families (`wildgen.light_families.PS_WILD_FAMILIES`) cycled:
   train (seed `--train-seed`, 128 px, 10 images, 16 spp, train assets; a new seed gives fresh data for a
   continued run; several seeds, comma-separated, give one set each, pooled for training), the fixed
   validation set (seed 4000, 100 objects, 128 px, 10 images, 32 spp, held-out assets: the test
   distribution) and the test set (seed 3000, 100 objects, same settings).
3. Train with `unips.train` (warm-up + cosine, gradient clipping, 1..10 images per sample, probes at
   every validation), from scratch or `--init-from` earlier weights. `--ablation` then trains the
   spatially uniform context variant with the same budget, after the main run (never alongside it).
4. `--ship` compares the best weights with the shipped weights of the same registered model (measured
   here, same probes) and, only if their all-images error on the fixed validation set is lower (or that
   model has no shipped weights yet), copies them to that model's pretrained entry in the registry
   (`unips/weights/`, where `create_model(name, pretrained=True)` loads them) and updates its model card
   (figures, lineage: continued when `--init-from` is the shipped file, restarted otherwise). A model
   without a pretrained entry is refused before any work.
5. Evaluate with `python -m orchestrate.benchmark` on the test set (and DiLiGenT when ../shared has it).
`--minutes` is the wall time of the whole recipe (`scenes.cli.budget`, counted from its start): each step starts
only while time is left, a step still running at the end is stopped, and a training run stops itself before it
(`unips.train --time-limit`; such a run is not finished: the next run of the recipe resumes it). The recipe then
stops with one line naming --minutes (exit 2).
Every step resumes or is skipped when its output already exists, so an interrupted recipe is re-run as is;
`--overwrite` starts afresh instead. Every step's arguments (and --assets, decoded) are checked before the
first step runs, and a failed step is reported as one line (`orchestrate.steps`).
"""
from __future__ import annotations

import os
import platform
import shutil
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

from orchestrate.asset_split import SPLIT_FOLDERS, check_split, split_assets
from orchestrate.steps import STOP_GRACE_S, OutOfTime, StepFailed, check_step, run_step
from scenes.cli.budget import Budget, end_reserve
from scenes.cli.errors import INPUT_ERRORS, UsageError, report_error
from scenes.cli.needs import Needs
from scenes.cli.options import REQUIRED, Command, arg, check_fields, comma_list, option
from scenes.cli.outputs import check_output_folder
from scenes.files import atomic_write, atomic_write_text, read_json, write_json
from wildgen.light_families import PS_WILD_FAMILIES

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"
FAMILIES = ["--lights", ",".join(PS_WILD_FAMILIES)]
VAL_FLAGS = ["--objects", "100", "--images", "10", "--res", "128", "--spp", "32", "--seed", "4000"]
TEST_FLAGS = ["--objects", "100", "--images", "10", "--res", "128", "--spp", "32", "--seed", "3000"]


def make_argv(args: RecipeOptions, work: Path, name: str, assets: str | None) -> list[str]:
    """The wildgen.make command line (after `python -m wildgen.make`) of dataset `name` (train<seed>, val128,
    test128)."""
    if name.startswith("train"):
        flags = ["--objects", str(args.train_objects), "--images", "10", "--res", "128", "--spp", "16", "--gt-spp", "4",
                 "--seed", name[len("train"):]]
    else:
        flags = VAL_FLAGS if name == "val128" else TEST_FLAGS
    return [*FAMILIES, *flags, *(["--assets", assets] if assets else []), "--out", str(work / name), "--quiet",
            *(["--overwrite"] if args.overwrite else [])]


def train_argv(args: RecipeOptions, work: Path, name: str, extra: list[str], minutes: float = 0.0) -> list[str]:
    """The unips.train command line of run `name` (resumed when its last.pt exists, unless --overwrite); `minutes`:
    its --time-limit (0: none)."""
    out = work / "runs" / name
    resume = ["--resume"] if (out / "last.pt").is_file() and not args.overwrite else []
    init = ["--init-from", args.init_from] if args.init_from and not resume and not extra else []
    model = [] if init or args.model is None else ["--model", args.model]  # None: unips.train's, DEFAULT_TRAIN_MODEL
    data = ",".join(str(work / f"train{seed}") for seed in args.train_seed)
    return ["--data", data, "--val", str(work / "val128"), *model, *init, "--out", str(out), "--steps", str(args.steps),
            "--batch", "4", "--lr", str(args.lr), "--val-every", "500", "--ckpt-every", "250", "--seed", "0",
            "--threads", str(args.threads), "--no-progress", *extra, *resume,
            *(["--time-limit", f"{minutes:.4f}"] if minutes else []),
            *(["--overwrite"] if args.overwrite else [])]


ABLATION = ["--model-option", "uniform_context=true"]


def bench_argv(args: RecipeOptions, work: Path) -> list[str]:
    """The orchestrate.benchmark command line of the test set."""
    argv = ["--data", str(work / "test128"), "--checkpoint", str(work / "runs" / "main" / "best.safetensors"),
            "--out", str(work / "benchmark")]
    if args.ablation:
        argv += ["--ablation-checkpoint", str(work / "runs" / "uniform" / "best.safetensors")]
    if (SHARED / "data" / "diligent").is_dir():
        argv += ["--diligent", str(SHARED / "data" / "diligent")]
    return argv + (["--overwrite"] if args.overwrite else [])


def trained_steps(run: Path) -> int | None:
    """The step a run's final.safetensors was written at (its final.json), None without one: a run stopped by
    its time limit writes it too, at the step reached."""
    try:
        step = read_json(run / "final.json")["extra"]["step"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return step if isinstance(step, int) else None


class Clock:
    """--minutes of the whole recipe (`scenes.cli.budget`): each step starts only while time is left, and is
    stopped (SIGTERM, then SIGKILL after `STOP_GRACE_S`) early enough for the recipe to end within the budget."""

    def __init__(self, minutes: float):
        self.minutes, self.budget = minutes, Budget(minutes * 60 if minutes else None)

    @property
    def stop_at(self) -> float | None:
        """When a running step is stopped (None: no budget)."""
        if not self.minutes:
            return None
        return self.budget.deadline - end_reserve(self.minutes * 60) - STOP_GRACE_S

    def over(self, what: str) -> OutOfTime:
        return OutOfTime(f"--minutes: {self.minutes:g} min ran out {what} (after {self.budget.spent():.0f} s; expected "
                         "a budget that fits the recipe: re-run the same command to continue, or raise --minutes)", 2)

    def step(self, cmd: list[str], **kw) -> bool:
        if self.stop_at is not None and time.time() >= self.stop_at:
            raise self.over(f"before step {' '.join(map(str, cmd[2:4]))}")
        return run_step(cmd, deadline=self.stop_at, out_of_time=f"--minutes: {self.minutes:g} min ran out",
                        **kw)

    def train_minutes(self) -> float:
        """The --time-limit of a training run started now: what is left before `stop_at` (0: no budget)."""
        if self.stop_at is None:
            return 0.0
        left = self.stop_at - time.time()
        if left <= 0:
            raise self.over("before a training run")
        return left / 60


def train_run(
    py: str, work: Path, name: str, args: RecipeOptions, extra: list[str], clock: Clock | None = None
) -> Path:
    """Train one run into work/runs/NAME (resumed when interrupted or stopped by a time limit, skipped when
    finished, i.e. trained to --steps, unless --overwrite); returns the run folder."""
    out, clock = work / "runs" / name, clock or Clock(0.0)
    if (trained_steps(out) or 0) >= args.steps and not args.overwrite:
        print(f"run {out} is finished (final.safetensors at step {args.steps}), kept", flush=True)
        return out
    t0 = time.time()
    clock.step([py, "-m", "unips.train", *train_argv(args, work, name, extra, clock.train_minutes())])
    atomic_write_text(out / "wall_time_s.txt", f"{time.time() - t0:.0f}\n")
    reached = trained_steps(out)
    if reached is not None and reached < args.steps:
        raise clock.over(f"during training run {name} (stopped at step {reached} of {args.steps}; re-run the same "
                         "command to resume it)")
    return out


@dataclass
class RecipeOptions:
    """The command line of orchestrate.train_recipe."""

    work: str = REQUIRED
    """Working folder (datasets, runs, benchmark output)."""
    assets: Annotated[str | None, arg(help_behavior_hint="(default: ../shared/assets when it exists)")] = None
    """Asset folder, split into train / held-out assets ('none': procedural shapes and lights only)."""
    model: Annotated[str | None, arg(help_behavior_hint="(default: unips.models.DEFAULT_TRAIN_MODEL)")] = None
    """Registered model trained from scratch (`unips.models.list_models()`)."""
    init_from: str | None = None
    """Weights to continue from (weights only; e.g. unips/weights/...)."""
    train_seed: Annotated[list[int], comma_list(int), arg(metavar="SEED[,SEED...]")] = option(
        default_factory=lambda: [5000], minimum=0
    )
    """Seed of the training data (new seed: fresh data); several, comma-separated: one set each, pooled."""
    train_objects: int = option(800, minimum=1)
    """Objects per training set."""
    steps: int = option(4000, minimum=1)
    """Training steps."""
    lr: float = option(1e-3, above=0)
    """Peak learning rate."""
    threads: int = option(2, minimum=1)
    """Torch threads of the (single) training run."""
    ablation: bool = False
    """Then train the uniform-context ablation, same budget."""
    minutes: float = option(0.0, minimum=0)
    """Wall-time budget of the whole recipe in minutes, counted from its start (0: no limit): each step starts only
    while time is left; a training run stops before the end and is resumed by the next run of the recipe."""
    ship: bool = False
    """Ship the best weights if the fixed validation improves (see 4. above)."""
    overwrite: bool = False
    """Start afresh in --work: split the assets again, and every step replaces its earlier output (datasets
    rendered again, runs trained again, benchmark recomputed); files the recipe did not write are never touched.
    Without it, a re-run continues: datasets resume, finished runs and an existing benchmark are kept."""

    def validate(self) -> "RecipeOptions":
        """The flags, the --work folder, and with --ship the registry entry (the steps: `check_steps`)."""
        check_fields(self)
        if not self.train_seed or len(set(self.train_seed)) != len(self.train_seed):
            raise ValueError(f"--train-seed: got {','.join(map(str, self.train_seed))!r}, expected distinct integers "
                             "separated by commas")
        held = {int(VAL_FLAGS[-1]): "validation", int(TEST_FLAGS[-1]): "test"}  # their objects' draws, again
        if clash := next((s for s in self.train_seed if s in held), None):
            raise ValueError(f"--train-seed: {clash} is the seed of the fixed {held[clash]} set; expected another (the "
                             "same seed draws the same shapes, materials and lights: the model would be scored on "
                             "what it was trained on)")
        check_output_folder(self.work, "--work")
        if self.ship:
            shipped_name(self)  # the registry must know where the trained model's weights go
        return self


def check_steps(args: RecipeOptions) -> bool:
    """Every step's arguments, before the first runs (`orchestrate.steps.check_step`): --assets decoded (the
    training set's wildgen.make with the whole asset folder), the other datasets' flags, the training runs'
    (model name, --init-from read), the benchmark's (DiLiGenT read), and the asset split already in --work.
    Returns whether the split must be written."""
    work = Path(args.work)
    assets = Path(args.assets) if args.assets else None
    if assets is not None:
        from scenes.cli.outputs import check_apart
        from scenes.files import is_within
        from wildgen.assets import AssetLibrary

        check_apart(work, {"--assets": assets}, "--work")  # the split's folders would land inside the assets
        if is_within(assets, work):  # and the other way round: the datasets and the split among the assets
            raise UsageError(f"--assets: {str(assets)!r} lies inside --work {str(work)!r}, where the asset split and "
                             "the datasets are written; expected an asset folder outside it")

        AssetLibrary.scan(assets)  # names --assets when it is missing or empty
    names = [*(f"train{seed}" for seed in args.train_seed), "val128", "test128"]  # every dataset step's folder
    for i, name in enumerate(names):
        check_step("wildgen.make", make_argv(args, work, name, str(assets) if assets and i == 0 else None))
    check_step("unips.train", train_argv(args, work, "main", []))
    if args.ablation:
        check_step("unips.train", train_argv(args, work, "uniform", ABLATION))
    if not (work / "benchmark" / "benchmark.json").is_file() or args.overwrite:
        check_step("orchestrate.benchmark", bench_argv(args, work))
    return check_split(assets, work, args.overwrite)


COMMAND = Command(RecipeOptions, prog="python -m orchestrate.train_recipe", description=__doc__, needs=(
    Needs("model", lambda c, _: c.init_from is None, "without --init-from (the weights name their own model)"),))


def main(argv: list[str] | None = None) -> int:
    """A failed step is one line naming the step and its own error (`orchestrate.steps`), exit status its own."""
    try:
        args = COMMAND.parse(argv).validate()
        if args.assets is None and (SHARED / "assets").is_dir():
            args.assets = str(SHARED / "assets")
        args.assets = None if args.assets == "none" else args.assets  # as every command that takes --assets
        from scenes.cli.outputs import output_lock

        with output_lock(args.work, "--work"):  # one recipe per folder (its steps hold their own subfolders too)
            return recipe(args, check_steps(args))  # the steps checked under the hold: their folders are inside
    except OutOfTime as exc:  # says how to go on itself
        return report_error(exc, code=exc.code)
    except StepFailed as exc:
        return report_error(UsageError(f"{exc} (the finished steps are kept: once this is fixed, the same command "
                                       "resumes)"), code=exc.code)
    except (*INPUT_ERRORS, OSError) as exc:
        return report_error(exc)


def recipe(args: RecipeOptions, split: bool = True) -> int:
    """Every step of the recipe (see the module doc), after the options and steps were checked (`check_steps`);
    `split`: write the asset split (False: --work holds it already)."""
    py, clock = sys.executable, Clock(args.minutes)
    work = Path(args.work)
    print(f"training recipe in {work}: datasets {', '.join(f'train{s}' for s in args.train_seed)}, val128, test128; "
          f"runs main{', uniform' if args.ablation else ''}; benchmark", flush=True)
    work.mkdir(parents=True, exist_ok=True)
    assets: tuple[str | None, str | None] = (None, None)
    if args.assets:
        if split:
            split_assets(Path(args.assets), work)
        assets = (str(work / SPLIT_FOLDERS[0]), str(work / SPLIT_FOLDERS[1]))
    for name in [*(f"train{seed}" for seed in args.train_seed), "val128", "test128"]:
        # Always run: on an existing dataset wildgen.make resumes (verifies finished objects, renders the rest).
        clock.step(
            [py, "-m", "wildgen.make", *make_argv(args, work, name, assets[0 if name.startswith("train") else 1])]
        )
    main_run = train_run(py, work, "main", args, [], clock)
    if args.ablation:
        train_run(py, work, "uniform", args, ABLATION, clock)
    if args.ship:
        if clock.stop_at is not None and time.time() >= clock.stop_at:
            raise clock.over("before --ship")
        ship(work / "val128", main_run, args)
    if (work / "benchmark" / "benchmark.json").is_file() and not args.overwrite:
        print(f"benchmark {work / 'benchmark'} exists, kept (--overwrite computes it again)", flush=True)
    else:
        clock.step([py, "-m", "orchestrate.benchmark", *bench_argv(args, work)])
    print(f"recipe done: weights {main_run / 'best.safetensors'}, tables {work / 'benchmark' / 'tables.md'}")
    return 0


def _val_probes(weights: Path, val: Path, threads: int, flag: str = "--data") -> dict:
    """Probe summary of `weights` on the fixed validation set (as unips.train validates)."""
    import torch

    from unips.models import load_model
    from unips.train import TrainConfig
    from unips.train_data import load_samples, probe_samples

    torch.set_num_threads(threads)
    cfg = TrainConfig()
    model, _ = load_model(weights)
    samples = load_samples(val, cfg.res, arg=flag)
    res = probe_samples(model, samples, cfg.max_images, torch.device("cpu"), probes=cfg.val_probes,
                        pixels=cfg.val_pixels)
    res.pop("objects", None)
    return res


def shipped_name(args: RecipeOptions) -> str:
    """The registered model a recipe run trains (`--model`, or the model of `--init-from`), checked to have a
    shipped-weights entry in the registry: called before any work when `--ship` is given."""
    from unips.models import DEFAULT_TRAIN_MODEL, load_model, pretrained_entry

    name = load_model(args.init_from)[1]["model_name"] if args.init_from else args.model or DEFAULT_TRAIN_MODEL
    try:
        pretrained_entry(name)
    except ValueError as exc:
        which = f"--init-from {args.init_from!r} holds" if args.init_from else "--model is"
        raise ValueError(f"--ship: {which} {name!r}, which has no place for shipped weights in the registry "
                         f"({exc})") from None
    _card(pretrained_entry(name).card_path)  # a damaged card is found before any work, not after training
    return name


def _card(path: Path) -> dict:
    """The model card --ship updates, one line naming --ship and the file when it is damaged."""
    from unips.models.registry import read_model_card

    try:
        return read_model_card(path)
    except ValueError as exc:
        raise ValueError(f"--ship: {exc}") from None


def _probe_card(res: dict, val_pixels: int) -> dict:
    """The model card's form of a validation summary (`unips.probes.summarise` via unips.train_data.probe_samples)."""
    def r(v: float) -> float:
        return round(float(v), 1)

    return {"data": VALIDATION_DATA, "scored_pixels_per_object": val_pixels,
            "probes_deg": {k: r(v) for k, v in res["probes"].items()}, "photometric_gain_deg": r(res["gain"]),
            "per_family": {f: {**{k: r(v) for k, v in b["mean"].items()}, "gain": r(b["gain"]), "n": b["n"]}
                           for f, b in res.get("families", {}).items() if "gain" in b}}


def _display(path: Path) -> str:
    path = path.resolve()
    return str(path.relative_to(REPO)) if path.is_relative_to(REPO) else str(path)


# Card entries that describe one set of weights (measured by orchestrate.benchmark): kept under replaced_model_*
# when new weights are shipped, until the benchmark of the new ones is copied in.
MEASURED_KEYS = ("test_set", "test_set_deg", "diligent", "diligent_deg")
VALIDATION_DATA = "seed 4000, 100 objects, 128 px, 10 images, 32 spp, held-out meshes and HDR maps"


def install_weights(weights: Path, entry, card: dict) -> None:
    """Copy `weights` (and its .json sidecar) to the registry's pretrained entry `entry` and write its model card
    `card` (orchestrate.ship uses this too)."""
    from unips.models.builder import sidecar_path

    current = entry.weights_path
    current.parent.mkdir(parents=True, exist_ok=True)
    for src, dst in ((weights, current), (sidecar_path(weights), sidecar_path(current))):  # never half a weights file
        atomic_write(dst, lambda tmp, src=src: shutil.copyfile(src, tmp))
    write_json(entry.card_path, card, indent=1)


def ship(val: Path, run_dir: Path, args: RecipeOptions) -> bool:
    """Ship the run's best weights if they beat the shipped weights of the same model on the fixed validation set
    `val`: copy them (with the .json sidecar) to the registry's pretrained entry of that model, where
    `create_model(name, pretrained=True)` loads them, and update its model card. Returns whether it shipped."""
    import torch

    from unips.checkpoint import git_revision
    from unips.models import load_model, pretrained_entry
    from unips.train import TrainConfig

    best = run_dir / "best.safetensors"
    model, meta = load_model(best)
    name = meta["model_name"]
    entry = pretrained_entry(name)
    current = entry.weights_path
    new = _val_probes(best, val, args.threads)
    old = _val_probes(current, val, args.threads) if current.is_file() else None
    print(f"fixed validation, all images: new {name} {new['mean']:.2f} deg, shipped {name} "
          + (f"{old['mean']:.2f} deg" if old else "none yet"), flush=True)
    if old is not None and new["mean"] >= old["mean"]:
        print("not shipped: the fixed validation did not improve", flush=True)
        return False
    # Continued from the shipped weights: the card's lineage goes on; otherwise the new weights start their own.
    continued = bool(args.init_from) and current.is_file() and Path(args.init_from).resolve() == current.resolve()
    card = _card(entry.card_path)
    lineage = card.get("lineage", []) if continued else []
    if card.get("lineage") and not continued:
        card["replaced_model_lineage"] = card["lineage"]
    wall = float((run_dir / "wall_time_s.txt").read_text()) if (run_dir / "wall_time_s.txt").is_file() else None
    seeds = ",".join(map(str, args.train_seed))
    data = f"wildgen.make seed(s) {seeds}, {args.train_objects} objects each, 128 px, 10 images, 16 spp, train assets"
    val_pixels = TrainConfig().val_pixels
    lineage.append(
        {
            "stage": f"orchestrate.train_recipe, {time.strftime('%Y-%m-%d')}",
            "init_from": args.init_from,
            "data": data,
            "steps": args.steps,
            "hours": round(wall / 3600, 3) if wall else None,
            "shipped": True,
            "best_step": meta.get("extra", {}).get("step"),
            "fixed_validation": {"all": round(new["mean"], 2), "gain": round(new["gain"], 2)},
            "per_family_at_best": {
                f: {"all": round(b["mean"]["all"], 2), "gain": round(b["gain"], 2), "n": b["n"]}
                for f, b in new.get("families", {}).items()
                if "gain" in b
            },
        }
    )
    for key in MEASURED_KEYS:
        if key in card:
            card[f"replaced_model_{key}"] = card.pop(key)
    card.update(
        {
            "model": name,
            "weights": _display(current),
            "parameters": sum(p.numel() for p in model.parameters()),
            "data_recipe": f"python -m orchestrate.train_recipe --train-seed {seeds} "
            f"--train-objects {args.train_objects} --steps {args.steps} --lr {args.lr}"
            + (f" --init-from {args.init_from}" if args.init_from else ""),
            "validation_data": f"orchestrate/train_recipe.py fixed validation set: wildgen.make {VALIDATION_DATA}",
            "train_objects": args.train_objects * len(args.train_seed),
            "steps": sum(s.get("steps") or 0 for s in lineage),
            "best_step": lineage[-1]["best_step"],
            "validation_mean_deg": round(new["mean"], 2),
            "validation_per_family_deg": {f: v["all"] for f, v in lineage[-1]["per_family_at_best"].items()},
            "wall_time_s": round(sum(s.get("hours") or 0 for s in lineage) * 3600),
            "hardware": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
            f"torch {torch.__version__}",
            "git_revision": git_revision(REPO),
            "probes_fixed_validation": _probe_card(new, val_pixels),
            "replaced_model_probes_fixed_validation": _probe_card(old, val_pixels) if old else None,
            "lineage": lineage,
        }
    )
    install_weights(best, entry, card)
    print(f"shipped {name}: {_display(current)} (create_model({name!r}, pretrained=True)); model card "
          f"{_display(entry.card_path)}: copy the benchmark's test-set and DiLiGenT figures in and review "
          "known_weaknesses", flush=True)
    return True


if __name__ == "__main__":  # Ctrl-C stops the work whole, in one line (scenes.cli.supervise)
    from scenes.cli.supervise import run_supervised

    stopped = ("interrupted: every step's finished files in --work are whole; run the same command again to go on "
               "from the steps that finished")
    sys.exit(run_supervised("orchestrate.train_recipe", main, stopped))
