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

import json
import re
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.cli_common import check_work, need_path, parse, refusals, run_main  # noqa: E402
from scenes.cli.errors import UsageError  # noqa: E402
from scenes.cli.options import REQUIRED, CommaList, Command, arg, check_fields, option  # noqa: E402
from scenes.files import read_figures, read_json, read_text_file, reading_record, write_json  # noqa: E402

PY = sys.executable
from unips.models import DEFAULT_MODEL, pretrained_entry  # noqa: E402 (after the path above)

SHIPPED = pretrained_entry(DEFAULT_MODEL).weights_path
BASE = ["--images", "10", "--res", "128", "--quiet"]
FAMILIES = "directional,point,near_area,hdri,mixed"
ARM_DATA = {
    "today": "today's default data: {n} objects, seed 20000, --lights directional,point,near_area,hdri,mixed",
    "new": "the new kinds: {n} objects, one fifth per --level 1-5 (seeds 20011-20015; level 5 --camera perspective "
           "--focal 15-300), --curriculum",
    "sensor": "today's {n} scenes re-derived with the machine-vision sensor (wildgen.sensor)",
}
"""The arms (--arms): what each trains on."""
LEVELS = 5
"""The `new` arm's objects are split over the complexity levels 1-5 (one fifth each)."""
DILIGENT_OBJECTS = ("ball", "cat")
"""The DiLiGenT objects every arm is scored on (the table's and the card's columns)."""
CARD_PATH = ROOT / "unips" / "weights" / "model_card.json"
"""The model card --record adds the arms to."""


def run(argv: list[str], label: str) -> None:
    t0 = time.perf_counter()
    print(f"[{time.strftime('%H:%M:%S')}] {label}: {' '.join(argv)}", flush=True)
    r = subprocess.run([PY, "-m", *argv], cwd=ROOT)
    if r.returncode != 0:
        raise SystemExit(f"{label} failed with exit status {r.returncode}")
    print(f"    {label}: {time.perf_counter() - t0:.0f} s", flush=True)


def make(out: Path, flags: list[str], label: str) -> Path:
    # always run: wildgen.make resumes an interrupted set (its manifest is written first) and returns at once when
    # every object is complete
    run(["wildgen.make", "--out", str(out), *BASE, *flags], label)
    return out


def score_set(net, folder: Path) -> dict:
    """Mean angular error over the objects of a dataset, all images and mask only (the photometric gain)."""
    from orchestrate.benchmark import probe_inputs
    from scenes.metrics import mean_angular_error
    from unips.data import find_objects, load_object
    from unips.inference import predict_object

    errs, masks = [], []
    for f in find_objects(folder):
        obj = load_object(f)
        errs.append(mean_angular_error(predict_object(obj, "model", net), obj.normals, obj.mask))
        masks.append(mean_angular_error(predict_object(probe_inputs(obj, "mask"), "model", net), obj.normals, obj.mask))
    return {"objects": len(errs), "mean_deg": float(np.mean(errs)), "mask_only_deg": float(np.mean(masks)),
            "gain_deg": float(np.mean(masks) - np.mean(errs))}


