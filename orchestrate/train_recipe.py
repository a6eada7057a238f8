"""The reproducible training recipe: data, held-out split, training, the ship decision, evaluation.

    python -m orchestrate.train_recipe --work /tmp/recipe [--assets ../shared/assets] [--model glc-small]
                                       [--init-from WEIGHTS] [--train-seed 5000[,SEED...]] [--train-objects 800]
                                       [--steps 4000] [--threads 2] [--ablation] [--ship]

1. Split the asset folder: the last quarter of the meshes and the last fifth of the HDR maps (sorted by
   name, rounded up; with ../shared/assets: 5 of 19 meshes, 7 of 35 maps) are held out for validation
   and test; texture sets are shared (there are only eight).
2. Render with `wildgen.make`, all five light families cycled: train (seed `--train-seed`, 128 px,
   10 images, 16 spp, train assets; a new seed gives fresh data for a continued run; several seeds,
   comma-separated, give one set each, pooled for training), the fixed
   validation set (seed 4000, 100 objects, 128 px, 10 images, 32 spp, held-out assets: the test
   distribution) and the test set (seed 3000, 100 objects, same settings).
3. Train with `unips.train` (warm-up + cosine, gradient clipping, 1..10 images per sample, probes at
   every validation), from scratch or `--init-from` earlier weights. `--ablation` then trains the
   spatially uniform context variant with the same budget, after the main run (never alongside it).
4. `--ship` copies the best weights into unips/weights/ only if their all-images error on the fixed
   validation set is below the shipped model's (both measured here, same probes), and appends the run
   to the model card's lineage (data seed, objects, steps, hours, validation probes).
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
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SHARED = REPO.parent / "shared"
FAMILIES = ["--lights", "directional,point,near_area,hdri,mixed"]
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


def train_run(py: str, work: Path, name: str, args: argparse.Namespace, extra: list[str]) -> Path:
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


def seed_list(text: str) -> list[int]:
    """--train-seed: one integer or several separated by commas."""
    try:
        seeds = [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected integers separated by commas, got {text!r}") from None
    if not seeds or len(set(seeds)) != len(seeds):
        raise argparse.ArgumentTypeError(f"expected distinct integers separated by commas, got {text!r}")
    return seeds


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--work", required=True, help="working folder (datasets, runs, benchmark output)")
    p.add_argument("--assets", default=str(SHARED / "assets") if (SHARED / "assets").is_dir() else None)
    p.add_argument("--model", default="glc-small", help="registered model trained from scratch (default glc-small)")
    p.add_argument("--init-from", default=None, help="weights to continue from (weights only; e.g. unips/weights/...)")
    p.add_argument("--train-seed", type=seed_list, default=[5000],
                   help="seed of the training data (new seed: fresh data); several, comma-separated: one set each, pooled")
    p.add_argument("--train-objects", type=int, default=800)
    p.add_argument("--steps", type=int, default=4000)
    p.add_argument("--lr", type=float, default=1e-3)
    p.add_argument("--threads", type=int, default=2, help="torch threads of the (single) training run")
    p.add_argument("--ablation", action="store_true", help="then train the uniform-context ablation, same budget")
    p.add_argument("--ship", action="store_true", help="ship the best weights if the fixed validation improves")
    args = p.parse_args()
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
        ship(work, main_run, args)
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

    from unips.checkpoint import load_model
    from unips.train import TrainConfig, load_samples, validate

    torch.set_num_threads(threads)
    cfg = TrainConfig()
    model, _ = load_model(weights)
    res = validate(model, load_samples(val, cfg.res), cfg.max_images, torch.device("cpu"), probes=cfg.val_probes,
                   pixels=cfg.val_pixels)
    res.pop("objects", None)
    return res


def ship(work: Path, run_dir: Path, args: argparse.Namespace) -> None:
    """Copy the run's best weights into the package if they beat the shipped model on the fixed validation."""
    import torch

    from unips.checkpoint import load_model
    from unips.inference import default_checkpoint

    weights = REPO / "unips" / "weights"
    current = default_checkpoint()
    new = _val_probes(run_dir / "best.safetensors", work / "val128", args.threads)
    old = _val_probes(current, work / "val128", args.threads) if current.is_file() else None
    print(f"fixed validation, all images: new {new['mean']:.2f} deg, shipped "
          f"{old['mean'] if old else float('nan'):.2f} deg", flush=True)
    if old is not None and new["mean"] >= old["mean"]:
        print("not shipped: the fixed validation did not improve", flush=True)
        return
    model, meta = load_model(run_dir / "best.safetensors")
    name = meta["model_name"]
    shutil.copyfile(run_dir / "best.safetensors", weights / f"{name}.safetensors")
    shutil.copyfile(run_dir / "best.json", weights / f"{name}.json")
    card_path = weights / "model_card.json"
    card = json.loads(card_path.read_text()) if card_path.is_file() else {}
    rev = subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True).stdout.strip() or None
    wall = float((run_dir / "wall_time_s.txt").read_text()) if (run_dir / "wall_time_s.txt").is_file() else None
    lineage = card.get("lineage", [])
    lineage.append({"model": name, "init_from": args.init_from, "train_seed": args.train_seed,
                    "train_objects": args.train_objects, "steps": args.steps, "hours": wall and wall / 3600,
                    "validation": {k: new[k] for k in ("mean", "gain", "probes", "families") if k in new},
                    "git_revision": rev})
    card.update({
        "model": name, "weights": f"unips/weights/{name}.safetensors",
        "parameters": sum(p.numel() for p in model.parameters()),
        "data_recipe": f"orchestrate/train_recipe.py --train-seed {','.join(map(str, args.train_seed))} --train-objects "
                       f"{args.train_objects} --steps {args.steps}" + (f" --init-from {args.init_from}" if args.init_from else ""),
        "validation_data": "seed 4000, 100 objects, 128 px, 10 images, 32 spp, held-out meshes and HDR maps",
        "validation_probes": {k: new[k] for k in ("mean", "gain", "probes", "families") if k in new},
        "replaced_validation_probes": {k: old[k] for k in ("mean", "gain", "probes") if k in old} if old else None,
        "hardware": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, torch {torch.__version__}",
        "lineage": lineage,
    })
    card_path.write_text(json.dumps(card, indent=1))


if __name__ == "__main__":
    sys.exit(main())
