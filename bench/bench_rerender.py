"""Bench of the re-render check: does its residual rank normal errors like the true angular error does, and
what does a re-render cost compared with the original render?

Renders a small PS-Wild-style dataset with `wildgen.make` (or uses --data), then for each object:
- ground-truth normals (normal.tif) with the noise floor, reproduction check and timings;
- perturbed ground truth (random per pixel, smooth low-frequency, constant bias) at several angles,
  re-rendered with the recorded seeds; residual (rel_l1) against the true MAE.
Prints a table, the Spearman rank correlation between residual and MAE (pooled and per object), the
fraction of monotonic series, and the re-render / original render time ratio.

    python bench/bench_rerender.py --res 64 --spp 64 --objects 3 --images 4
"""
from __future__ import annotations

import logging
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Literal

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.cli_common import MIN_RES, claim_result, need_path, parse, run_main, write_result  # noqa: E402
from scenes.cli.needs import Needs  # noqa: E402
from scenes.cli.options import CommaList, Command, arg, comma_list, option  # noqa: E402
from scenes.renderer.variant import PREFERENCE as VARIANTS  # noqa: E402
from validate.perturb import KINDS  # noqa: E402
from wildgen.light_families import LIGHT_FAMILIES  # noqa: E402

RESULT_KEYS = ("rows", "baselines", "spearman_pooled", "monotonic")
"""The keys of every result (--json): a file without them is not this bench's and is never replaced."""


@dataclass
class Options:
    """The command line of bench/bench_rerender.py."""

    data: Annotated[str | None, arg(metavar="DIR", help_behavior_hint="(default: render one with wildgen.make)")] = (
        None
    )
    """existing dataset folder (*.data)"""
    res: int = option(64, minimum=MIN_RES)
    """resolution of the rendered dataset"""
    spp: int = option(64, minimum=1)
    """samples per pixel of the rendered dataset"""
    objects: int = option(3, minimum=1)
    """objects to render"""
    images: int = option(4, minimum=1)
    """images per object"""
    lights: Annotated[list[str], CommaList] = option(
        default_factory=lambda: ["near_area", "hdri", "mixed"], choices=tuple(LIGHT_FAMILIES))
    """light families for wildgen.make (cycled over objects)"""
    bounces: int = option(4, minimum=0)
    """bounces of the rendered dataset"""
    seed: int = 0
    """dataset and perturbation seed"""
    levels: Annotated[list[float], comma_list(float, "DEG,DEG")] = option(
        default_factory=lambda: [2.0, 5.0, 10.0, 20.0, 40.0], minimum=0, maximum=90)
    """perturbation angles in degrees"""
    kinds: Annotated[list[str], CommaList] = option(default_factory=lambda: list(KINDS), choices=KINDS)
    """perturbation kinds"""
    seed_mode: Literal["same", "independent"] = "same"
    """Seeds of the re-render: the recorded ones (same) or new ones (independent)."""
    variant: str | None = option(None, choices=("auto", *VARIANTS))
    """Mitsuba variant (default: cuda, llvm, scalar, the first this machine runs)."""
    json: Annotated[str | None, arg(metavar="FILE")] = None
    """write all numbers to this JSON file"""


COMMAND = Command(Options, prog="python bench/bench_rerender.py", description=__doc__, needs=tuple(
    Needs(f, lambda c, _: c.data is None, "without --data (they shape the dataset it renders)")
    for f in ("res", "spp", "objects", "images", "lights", "bounces")))


def before_work(args: Options) -> None:
    """What the command line names on disk, checked before any work (each refusal one line)."""
    if args.data is not None:
        need_path(args.data, "--data", "a dataset folder of object folders (*.data)")
    claim_result(args.json, RESULT_KEYS, COMMAND, "--json", inputs={"--data": args.data})