@dataclass
class Options:
    """The command line of bench/ab_data.py."""

    work: Annotated[Path, arg(metavar="WORK")] = REQUIRED
    """Working folder: the asset split, the datasets, the runs and ab.json (every step skipped when its output
    exists)."""
    assets: Annotated[Path, arg(metavar="DIR", help_behavior_hint="(default: ../shared/assets)")] = (
        ROOT.parent / "shared" / "assets"
    )
    """Asset library, split into the recipe's train and held-out halves."""
    objects: int = option(300, minimum=1)
    """training objects per arm"""
    steps: int = option(1000, minimum=1)
    """Training steps of every arm."""
    arms: Annotated[list[str], CommaList] = option(default_factory=lambda: list(ARM_DATA), choices=tuple(ARM_DATA))
    """Arms to train and score, comma-separated (today, new, sensor)."""
    threads: int = option(2, minimum=1)
    """CPU threads of training and scoring."""
    lr: str = "1.5e-4"
    """peak learning rate of every arm (the model card's last stage: 1.5e-4)"""
    record: bool = False
    """append every scored arm to the model card's lineage (not shipped) and its scores to the card's data_ab
    entry, from which the docs' A/B table is generated"""
    tag: str = ""
    """suffix of the run folders and result names (several settings in one WORK)"""
    diligent: Annotated[Path, arg(metavar="DIR", help_behavior_hint="(default: ../shared/data/diligent)")] = (
        ROOT.parent / "shared" / "data" / "diligent"
    )
    """DiLiGenT folder holding ballPNG and catPNG with their ground truth (scored raw, K = 96 and 16)"""

    def validate(self) -> "Options":
        import math

        check_fields(self)
        try:
            lr = float(self.lr)
        except ValueError:
            lr = math.nan
        if not (math.isfinite(lr) and lr > 0):  # nan fails too
            raise UsageError(f"--lr: got {self.lr!r}, expected a number > 0")
        if not re.fullmatch(r"[A-Za-z0-9_.+-]{0,40}", self.tag) or ".." in self.tag:  # part of a folder name
            raise UsageError(f"--tag: got {self.tag!r}, expected at most 40 letters, digits, '_', '-', '+' or '.' "
                             "(a suffix of the run folders' names)")
        if "new" in self.arms and self.objects < LEVELS:
            raise UsageError(f"--objects: got {self.objects}, expected an integer >= {LEVELS} with the arm new (its "
                             f"objects are split over the {LEVELS} levels)")
        return self


COMMAND = Command(Options, prog="python bench/ab_data.py", description=__doc__.split("\n\n")[0])


def before_work(args: Options) -> None:
    """What the command line names on disk, checked before any work (each refusal one line)."""
    check_work(args.work, inputs={"--assets": args.assets, "--diligent": args.diligent})
    need_path(args.assets, "--assets", "the asset library (meshes, HDR maps, textures)")
    if not _scored(args) >= {"shipped", *(arm + args.tag for arm in args.arms)}:  # an arm to score: DiLiGenT read
        need_path(args.diligent, "--diligent", "a DiLiGenT folder holding ballPNG and catPNG")
        lacking = [f"{k}PNG" for k in DILIGENT_OBJECTS if not (args.diligent / f"{k}PNG").is_dir()]
        with refusals():
            if lacking:
                raise UsageError(f"--diligent: {str(args.diligent)!r} holds no {', '.join(lacking)}; expected a "
                                 "DiLiGenT folder holding ballPNG and catPNG (the A/B scores both)")
    if args.record:
        with refusals():
            check_card_ab(args)


def _scored(args: Options) -> set[str]:
    """The arms WORK/ab.json already holds scores of (none where it is missing or unreadable: main says why)."""
    try:
        scores = read_figures(args.work / "ab.json")
    except (OSError, ValueError, RecursionError):
        return set()
    return set(scores) if isinstance(scores, dict) else set()


