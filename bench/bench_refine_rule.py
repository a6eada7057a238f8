"""When should the refined map replace the model's? Rules of keeping, measured on held-out renders with ground truth
(docs/check.md, "Keeping the refined map").

    python bench/bench_refine_rule.py --work /tmp/refbench --out bench/results/refine_rule.json

Renders `ROWS` (for each of `--seeds`: a rule is chosen on the first set and confirmed on the others) with the
held-out meshes and HDR maps (`orchestrate.asset_split`), predicts each object with the shipped model, and refines
every map the check can judge (`validate.fitted.refinement.refine_object`, the capture's own refinement, a Dr.Jit
thread per core). Every report carries the model's and the refined map's true mean angular error, the judged
residual before and after, the capture's resolution and the residual on the held-out images (which no step that
moved the normals used). Each rule of `RULES` decides from those figures alone (never the truth) whether the refined
map is kept; per rule: the mean true error of the kept maps, how often it kept a refined map that was worse by more
than `HURT_DEG` ("hurt") and declined one that was better by as much ("missed"), beside always the model's map and
the oracle (the better of the two).
"""
from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.cli_common import check_given, check_work, claim_result, machine, parse, run_main, write_result  # noqa: E402
from scenes.cli.errors import UsageError  # noqa: E402
from scenes.cli.options import Command, arg, check_fields, comma_list, option  # noqa: E402

RESULT_KEYS = ("command", "rows_rendered", "hurt_deg", "rows", "sets")
"""The keys of every result (--out): a file without them is not this bench's and is never replaced."""

ROWS = (
    ("diffuse", ("--lights", "directional", "--materials", "diffuse", "--images", "12")),
    ("specular", ("--lights", "directional", "--materials", "specular", "--images", "12")),
    ("diligent", ("--preset", "diligent", "--images", "12")),
    ("machine_vision", ("--lights", "directional", "--materials", "diffuse", "--images", "12", "--sensor",
                        "machine-vision")),
    ("few", ("--lights", "directional", "--images", "6")),
)
"""Captures a distant-light check can often judge: lab-like light, diffuse to glossy, a sensor's noise, few photos."""
HURT_DEG = 0.5
"""A kept refined map more than this much worse than the model's (deg of mean angular error) counts as hurt."""


def _fall(before: float, after: float) -> float:
    return (before - after) / before if before > 0 else 0.0


def _falls(key: str, share: float):
    def rule(r: dict) -> bool:
        if key == "judged":
            return _fall(r["judged_before_rel_l1"], r["judged_after_rel_l1"]) > share
        held = r["holdout_judged"]
        return held is not None and _fall(held["before_rel_l1"], held["after_rel_l1"]) > share
    return rule


RULES = {
    **{f"residual falls {t:.0%}": _falls("judged", t) for t in (0.02, 0.1, 0.2, 0.3, 0.4)},
    "residual falls beyond the resolution": lambda r: r["judged_before_rel_l1"] - r["judged_after_rel_l1"]
    > r["resolution"],
    **{f"held-out residual falls {t:.0%}": _falls("held-out", t) for t in (0.02, 0.1, 0.2, 0.3)},
    "residual falls 2% and held-out 30%": lambda r: _falls("judged", 0.02)(r) and _falls("held-out", 0.3)(r),
    "never (the model's map)": lambda r: False,
}
"""Rules of keeping the refined map: name -> decision from the refinement's report (no ground truth). The rule in use
(`validate.fitted.refinement.refine_judged`) is "residual falls 2% and held-out 30%"."""


@dataclass
class Options:
    """bench_refine_rule: rules of keeping the refined map, on held-out renders."""

    work: Annotated[str, arg(metavar="DIR")] = "/tmp/refbench"
    """Renders, WORK/seed<N> per seed (resumed when run again)."""
    out: Annotated[str, arg(metavar="FILE")] = "bench/results/refine_rule.json"
    """Where the results are written (JSON)."""
    objects: int = option(10, minimum=1)
    """Objects per row."""
    seeds: Annotated[list[int], comma_list(int, "SEED,SEED")] = option(default_factory=lambda: [9500, 9600],
                                                                        minimum=0)
    """Seeds of independently rendered sets, comma-separated (a set's row i: seed + 100 i): a rule is chosen on the
    first and confirmed on the others; none is a seed the model was trained, validated or tested on."""

    def validate(self) -> "Options":
        check_fields(self)
        check_given(self, "seeds")
        if len(self.seeds) < 2:  # one set chooses a rule that nothing then confirms
            raise UsageError(f"--seeds: got {','.join(map(str, self.seeds))!r}, expected at least two seeds (a rule "
                             "is chosen on the first set and confirmed on the others)")
        if len(set(self.seeds)) < len(self.seeds):
            raise UsageError(f"--seeds: got {','.join(map(str, self.seeds))!r}, expected different seeds (each one a "
                             "set rendered into WORK/seed<N>)")
        return self