def main(argv: list[str] | None = None) -> int:
    args = parse(COMMAND, argv)
    before_work(args)
    logging.basicConfig(level=logging.WARNING)

    from scipy.stats import spearmanr

    from scenes.renderer.variant import choose_variant

    choose_variant(args.variant)
    import mitsuba as mi

    mi.set_log_level(mi.LogLevel.Error)
    from scenes.folder.format import list_object_folders
    from validate.observations import load_known_scene
    from validate.perturb import perturb_normals
    from validate.rerender import RerenderConfig, rerender_object

    tmp = None
    if args.data is None:
        from wildgen.make import main as make_main

        tmp = tempfile.TemporaryDirectory(prefix="bench_rerender_")
        data = Path(tmp.name) / "data"
        t0 = time.perf_counter()
        rc = make_main(
            ["--out", str(data), "--objects", str(args.objects), "--images", str(args.images), "--res", str(args.res),
             "--spp", str(args.spp), "--bounces", str(args.bounces), "--seed", str(args.seed), "--quiet"]
            + sum((["--lights", f] for f in args.lights), [])
        )
        if rc != 0:
            print(f"error: wildgen.make failed with exit code {rc}", file=sys.stderr)
            return 1
        print(
            f"dataset: {args.objects} objects x {args.images} images at {args.res}^2, {args.spp} spp "
            f"in {time.perf_counter() - t0:.1f} s"
        )
    else:
        data = Path(args.data)
    levels, kinds = args.levels, args.kinds

    rows, baselines = [], []
    for folder in list_object_folders(data):
        obj = load_known_scene(folder)
        if obj.normal_gt is None:
            print(f"skipping {obj.name}: no normal.tif")
            continue
        base = rerender_object(folder, obj.normal_gt, RerenderConfig(seed_mode=args.seed_mode))
        baselines.append(base)
        for kind in kinds:
            for level in levels:
                pred = perturb_normals(obj.normal_gt, obj.mask, kind, level, seed=args.seed + 1)
                r = rerender_object(folder, pred, RerenderConfig(seed_mode=args.seed_mode, floors=False))
                rows.append(
                    {
                        "object": obj.name,
                        "family": obj.desc.light_family,
                        "kind": kind,
                        "level": level,
                        "mae_deg": r["mae_deg"],
                        "rel_l1": r["rel_l1"],
                        "psnr": r["psnr"],
                        "gt_rel_l1": base["gt_rel_l1"],
                    }
                )

    print()
    print("object                family     gt_rel_l1  noise_floor  reproduce  rerender_s  original_s  ratio")
    for b in baselines:
        t = b["timings"]
        family = load_known_scene(b["folder"]).desc.light_family
        print(
            f"{b['object']:<21} {family:<10} {b['gt_rel_l1']:<10.4f} {b['noise_floor_rel_l1']:<12.4f} "
            f"{b['reproduce_rel_l1']:<10.2g} {t['rerender_s']:<11.4f} {t['original_render_s']:<11.4f} "
            f"{t['rerender_over_original']:.3f}"
        )
    print()
    print("object                kind    level   MAE     rel_l1   rel_l1/gt")
    for r in rows:
        print(
            f"{r['object']:<21} {r['kind']:<7} {r['level']:<7g} {r['mae_deg']:<7.2f} {r['rel_l1']:<8.4f} "
            f"{r['rel_l1'] / r['gt_rel_l1']:.2f}"
        )

    mae = np.array([r["mae_deg"] for r in rows])
    res = np.array([r["rel_l1"] for r in rows])
    def rank_corr(x: np.ndarray, y: np.ndarray) -> float:
        return float(spearmanr(x, y).statistic) if len(np.unique(y)) > 1 else float("nan")  # needs 2+ levels

    pooled = rank_corr(res, mae)
    per_object = {}
    for name in dict.fromkeys(r["object"] for r in rows):
        sel = np.array([r["object"] == name for r in rows])
        per_object[name] = rank_corr(res[sel], mae[sel])
    series = monotonic = 0
    for name in per_object:
        for kind in kinds:
            vals = [r["rel_l1"] for r in rows if r["object"] == name and r["kind"] == kind]
            series += 1
            monotonic += all(a < b for a, b in zip(vals, vals[1:]))
    ratios = [b["timings"]["rerender_over_original"] for b in baselines]
    print()
    print(f"Spearman(rel_l1, MAE): pooled {pooled:.3f} over {len(rows)} cases; per object "
          + ", ".join(f"{k} {v:.3f}" for k, v in per_object.items()))
    print(f"monotonic series: {monotonic}/{series}")
    print(
        f"re-render / original render time (median per image): {np.median(ratios):.3f} "
        f"(per object {', '.join(f'{x:.3f}' for x in ratios)})"
    )
    if args.json:
        write_result(
            Path(args.json),
            {
                "rows": rows,
                "baselines": baselines,
                "spearman_pooled": pooled,
                "spearman_per_object": per_object,
                "monotonic": [monotonic, series],
            },
            indent=1,
        )
    if tmp is not None:
        tmp.cleanup()
    return 0


if __name__ == "__main__":
    sys.exit(run_main(main))