def main(argv: list[str] | None = None) -> int:
    args = parse(COMMAND, argv)
    before_work(args)
    from orchestrate.asset_split import SPLIT_FOLDERS, check_split, split_assets

    w = args.work
    w.mkdir(parents=True, exist_ok=True)
    if check_split(args.assets, w, False):
        split_assets(args.assets, w)
    train_assets, held = (str(w / d) for d in SPLIT_FOLDERS)
    val = make(w / "val", ["--objects", "100", "--spp", "32", "--seed", "4000", "--lights", FAMILIES, "--assets", held],
               "fixed validation set")
    newval = [
        make(
            w / "newval4",
            ["--objects", "30", "--spp", "32", "--seed", "4104", "--level", "4", "--assets", held],
            "held-out new kinds, level 4",
        ),
        make(
            w / "newval5",
            [
                "--objects",
                "30",
                "--spp",
                "32",
                "--seed",
                "4105",
                "--level",
                "5",
                "--camera",
                "perspective",
                "--focal",
                "15-300",
                "--assets",
                held,
            ],
            "held-out new kinds, level 5, perspective",
        ),
    ]
    n = args.objects
    data = {}
    arms = args.arms
    if "today" in arms or "sensor" in arms:
        data["today"] = [
            make(
                w / "train_today",
                ["--objects", str(n), "--spp", "16", "--seed", "20000", "--lights", FAMILIES, "--assets", train_assets],
                "train: today",
            )
        ]
    if "sensor" in arms:
        out = w / "train_sensor"
        if not (out / "manifest.json").is_file():
            run(["wildgen.sensor", "--data", str(data["today"][0]), "--sensor", "machine-vision", "--out", str(out)],
                "train: today's scenes, machine-vision sensor")
        data["sensor"] = [out]
    if "new" in arms:
        data["new"] = []
        for level in range(1, LEVELS + 1):
            extra = ["--camera", "perspective", "--focal", "15-300"] if level == 5 else []
            data["new"].append(make(w / f"train_new_l{level}", ["--objects", str(n // LEVELS), "--spp", "16", "--seed",
                                                                 str(20010 + level), "--level", str(level),
                                                                 "--assets", train_assets, *extra],
                                    f"train: new, level {level}"))
    runs = {}
    for arm in arms:
        out = w / f"run_{arm}{args.tag}"
        if not (out / "best.safetensors").is_file():
            run(["unips.train", "--data", ",".join(map(str, data[arm])), "--val", str(val), "--model", DEFAULT_MODEL,
                 "--init-from", str(SHIPPED), "--out", str(out), "--steps", str(args.steps), "--lr", args.lr,
                 "--warmup", "50", "--val-every", str(args.steps), "--ckpt-every", str(args.steps), "--seed", "0",
                 "--threads", str(args.threads), "--no-progress", *(["--curriculum"] if arm == "new" else [])],
                f"fine-tune: {arm}")
        runs[arm + args.tag] = out / "best.safetensors"

    import torch

    torch.set_num_threads(args.threads)
    from orchestrate.benchmark import diligent_table
    from unips.inference import load_network

    results_path = w / "ab.json"
    results: dict = {}
    if results_path.is_file():  # an earlier run's scores, kept (resumed)
        with reading_record(results_path, "this bench's scores (WORK/ab.json)", "remove it to score again",
                            flag="--work"):
            results = read_figures(results_path)
            if not isinstance(results, dict) or not all(isinstance(r, dict) for r in results.values()):
                raise ValueError("expected an object of scores per arm")
            for name, r in results.items():
                _table_row(name, r)  # every figure the table and the card read, of its kind
    for name, weights in [("shipped", SHIPPED), *runs.items()]:
        if name in results:
            continue
        t0 = time.perf_counter()
        net = load_network(weights)
        r = {"weights": str(weights), "fixed_validation": score_set(net, val),
             "new_kinds": [score_set(net, f) for f in newval]}
        dil = diligent_table(args.diligent, net, None, None)
        r["diligent"] = {k: {"k96_deg": v["methods"]["model"]["mae_deg"], "k16_deg": v["model_subsets"]["mean"]}
                         for k, v in dil.items() if k in DILIGENT_OBJECTS}
        r["seconds"] = time.perf_counter() - t0
        results[name] = r
        write_json(results_path, results, indent=1)
        print(f"scored {name} in {r['seconds']:.0f} s", flush=True)
    print(f"\n{'model':10s} {'fixed val':>9s} {'gain':>5s} {'new L4':>7s} {'new L5':>7s} {'ball96':>7s} {'ball16':>7s} "
          f"{'cat96':>6s} {'cat16':>6s}")
    for name, r in results.items():
        print(_table_row(name, r))
    print(f"wrote {results_path}")
    if args.record:
        record(results, w, args)
    return 0


def _table_row(name: str, r: dict) -> str:
    """One arm's line of the printed table (the figures of its scores, each a number)."""
    d = r["diligent"]
    figures = [r["fixed_validation"]["mean_deg"], r["fixed_validation"]["gain_deg"], r["new_kinds"][0]["mean_deg"],
               r["new_kinds"][1]["mean_deg"], d["ball"]["k96_deg"], d["ball"]["k16_deg"], d["cat"]["k96_deg"],
               d["cat"]["k16_deg"]]
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in figures):
        raise ValueError(f"arm {name!r}: a figure is not a number")
    widths = (9, 5, 7, 7, 7, 7, 6, 6)
    return f"{name:10s} " + " ".join(f"{v:{n}.2f}" for v, n in zip(figures, widths))