def summarise(reports: list[dict]) -> list[dict]:
    """Per rule (and the oracle): the mean true error of the kept maps, hurt and missed counts."""
    model = np.array([r["before"]["mae_deg"] for r in reports])
    refined = np.array([r["refined_mae_deg"] for r in reports])
    rows = []
    for name, rule in RULES.items():
        keep = np.array([bool(rule(r)) for r in reports])
        kept = np.where(keep, refined, model)
        rows.append({"rule": name, "kept_refined": int(keep.sum()), "mean_error_deg": round(float(kept.mean()), 3),
                     "hurt": int((keep & (refined > model + HURT_DEG)).sum()),
                     "missed": int((~keep & (refined < model - HURT_DEG)).sum())})
    rows.append({"rule": "oracle (the better map, from the truth)", "kept_refined": int((refined < model).sum()),
                 "mean_error_deg": round(float(np.minimum(model, refined).mean()), 3), "hurt": 0, "missed": 0})
    return rows


def table(sets: list[dict]) -> list[dict]:
    """One row per rule: its figures on each set (`summarise`), keyed by the set's seed."""
    per_set = [summarise(d["reports"]) for d in sets]
    return [{"rule": row["rule"], "by_seed": {str(d["seed"]): rows[i] for d, rows in zip(sets, per_set)}}
            for i, row in enumerate(per_set[0])]


def refine_set(work: Path, objects: int, seed: int) -> dict:
    """Render (or resume) one set and refine each object's model map: its judged captures' reports."""
    from orchestrate.asset_split import split_assets
    from orchestrate.error_calibration import objects_of, render_suite
    from unips.data import load_object
    from unips.inference import load_network, run_model
    from validate.fitted.refinement import RefineConfig, refine_object

    work.mkdir(parents=True, exist_ok=True)
    assets = ROOT.parent / "shared" / "assets"
    held = str(split_assets(assets, work)[1]) if assets.is_dir() else None
    datasets = render_suite(work, held, objects, seed, rows=ROWS)
    net = load_network(None)
    reports = []
    folders = objects_of(datasets)
    for i, folder in enumerate(folders):
        r = refine_object(str(folder), run_model(net, load_object(folder)), RefineConfig())
        if r["trusted"]:
            reports.append({k: r[k] for k in ("object", "judged_before_rel_l1", "judged_after_rel_l1", "resolution",
                                               "holdout_judged", "refined_mae_deg", "accepted", "explained_fraction")}
                           | {"row": folder.parent.name, "before": {"mae_deg": r["before"]["mae_deg"]}})
        print(f"\rseed {seed}: {i + 1}/{len(folders)} objects, {len(reports)} judged", end="", file=sys.stderr,
              flush=True)
    print(file=sys.stderr)
    return {"seed": seed, "objects": len(folders), "judged": len(reports), "reports": reports}


COMMAND = Command(Options, prog="python bench/bench_refine_rule.py", description=__doc__.split("\n\n")[0])


def main(argv: list[str] | None = None) -> int:
    import torch

    from scenes.renderer.variant import choose_variant, set_jit_threads

    opts = parse(COMMAND, argv)
    check_work(opts.work)
    claim_result(opts.out, RESULT_KEYS, COMMAND)
    torch.set_num_threads(2)
    choose_variant("llvm_ad_rgb")  # the refinement needs automatic differentiation
    set_jit_threads(None)
    t0 = time.time()
    seeds = opts.seeds
    sets = [refine_set(Path(opts.work) / f"seed{seed}", opts.objects, seed) for seed in seeds]
    rows = table(sets)
    for row in rows:
        print(f"{row['rule']:42s} " + "  ".join(
            f"seed {k}: kept {q['kept_refined']:3d} mean {q['mean_error_deg']:.2f} hurt {q['hurt']} missed "
            f"{q['missed']}" for k, q in row["by_seed"].items()))
    result = {"command": f"python bench/bench_refine_rule.py --work WORK --objects {opts.objects} "
                         f"--seeds {','.join(map(str, seeds))}",
              "rows_rendered": [name for name, _ in ROWS], "hurt_deg": HURT_DEG,
              "rows": rows, "sets": sets, "seconds": round(time.time() - t0, 1),
              "machine": machine()}
    write_result(Path(opts.out), result, indent=1)
    print(f"wrote {opts.out}")
    return 0


if __name__ == "__main__":
    sys.exit(run_main(main))
