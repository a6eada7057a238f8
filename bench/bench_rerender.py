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

import argparse
import logging
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument(
        "--data", default=None, help="existing dataset folder (*.data); default: render one with wildgen.make"
    )
    p.add_argument("--res", type=int, default=64, help="resolution of the rendered dataset")
    p.add_argument("--spp", type=int, default=64, help="samples per pixel of the rendered dataset")
    p.add_argument("--objects", type=int, default=3, help="objects to render")
    p.add_argument("--images", type=int, default=4, help="images per object")
    p.add_argument(
        "--lights", default="near_area,hdri,mixed", help="light families for wildgen.make (cycled over objects)"
    )
    p.add_argument("--bounces", type=int, default=4, help="bounces of the rendered dataset")
    p.add_argument("--seed", type=int, default=0, help="dataset and perturbation seed")
    p.add_argument("--levels", default="2,5,10,20,40", help="perturbation angles in degrees")
    p.add_argument("--kinds", default="random,smooth,bias", help="perturbation kinds")
    p.add_argument("--seed-mode", default="same", choices=("same", "independent"))
    p.add_argument("--variant", default=None)
    p.add_argument("--json", default=None, help="write all numbers to this JSON file")
    args = p.parse_args(argv)
    logging.basicConfig(level=logging.WARNING)

    from scipy.stats import spearmanr

    from scenes.renderer.variant import choose_variant

    choose_variant(args.variant)
    import mitsuba as mi

    mi.set_log_level(mi.LogLevel.Error)
    from validate.io import list_objects, load_object
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
            + sum((["--lights", f] for f in args.lights.split(",")), [])
        )
        if rc != 0:
            print(f"error: wildgen.make failed with exit code {rc}", file=sys.stderr)
            return 1
        print(
            f"dataset: {args.objects} objects x {args.images} images at {args.res}^2, {args.spp} spp in {time.perf_counter() - t0:.1f} s"
        )
    else:
        data = Path(args.data)
    levels = [float(x) for x in args.levels.split(",")]
    kinds = args.kinds.split(",")

    rows, baselines = [], []
    for folder in list_objects(data):
        obj = load_object(folder)
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
        family = load_object(b["folder"]).desc.light_family
        print(
            f"{b['object']:<21} {family:<10} {b['gt_rel_l1']:<10.4f} {b['noise_floor_rel_l1']:<12.4f} "
            f"{b['reproduce_rel_l1']:<10.2g} {t['rerender_s']:<11.4f} {t['original_render_s']:<11.4f} {t['rerender_over_original']:.3f}"
        )
    print()
    print("object                kind    level   MAE     rel_l1   rel_l1/gt")
    for r in rows:
        print(
            f"{r['object']:<21} {r['kind']:<7} {r['level']:<7g} {r['mae_deg']:<7.2f} {r['rel_l1']:<8.4f} {r['rel_l1'] / r['gt_rel_l1']:.2f}"
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
        f"re-render / original render time (median per image): {np.median(ratios):.3f} (per object {', '.join(f'{x:.3f}' for x in ratios)})"
    )
    if args.json:
        from scenes.files import write_json

        write_json(
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
    sys.exit(main())
