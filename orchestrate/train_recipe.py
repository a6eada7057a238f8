"""The reproducible recipe of the shipped model: data, held-out split, training, evaluation, shipping.

    python -m orchestrate.train_recipe --work /tmp/recipe [--assets ../shared/assets] [--steps 4000] [--ablation] [--ship]

1. Split the asset folder: the last quarter of the meshes and the last fifth of the HDR maps (sorted by
   name, rounded up; with ../shared/assets: 5 of 19 meshes, 7 of 35 maps) are held out for validation
   and test; texture sets are shared (there are only eight).
2. Render with `wildgen.make`: train (seed 1000, 800 objects, 64 px, 8 images, 16 spp, all five light
   families cycled, train assets), validation (seed 2000, 50 objects, same settings, held-out assets) and
   test (seed 3000, 50 objects, 128 px, 10 images, 32 spp, held-out assets).
3. Train `glc-tiny` with `unips.train` (AdamW 5e-4, x0.8 every 1000 steps, batch 4, 2..8 images).
   `--ablation` trains the spatially uniform context variant the same way.
4. `--ship` copies the best checkpoint into unips/weights/ with a model card (JSON).
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


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--work", required=True, help="working folder (datasets, runs, benchmark output)")
    p.add_argument("--assets", default=str(SHARED / "assets") if (SHARED / "assets").is_dir() else None)
    p.add_argument("--train-objects", type=int, default=800)
    p.add_argument("--steps", type=int, default=4000)
    p.add_argument("--threads", type=int, default=1, help="torch threads per training run")
    p.add_argument("--ablation", action="store_true", help="also train the uniform-context ablation")
    p.add_argument("--ship", action="store_true", help="copy the best weights into unips/weights/")
    args = p.parse_args()
    py = sys.executable
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    asset_flags: tuple[list[str], list[str]] = ([], [])
    if args.assets:
        train_assets, held_assets = split_assets(Path(args.assets), work)
        asset_flags = (["--assets", str(train_assets)], ["--assets", str(held_assets)])
    fams = ["--lights", "directional,point,near_area,hdri,mixed"]
    sets = {
        "train64": ["--objects", str(args.train_objects), "--images", "8", "--res", "64", "--spp", "16", "--gt-spp", "4", "--seed", "1000", *asset_flags[0]],
        "val64": ["--objects", "50", "--images", "8", "--res", "64", "--spp", "16", "--gt-spp", "4", "--seed", "2000", *asset_flags[1]],
        "test128": ["--objects", "50", "--images", "10", "--res", "128", "--spp", "32", "--seed", "3000", *asset_flags[1]],
    }
    for name, flags in sets.items():
        # Always run: on an existing dataset wildgen.make resumes (verifies finished objects, renders the rest).
        run([py, "-m", "wildgen.make", *fams, *flags, "--out", str(work / name), "--quiet"])
    runs = {"glc-tiny": []}
    if args.ablation:
        runs["glc-tiny-uniform"] = ["--model-option", "uniform_context=true"]
    # The runs are independent: with --ablation both train at once, --threads each (1 + 1 on a 2-core machine
    # is faster than one after the other with 2 threads each, which contend in torch's thread pool).
    procs = []
    for run_name, extra in runs.items():
        out = work / "runs" / run_name
        if (out / "final.safetensors").is_file():
            continue
        resume = ["--resume"] if (out / "last.pt").is_file() else []
        cmd = [py, "-m", "unips.train", "--data", str(work / "train64"), "--val", str(work / "val64"), "--model", "glc-tiny",
               "--out", str(out), "--steps", str(args.steps), "--batch", "4", "--lr", "5e-4", "--decay-every", "1000",
               "--decay", "0.8", "--val-every", "500", "--ckpt-every", "250", "--seed", "0", "--threads", str(args.threads),
               "--no-progress", *extra, *resume]
        print("+", " ".join(cmd), flush=True)
        procs.append((out, time.time(), subprocess.Popen(cmd, cwd=REPO)))
    for out, t0, proc in procs:
        if proc.wait() != 0:
            raise SystemExit(f"train_recipe: training into {out} failed with exit code {proc.returncode}")
        (out / "wall_time_s.txt").write_text(f"{time.time() - t0:.0f}\n")
    if args.ship:
        ship(work, args)
    bench = [py, "-m", "orchestrate.benchmark", "--data", str(work / "test128"), "--checkpoint", str(work / "runs" / "glc-tiny" / "best.safetensors"), "--out", str(work / "benchmark")]
    if args.ablation:
        bench += ["--ablation-checkpoint", str(work / "runs" / "glc-tiny-uniform" / "best.safetensors")]
    if (SHARED / "data" / "diligent").is_dir():
        bench += ["--diligent", str(SHARED / "data" / "diligent")]
    run(bench)
    return 0


def ship(work: Path, args: argparse.Namespace) -> None:
    """Copy best weights into the package with a model card."""
    run_dir = work / "runs" / "glc-tiny"
    weights = REPO / "unips" / "weights"
    weights.mkdir(exist_ok=True)
    shutil.copyfile(run_dir / "best.safetensors", weights / "glc-tiny.safetensors")
    shutil.copyfile(run_dir / "best.json", weights / "glc-tiny.json")
    log = [json.loads(line) for line in (run_dir / "log.jsonl").read_text().splitlines() if line.strip()]
    vals = [r for r in log if "val" in r]
    best = min(vals, key=lambda r: r["val"]["mean"]) if vals else None
    fams = best["val"]["families"] if best else {}
    weak = sorted(fams, key=fams.get, reverse=True)[:2]
    try:
        rev = subprocess.run(["git", "rev-parse", "HEAD"], cwd=REPO, capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        rev = None
    import torch

    from unips.checkpoint import load_model

    n_params = sum(p.numel() for p in load_model(weights / "glc-tiny.safetensors")[0].parameters())
    card = {
        "model": "glc-tiny",
        "parameters": n_params,
        "data_recipe": "orchestrate/train_recipe.py: wildgen.make --lights directional,point,near_area,hdri,mixed --objects "
                       f"{args.train_objects} --images 8 --res 64 --spp 16 --gt-spp 4 --seed 1000 --assets <train split of "
                       "../shared/assets>; held out of training: the last 1/4 of the meshes and the last 1/5 of the HDR maps by name",
        "validation_data": "seed 2000, 50 objects, 64 px, 8 images, held-out assets",
        "train_objects": args.train_objects,
        "training": {"steps": args.steps, "batch": 4, "optimizer": "AdamW lr 5e-4 wd 0.05, x0.8 every 1000 steps",
                     "images_per_sample": "2..8", "seed": 0, "torch_threads": args.threads},
        "steps": args.steps,
        "best_step": best["step"] if best else None,
        "validation_mean_deg": best["val"]["mean"] if best else None,
        "validation_per_family_deg": fams,
        "wall_time_s": float((run_dir / "wall_time_s.txt").read_text()) if (run_dir / "wall_time_s.txt").is_file() else None,
        "hardware": f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, CPU only, torch {torch.__version__}",
        "git_revision": rev,
        "known_weaknesses": (f"weakest validation families: {', '.join(f'{f} {fams[f]:.1f} deg' for f in weak)}; "
                             "trained at 64 px on 2 CPU cores, so fine detail at 128+ px is smoothed; "
                             "see the README Evaluation section for the held-out and DiLiGenT figures") if fams else "not validated",
    }
    (weights / "model_card.json").write_text(json.dumps(card, indent=1))


if __name__ == "__main__":
    sys.exit(main())
