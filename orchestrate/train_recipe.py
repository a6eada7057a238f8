"""The reproducible training recipe: data, held-out split, training, the ship decision, evaluation.

    python -m orchestrate.train_recipe --work /tmp/recipe [--assets ../shared/assets] [--model glc-small]
                                       [--init-from WEIGHTS] [--train-seed 5000[,SEED...]] [--train-objects 800]
                                       [--steps 4000] [--threads 2] [--ablation] [--ship]

1. Split the asset folder: the last quarter of the meshes and the last fifth of the HDR maps (sorted by
   name, rounded up; with ../shared/assets: 5 of 19 meshes, 7 of 35 maps) are held out for validation
   and test; texture sets are shared (there are only eight).
2. Render with `wildgen.make`, every light family (`wildgen.lighting.LIGHT_FAMILIES`) cycled: train (seed `--train-seed`, 128 px,
   10 images, 16 spp, train assets; a new seed gives fresh data for a continued run; several seeds,
   comma-separated, give one set each, pooled for training), the fixed
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
Every step resumes or is skipped when its output already exists, so an interrupted recipe is re-run as is.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import platform
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

from scenes.cli import INPUT_ERRORS, check_output_folder, report_error
from scenes.config import check_fields, config_parser, option
from scenes.config import config_from_args as parse_config
from wildgen.lighting import LIGHT_FAMILIES

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"
FAMILIES = ["--lights", ",".join(LIGHT_FAMILIES)]
VAL_FLAGS = ["--objects", "100", "--images", "10", "--res", "128", "--spp", "32", "--seed", "4000"]
TEST_FLAGS = ["--objects", "100", "--images", "10", "--res", "128", "--spp", "32", "--seed", "3000"]


def split_assets(assets: Path, work: Path) -> tuple[Path, Path]:
    """Symlink folders train_assets/ and heldout_assets/ (last 1/4 of meshes, last 1/5 of HDRIs held out)."""
    train, held = work / "train_assets", work / "heldout_assets"
    for d in (train, held):
        shutil.rmtree(d, ignore_errors=True)
        (d / "meshes").mkdir(parents=True)
        (d / "hdri").mkdir()
        if (assets / "textures").is_dir():
            os.symlink(assets / "textures", d / "textures")
    meshes = sorted(p for p in (assets / "meshes").iterdir() if p.is_dir() or p.suffix.lower() in (".obj", ".ply", ".stl")) if (assets / "meshes").is_dir() else []
    hdris = sorted(p for p in (assets / "hdri").iterdir() if p.suffix.lower() in (".hdr", ".exr")) if (assets / "hdri").is_dir() else []
    for items, sub, share in ((meshes, "meshes", 4), (hdris, "hdri", 5)):
        cut = len(items) - math.ceil(len(items) / share)
        for i, p in enumerate(items):
            os.symlink(p, (train if i < cut else held) / sub / p.name)
    return train, held


def run(cmd: list[str]) -> None:
    print("+", " ".join(cmd), flush=True)
    subprocess.run(cmd, check=True, cwd=REPO)


def train_run(py: str, work: Path, name: str, args: RecipeOptions, extra: list[str]) -> Path:
    """Train one run into work/runs/NAME (resumed when interrupted); returns the run folder."""
    out = work / "runs" / name
    if (out / "final.safetensors").is_file():
        return out
    resume = ["--resume"] if (out / "last.pt").is_file() else []
    init = ["--init-from", args.init_from] if args.init_from and not resume and not extra else []
    model = [] if init else ["--model", args.model]
    data = ",".join(str(work / f"train{seed}") for seed in args.train_seed)
    cmd = [py, "-m", "unips.train", "--data", data, "--val", str(work / "val128"),
           *model, *init, "--out", str(out), "--steps", str(args.steps), "--batch", "4", "--lr", str(args.lr),
           "--val-every", "500", "--ckpt-every", "250", "--seed", "0", "--threads", str(args.threads),
           "--no-progress", *extra, *resume]
    t0 = time.time()
    run(cmd)
    (out / "wall_time_s.txt").write_text(f"{time.time() - t0:.0f}\n")
    return out


@dataclass
class RecipeOptions:
    """The command line of orchestrate.train_recipe."""

    work: str = option("", required=True)
    """Working folder (datasets, runs, benchmark output)."""
    assets: str | None = option(None, default_text="../shared/assets when it exists")
    """Asset folder, split into train / held-out assets."""
    model: str = "glc-small"
    """Registered model trained from scratch (`unips.models.list_models()`)."""
    init_from: str | None = None
    """Weights to continue from (weights only; e.g. unips/weights/...)."""
    train_seed: list[int] = option(default_factory=lambda: [5000], minimum=0, metavar="SEED[,SEED...]")
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
    ship: bool = False
    """Ship the best weights if the fixed validation improves (see 4. above)."""

    def validate(self) -> "RecipeOptions":
        """Every check before any work: flags, the --work folder, and with --ship the registry entry."""
        check_fields(self)
        if not self.train_seed or len(set(self.train_seed)) != len(self.train_seed):
            raise ValueError(f"--train-seed: got {','.join(map(str, self.train_seed))!r}, expected distinct integers "
                             "separated by commas")
        check_output_folder(self.work, "--work")
        if self.ship:
            shipped_name(self)  # the registry must know where the trained model's weights go
        return self


def build_parser() -> argparse.ArgumentParser:
    return config_parser(RecipeOptions, prog="python -m orchestrate.train_recipe", description=__doc__,
                         formatter_class=argparse.RawDescriptionHelpFormatter)


def main(argv: list[str] | None = None) -> int:
    try:
        args = parse_config(RecipeOptions, build_parser().parse_args(argv)).validate()
        if args.assets is None and (SHARED / "assets").is_dir():
            args.assets = str(SHARED / "assets")
        return recipe(args)
    except INPUT_ERRORS as exc:
        return report_error(exc)
    except subprocess.CalledProcessError as exc:
        return report_error(RuntimeError(f"step {' '.join(map(str, exc.cmd[1:4]))} failed with exit status "
                                         f"{exc.returncode} (its output is above); re-run the same command to resume"),
                            code=1)


def recipe(args: RecipeOptions) -> int:
    """Every step of the recipe (see the module doc), after the options were checked."""
    py = sys.executable
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    asset_flags: tuple[list[str], list[str]] = ([], [])
    if args.assets:
        train_assets, held_assets = split_assets(Path(args.assets), work)
        asset_flags = (["--assets", str(train_assets)], ["--assets", str(held_assets)])
    sets = {
        **{f"train{seed}": ["--objects", str(args.train_objects), "--images", "10", "--res", "128", "--spp", "16",
                            "--gt-spp", "4", "--seed", str(seed), *asset_flags[0]] for seed in args.train_seed},
        "val128": [*VAL_FLAGS, *asset_flags[1]],
        "test128": [*TEST_FLAGS, *asset_flags[1]],
    }
    for name, flags in sets.items():
        # Always run: on an existing dataset wildgen.make resumes (verifies finished objects, renders the rest).
        run([py, "-m", "wildgen.make", *FAMILIES, *flags, "--out", str(work / name), "--quiet"])
    main_run = train_run(py, work, "main", args, [])
    ablation = train_run(py, work, "uniform", args, ["--model-option", "uniform_context=true"]) if args.ablation else None
    if args.ship:
        ship(work / "val128", main_run, args)
    bench = [py, "-m", "orchestrate.benchmark", "--data", str(work / "test128"), "--checkpoint",
             str(main_run / "best.safetensors"), "--out", str(work / "benchmark")]
    if ablation is not None:
        bench += ["--ablation-checkpoint", str(ablation / "best.safetensors")]
    if (SHARED / "data" / "diligent").is_dir():
        bench += ["--diligent", str(SHARED / "data" / "diligent")]
    run(bench)
    return 0


def _val_probes(weights: Path, val: Path, threads: int) -> dict:
    """Probe summary of `weights` on the fixed validation set (as unips.train validates)."""
    import torch

    from unips.models import load_model
    from unips.train import TrainConfig
    from unips.train_data import load_samples, probe_samples

    torch.set_num_threads(threads)
    cfg = TrainConfig()
    model, _ = load_model(weights)
    res = probe_samples(model, load_samples(val, cfg.res), cfg.max_images, torch.device("cpu"), probes=cfg.val_probes,
                        pixels=cfg.val_pixels)
    res.pop("objects", None)
    return res


def shipped_name(args: RecipeOptions) -> str:
    """The registered model a recipe run trains (`--model`, or the model of `--init-from`), checked to have a
    shipped-weights entry in the registry: called before any work when `--ship` is given."""
    from unips.models import load_model, pretrained_entry

    name = load_model(args.init_from)[1]["model_name"] if args.init_from else args.model
    try:
        pretrained_entry(name)
    except ValueError as exc:
        which = f"--init-from {args.init_from!r} holds" if args.init_from else "--model is"
        raise ValueError(f"--ship: {which} {name!r}, which has no place for shipped weights in the registry "
                         f"({exc})") from None
    return name


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


def ship(val: Path, run_dir: Path, args: RecipeOptions) -> bool:
    """Ship the run's best weights if they beat the shipped weights of the same model on the fixed validation set
    `val`: copy them (with the .json sidecar) to the registry's pretrained entry of that model, where
    `create_model(name, pretrained=True)` loads them, and update its model card. Returns whether it shipped."""
    import torch

    from unips.checkpoint import git_revision
    from unips.models import load_model, pretrained_entry
    from unips.models.builder import sidecar_path
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
    card = json.loads(entry.card_path.read_text()) if entry.card_path.is_file() else {}
    lineage = card.get("lineage", []) if continued else []
    if card.get("lineage") and not continued:
        card["replaced_model_lineage"] = card["lineage"]
    wall = float((run_dir / "wall_time_s.txt").read_text()) if (run_dir / "wall_time_s.txt").is_file() else None
    seeds = ",".join(map(str, args.train_seed))
    data = f"wildgen.make seed(s) {seeds}, {args.train_objects} objects each, 128 px, 10 images, 16 spp, train assets"
    val_pixels = TrainConfig().val_pixels
    lineage.append({"stage": f"orchestrate.train_recipe, {time.strftime('%Y-%m-%d')}",
                    "init_from": args.init_from, "data": data, "steps": args.steps,
                    "hours": round(wall / 3600, 3) if wall else None, "shipped": True,
                    "best_step": meta.get("extra", {}).get("step"),
                    "fixed_validation": {"all": round(new["mean"], 2), "gain": round(new["gain"], 2)},
                    "per_family_at_best": {f: {"all": round(b["mean"]["all"], 2), "gain": round(b["gain"], 2),
                                               "n": b["n"]} for f, b in new.get("families", {}).items() if "gain" in b}})
    for key in MEASURED_KEYS:
        if key in card:
            card[f"replaced_model_{key}"] = card.pop(key)
    card.update({
        "model": name, "weights": _display(current),
        "parameters": sum(p.numel() for p in model.parameters()),
        "data_recipe": f"python -m orchestrate.train_recipe --train-seed {seeds} --train-objects {args.train_objects} "
                       f"--steps {args.steps} --lr {args.lr}" + (f" --init-from {args.init_from}" if args.init_from else ""),
        "validation_data": f"orchestrate/train_recipe.py fixed validation set: wildgen.make {VALIDATION_DATA}",
        "train_objects": args.train_objects * len(args.train_seed),
        "steps": sum(s.get("steps") or 0 for s in lineage),
        "best_step": lineage[-1]["best_step"],
        "validation_mean_deg": round(new["mean"], 2),
        "validation_per_family_deg": {f: v["all"] for f, v in lineage[-1]["per_family_at_best"].items()},
        "wall_time_s": round(sum(s.get("hours") or 0 for s in lineage) * 3600),
        "hardware": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, torch {torch.__version__}",
        "git_revision": git_revision(REPO),
        "probes_fixed_validation": _probe_card(new, val_pixels),
        "replaced_model_probes_fixed_validation": _probe_card(old, val_pixels) if old else None,
        "lineage": lineage,
    })
    current.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(best, current)
    shutil.copyfile(sidecar_path(best), sidecar_path(current))
    entry.card_path.write_text(json.dumps(card, indent=1))
    print(f"shipped {name}: {_display(current)} (create_model({name!r}, pretrained=True)); model card "
          f"{_display(entry.card_path)}: copy the benchmark's test-set and DiLiGenT figures in and review "
          "known_weaknesses", flush=True)
    return True


if __name__ == "__main__":
    sys.exit(main())
