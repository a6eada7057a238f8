"""Fixed-budget A/B of the training data: does the new data help the shipped model? Not a test: a resumable run.

    python bench/ab_data.py --work /tmp/ab --objects 300 --steps 1000 [--assets ../shared/assets]

Every arm fine-tunes the shipped weights with the same budget (the same number of objects, steps, learning
rate, seed and threads as each other; the last stage's settings of the model card otherwise) on one kind of data:

- `today`: today's default data (the PS-Wild light families, one object, orthographic, ideal sensor);
- `new`: the new kinds: one fifth of the objects per complexity level 1-5 (`wildgen.make --level`: detail,
  clusters, PS-Verse and frontal lights), level 5 also perspective with 15-300 mm focal lengths, trained with
  `--curriculum`;
- `sensor`: the `today` scenes re-derived with the machine-vision sensor (`wildgen.sensor`: noise, black level,
  12 significant bits, vignetting), without rendering: the same scenes, realistic files.

Training data uses the train half of the recipe's asset split (`orchestrate.train_recipe`); every score uses the
held-out half: the recipe's fixed validation set (seed 4000, 100 objects, today's kinds) and a held-out set
of the new kinds (levels 4 and 5, half of it perspective), and DiLiGenT ball and cat (raw images, K = 96 and
the mean of 5 random 16-image subsets, `orchestrate.benchmark`). The shipped model is scored beside them. Each
step is skipped when its output exists; results go to WORK/ab.json and a table is printed.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
PY = sys.executable
SHIPPED = ROOT / "unips" / "weights" / "glc-tiny.safetensors"
BASE = ["--images", "10", "--res", "128", "--quiet"]
FAMILIES = "directional,point,near_area,hdri,mixed"


def run(argv: list[str], label: str) -> None:
    t0 = time.perf_counter()
    print(f"[{time.strftime('%H:%M:%S')}] {label}: {' '.join(argv)}", flush=True)
    r = subprocess.run([PY, "-m", *argv], cwd=ROOT)
    if r.returncode != 0:
        raise SystemExit(f"{label} failed with exit status {r.returncode}")
    print(f"    {label}: {time.perf_counter() - t0:.0f} s", flush=True)


def make(out: Path, flags: list[str], label: str) -> Path:
    if not (out / "manifest.json").is_file() or any(out.glob(".tmp_*")):
        run(["wildgen.make", "--out", str(out), *BASE, *flags], label)
    return out


def score_set(net, folder: Path) -> dict:
    """Mean angular error over the objects of a dataset, all images and mask only (the photometric gain)."""
    from scenes.objfolder import mean_angular_error
    from unips.data import find_objects, load_object
    from unips.inference import predict_object
    from orchestrate.benchmark import probe_inputs

    errs, masks = [], []
    for f in find_objects(folder):
        obj = load_object(f)
        errs.append(mean_angular_error(predict_object(obj, "model", net), obj.normals, obj.mask))
        masks.append(mean_angular_error(predict_object(probe_inputs(obj, "mask"), "model", net), obj.normals, obj.mask))
    return {"objects": len(errs), "mean_deg": float(np.mean(errs)), "mask_only_deg": float(np.mean(masks)),
            "gain_deg": float(np.mean(masks) - np.mean(errs))}


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--work", type=Path, required=True)
    p.add_argument("--assets", type=Path, default=ROOT.parent / "shared" / "assets")
    p.add_argument("--objects", type=int, default=300, help="training objects per arm")
    p.add_argument("--steps", type=int, default=1000)
    p.add_argument("--arms", default="today,new,sensor")
    p.add_argument("--threads", type=int, default=2)
    args = p.parse_args()
    from orchestrate.train_recipe import SPLIT_FOLDERS, check_split, split_assets

    w = args.work
    w.mkdir(parents=True, exist_ok=True)
    if check_split(args.assets, w, False):
        split_assets(args.assets, w)
    train_assets, held = (str(w / d) for d in SPLIT_FOLDERS)
    val = make(w / "val", ["--objects", "100", "--spp", "32", "--seed", "4000", "--lights", FAMILIES, "--assets", held],
               "fixed validation set")
    newval = [make(w / "newval4", ["--objects", "30", "--spp", "32", "--seed", "4104", "--level", "4", "--assets", held],
                   "held-out new kinds, level 4"),
              make(w / "newval5", ["--objects", "30", "--spp", "32", "--seed", "4105", "--level", "5", "--camera", "perspective",
                                   "--focal", "15-300", "--assets", held], "held-out new kinds, level 5, perspective")]
    n = args.objects
    data = {}
    arms = args.arms.split(",")
    if "today" in arms or "sensor" in arms:
        data["today"] = [make(w / "train_today", ["--objects", str(n), "--spp", "16", "--seed", "20000", "--lights", FAMILIES,
                                                 "--assets", train_assets], "train: today")]
    if "sensor" in arms:
        out = w / "train_sensor"
        if not (out / "manifest.json").is_file():
            run(["wildgen.sensor", "--data", str(data["today"][0]), "--sensor", "machine-vision", "--out", str(out)],
                "train: today's scenes, machine-vision sensor")
        data["sensor"] = [out]
    if "new" in arms:
        data["new"] = []
        for level in range(1, 6):
            extra = ["--camera", "perspective", "--focal", "15-300"] if level == 5 else []
            data["new"].append(make(w / f"train_new_l{level}", ["--objects", str(n // 5), "--spp", "16", "--seed",
                                                                 str(20010 + level), "--level", str(level),
                                                                 "--assets", train_assets, *extra],
                                    f"train: new, level {level}"))
    runs = {}
    for arm in arms:
        out = w / f"run_{arm}"
        if not (out / "best.safetensors").is_file():
            run(["unips.train", "--data", ",".join(map(str, data[arm])), "--val", str(val), "--model", "glc-tiny",
                 "--init-from", str(SHIPPED), "--out", str(out), "--steps", str(args.steps), "--lr", "1.5e-4",
                 "--warmup", "50", "--val-every", str(args.steps), "--ckpt-every", str(args.steps), "--seed", "0",
                 "--threads", str(args.threads), "--no-progress", *(["--curriculum"] if arm == "new" else [])],
                f"fine-tune: {arm}")
        runs[arm] = out / "best.safetensors"

    import torch

    torch.set_num_threads(args.threads)
    from orchestrate.benchmark import diligent_table
    from unips.inference import load_network

    results_path = w / "ab.json"
    results = json.loads(results_path.read_text()) if results_path.is_file() else {}
    for name, weights in [("shipped", SHIPPED), *runs.items()]:
        if name in results:
            continue
        t0 = time.perf_counter()
        net = load_network(weights)
        r = {"weights": str(weights), "fixed_validation": score_set(net, val),
             "new_kinds": [score_set(net, f) for f in newval]}
        dil = diligent_table(ROOT.parent / "shared" / "data" / "diligent", net, None, None)
        r["diligent"] = {k: {"k96_deg": v["methods"]["model"]["mae_deg"], "k16_deg": v["model_subsets"]["mean"]}
                         for k, v in dil.items()}
        r["seconds"] = time.perf_counter() - t0
        results[name] = r
        results_path.write_text(json.dumps(results, indent=1))
        print(f"scored {name} in {r['seconds']:.0f} s", flush=True)
    print(f"\n{'model':10s} {'fixed val':>9s} {'gain':>5s} {'new L4':>7s} {'new L5':>7s} {'ball96':>7s} {'ball16':>7s} "
          f"{'cat96':>6s} {'cat16':>6s}")
    for name, r in results.items():
        d = r["diligent"]
        print(f"{name:10s} {r['fixed_validation']['mean_deg']:9.2f} {r['fixed_validation']['gain_deg']:5.2f} "
              f"{r['new_kinds'][0]['mean_deg']:7.2f} {r['new_kinds'][1]['mean_deg']:7.2f} {d['ball']['k96_deg']:7.2f} "
              f"{d['ball']['k16_deg']:7.2f} {d['cat']['k96_deg']:6.2f} {d['cat']['k16_deg']:6.2f}")
    print(f"wrote {results_path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