def check_card_ab(args: Options) -> None:
    """With --record, before any work: the model card is readable, and an A/B it already holds was measured with
    this run's --steps and --objects (its arms and this run's share one table; another budget would mix two)."""
    with reading_record(CARD_PATH, "a model card", "restore it (git checkout)", flag="--record"):
        card = read_figures(CARD_PATH)
        if not isinstance(card, dict) or not isinstance(card.get("lineage"), list):
            raise ValueError("expected an object with a lineage list")
        ab = card.get("data_ab")
        if ab is not None and not (isinstance(ab, dict) and isinstance(ab.get("results"), dict)):
            raise ValueError("its data_ab is not an object with results per arm")
    if ab and (ab.get("steps"), ab.get("objects")) != (args.steps, args.objects):
        raise UsageError(f"--record: the model card's A/B holds arms {', '.join(ab['results'])} measured with --steps "
                         f"{ab.get('steps')} --objects {ab.get('objects')}; this run's --steps {args.steps} --objects "
                         f"{args.objects} would mix two budgets in one table: run with those, or without --record")


def record(results: dict, w: Path, args) -> None:
    """Append each arm's run to the model card's lineage (not shipped: none of them is compared for shipping
    here) and the A/B scores to `data_ab`."""
    from scenes.files import write_json

    card_path = CARD_PATH
    with reading_record(card_path, "a model card", "restore it (git checkout)"):
        card = read_json(card_path)
        shipped_stage = next((s["stage"] for s in reversed(card["lineage"]) if s.get("shipped") is not False
                              and "not shipped" not in s["stage"]), "shipped")
        stages = {s["stage"] for s in card["lineage"]}
    for name, r in results.items():
        if name == "shipped":
            continue
        arm = name.split("_")[0]
        run_dir = w / f"run_{name}"
        with reading_record(run_dir / "log.jsonl", "a unips.train log", "train the arm again", flag="--work"):
            log = [json.loads(line) for line in read_text_file(run_dir / "log.jsonl").splitlines()]
            vals = [x for x in log if "val" in x]
            steps = max(x["step"] for x in log if "step" in x)
            train_t = {x["step"]: x["elapsed_s"] for x in log if "loss" in x and "elapsed_s" in x}
            if not isinstance(steps, int) or not train_t or not all(
                    isinstance(v, (int, float)) for v in train_t.values()):
                raise ValueError("its steps are not whole numbers with their elapsed seconds")
            curve = [{"step": x["step"], "hours": round(train_t.get(x["step"], max(train_t.values())) / 3600, 3),
                      **{k: round(v, 2) for k, v in x["val"]["probes"].items()}, "gain": round(x["val"]["gain"], 2)}
                     for x in vals]
            families = {f: {"all": round(v["mean"]["all"], 2), "gain": round(v["gain"], 2), "n": v["n"]}
                        for f, v in vals[-1]["val"]["families"].items()} if vals else {}
        lr = name.split("_lr", 1)[1] if "_lr" in name else "1.5e-4"  # the tag this script gives a --lr run
        n = sum(
            len(list(Path(d).glob("*.data")))
            for d in {
                "today": [w / "train_today"],
                "sensor": [w / "train_sensor"],
                "new": sorted(w.glob("train_new_l*")),
            }[arm]
        )
        stage = f"data A/B: {arm}, lr {lr} (not shipped)"
        if stage in stages:
            continue
        card["lineage"].append({
            "stage": stage, "init_from": f"{shipped_stage} (shipped)", "data": ARM_DATA[arm].format(n=n) +
            ", 128 px, 10 images, 16 spp, train assets (bench/ab_data.py)",
            "command": f"python bench/ab_data.py --work WORK --objects {args.objects} --steps {args.steps} --arms {arm}"
                       + (f" --lr {lr} --tag _lr{lr}" if "_lr" in name else ""),
            "steps": steps, "threads": args.threads, "shipped": False, "objects": n,
            "hours": round(max(train_t.values()) / 3600, 2),
            "best_step": vals[-1]["step"] if vals else None, "curve": curve,
            "per_family_at_best": families,
        })
    # arms an earlier WORK recorded with the same budget stay beside this run's (check_card_ab refused another budget)
    kept = dict((card.get("data_ab") or {}).get("results") or {})
    kept.update({k: {a: v[a] for a in ("fixed_validation", "new_kinds", "diligent")} for k, v in results.items()})
    card["data_ab"] = {"protocol": __doc__.split("\n\n")[1].strip(), "steps": args.steps, "objects": args.objects,
                       "results": kept}
    write_json(card_path, card, indent=1)
    print(f"recorded {len(results) - 1} runs in {card_path}")


if __name__ == "__main__":
    sys.exit(run_main(main))
