"""Does the fitted check rank the truth first where it judges, and abstain elsewhere? (docs/check.md, "Trusted")

    python bench/bench_verdict.py --out bench_verdict.json CAPTURE [CAPTURE ...]

Each CAPTURE is an object folder with ground-truth normals and without scene.json (the fitted mode): DiLiGenT
`*PNG` folders, or `wildgen.make` objects copied without their scene file. A hard synthetic suite (held-out
meshes and HDR maps, glossy and metallic materials, near point and area lights):

    python -m wildgen.make --objects 40 --images 12 --res 64 --spp 64 --lights directional,point,near_area,hdri,mixed \\
        --assets ASSETS --shapes mesh --seed 777 --out HARD
    for d in HARD/*.data; do
        mkdir -p HARDNOS/$(basename $d); cp $d/L*.png $d/mask.png $d/normal.tif HARDNOS/$(basename $d)/
    done

For each capture: the verdict from the images alone (`validate.fitted.verdict`: explained fraction, trusted), and
for each map (ground truth; the truth tilted locally by 10 and 25 degrees about an axis that varies across the
image, `smooth`; 10 degrees per pixel, `random`; the shipped model's prediction; the constant (0, 0, 1) map)
its angular error, the fitted score over all observations (`rel_l1`) and over the observations every map
shares (`judged_rel_l1`). The targets: on every trusted capture, the truth scores below every map at least 10
degrees off, and GT+10 < GT+25 < constant; the abstention rate. `--near` runs the near-light trial of
docs/check.md (a test per tile where the whole-object test abstains; measured, not adopted).
"""
from __future__ import annotations

import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Literal

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.cli_common import claim_result, need_path, parse, run_main, write_result  # noqa: E402
from scenes.cli.errors import UsageError  # noqa: E402
from scenes.cli.needs import Needs  # noqa: E402
from scenes.cli.options import REQUIRED, Command, Positional, arg, check_fields, option  # noqa: E402


def explain_by_tile(images: np.ndarray, mask: np.ndarray, saturated: np.ndarray | None, tile: int,
                    from_box: bool = False):
    """`validate.fitted.verdict.explain` run on each tile x tile square of the mask separately (tiles of fewer than 12
    mask pixels are not explained): a trial of a test for near lights, which are locally distant. Squares laid
    from the image's corner, or from the mask's bounding box (`from_box`, the --near trial)."""
    from validate.fitted.verdict import Explanation, explain

    p = int(mask.sum())
    keep, explained, residual = np.zeros((images.shape[0], p), bool), np.zeros(p, bool), np.full(p, np.inf)
    index = np.full(mask.shape, -1)
    index[mask] = np.arange(p)
    sigmas = []
    ys, xs = np.nonzero(mask)
    y0, x0 = (int(ys.min()), int(xs.min())) if from_box and p else (0, 0)
    for y in range(y0, mask.shape[0], tile):
        for x in range(x0, mask.shape[1], tile):
            sub = np.zeros_like(mask)
            sub[y:y + tile, x:x + tile] = mask[y:y + tile, x:x + tile]
            if sub.sum() < 12:
                continue
            ex = explain(images, sub, saturated)
            ids = index[sub]
            keep[:, ids], explained[ids], residual[ids] = ex.keep, ex.explained, ex.residual
            sigmas.append(ex.sigma)
    return Explanation(keep=keep, explained=explained, residual=residual,
                       sigma=float(np.median(sigmas)) if sigmas else 0.0)


def optimised_maps(maps: dict, cap, small, cfg) -> None:
    """--optimised: refine each starting map (validate.refine's defaults, fitted lights) at the fitting resolution
    and add it to `maps` as '<name>*' (upsampled by nearest neighbour to be scored and measured like the others)."""
    import cv2

    from unips.data import load_object
    from unips.inference import predict_object
    from validate.fitted.fit import prepare
    from validate.fitted.refinement import RefineConfig, refine_normals

    starts = {k: maps[k] for k in ("gt", "gt+10", "gt+25", "model") if k in maps}
    if cap.light_directions is not None:
        starts["least-squares"] = maps["least-squares"] = predict_object(load_object(cap.folder), "least-squares", None)
    h, w = cap.mask.shape
    for name, m in starts.items():
        _, nm, _ = prepare(cap, m, cfg)
        t0 = time.perf_counter()
        r = refine_normals(small.images, small.mask, nm, RefineConfig(), saturated=small.saturated)
        up = cv2.resize(r.normals, (w, h), interpolation=cv2.INTER_NEAREST)
        up = np.where(cap.mask[..., None], up / np.maximum(np.linalg.norm(up, axis=-1, keepdims=True), 1e-12), 0)
        maps[name + "*"] = np.where(np.linalg.norm(up, axis=-1, keepdims=True) > 0.5, up, m).astype(np.float32)
        print(f"  refined {name} in {time.perf_counter() - t0:.0f} s", flush=True)


def _subsets(cap) -> dict[str, object]:
    """The --degenerate sweep of one calibrated capture: name -> image indices, or ('copies', i) for 8 scaled
    copies of image i (the image lit most nearly from the camera)."""
    L = cap.light_directions  # (K, 3) toward the light
    right = np.nonzero(L[:, 0] > 0.15)[0]
    spread = lambda idx, n: idx[np.linspace(0, len(idx) - 1, n).round().astype(int)]  # noqa: E731
    return {
        "8 copies of one image": ("copies", int(np.argmin(np.abs(L[:, 0]) + np.abs(L[:, 1])))),
        "5 lights most to the right": np.argsort(-L[:, 0])[:5],
        "5 of the right half": spread(right, 5),
        "40 of the right half": spread(right, min(40, len(right))),
        "5 spread over all": spread(np.arange(len(L)), 5),
        "8 spread over all": spread(np.arange(len(L)), 8),
    }


def degenerate_sweep(captures: list[Path], out: Path) -> int:
    """--degenerate: per capture and subset, the light dimensions and verdict from the images alone, and the judged
    scores of the truth, its mirror image (n_x negated) and the constant map."""
    import dataclasses

    from scenes.renderer.variant import choose_variant

    choose_variant("llvm_ad_rgb")
    from validate.fitted.fit import fit_normals, prepare
    from validate.fitted.fit_scene import FitConfig
    from validate.fitted.verdict import explain, judged_rel_l1, verdict
    from validate.observations import load_capture

    cfg, rows = FitConfig().validate(), []
    for folder in captures:
        full = load_capture(folder, arg="CAPTURE")
        if full.light_directions is None or full.normal_gt is None:
            print(f"{folder}: needs calibrated lights and ground truth, skipped", file=sys.stderr)
            continue
        for name, sel in _subsets(full).items():
            if isinstance(sel, tuple):
                imgs = np.stack([full.images[sel[1]] * s for s in np.linspace(0.6, 1.3, 8)]).astype(np.float32)
                cap = dataclasses.replace(
                    full,
                    images=imgs,
                    saturated=None,
                    light_directions=None,
                    light_irradiance=None,
                    image_names=[f"copy{i}" for i in range(8)],
                )
            else:
                cap = dataclasses.replace(full, images=full.images[sel], light_directions=full.light_directions[sel],
                                          light_irradiance=None, image_names=[full.image_names[i] for i in sel],
                                          saturated=None if full.saturated is None else full.saturated[sel])
            gt = cap.normal_gt
            small, _, _ = prepare(cap, gt, cfg)
            ex = explain(small.images, small.mask, small.saturated)
            trusted, why = verdict(ex)
            row = {"capture": folder.name, "subset": name, "images": len(small.images),
                   "dimensions": [round(d, 1) for d in ex.dimensions], "trusted": trusted, "why": why, "judged": {}}
            maps = {"gt": gt, "mirrored": gt * np.float32([-1, 1, 1]),
                    "constant": np.where(cap.mask[..., None], np.float32([0, 0, 1]), 0).astype(np.float32)}
            for key, m in maps.items():
                _, nm, _ = prepare(cap, m, cfg)
                r = fit_normals(small.images, small.mask, nm, cfg, saturated=small.saturated)
                row["judged"][key] = judged_rel_l1(r.render, small.images[:, small.mask], ex)
            rows.append(row)
            print(f"{folder.name:<10} {name:<28} K={row['images']:<3} dimensions {row['dimensions']} trusted "
                  f"{trusted!s:<5} " + "  ".join(f"{k} {v:.4f}" for k, v in row["judged"].items()), flush=True)

    write_result(out, {"rows": rows}, indent=1)
    print(f"wrote {out}")
    return 0


NEAR_MIN_EXPLAINED = 0.55
"""--near trial: share of the mask a tile-by-tile test must explain (above the whole-object test's 0.5)."""
NEAR_TILES_ACROSS = 4
"""--near trial: tiles of a quarter of the mask's larger bounding-box side (16 px on the 64 px suite)."""


def near_judgement(images: np.ndarray, mask: np.ndarray, saturated: np.ndarray | None):
    """--near trial: the check's whole-object test first; where it abstains, the rank-4 test per tile of a quarter of
    the object (a near light is locally distant), trusted at `NEAR_MIN_EXPLAINED` and judged with the point light
    model. Returns (explanation, trusted, why, light model, test)."""
    from validate.fitted.verdict import explain, verdict

    ex = explain(images, mask, saturated)
    trusted, why = verdict(ex)
    if trusted:
        return ex, True, why, "directional", "whole object"
    ys, xs = np.nonzero(mask)
    tile = max(8, int(np.ceil(max(np.ptp(ys) + 1, np.ptp(xs) + 1) / NEAR_TILES_ACROSS)))
    local = explain_by_tile(images, mask, saturated, tile, from_box=True)
    if local.explained_fraction >= NEAR_MIN_EXPLAINED:
        return local, True, f"{local.explained_fraction:.0%} explained tile by tile", "point", f"tiles of {tile} px"
    return ex, False, why, "directional", "whole object"


@dataclass
class Options:
    """The command line of bench/bench_verdict.py."""

    captures: Positional[Annotated[list[Path], arg(metavar="CAPTURE")]] = REQUIRED
    """Object folders with ground-truth normals, one or more."""
    out: Annotated[Path, arg(metavar="FILE")] = Path("bench_verdict.json")
    """Write the rows and the summary as JSON here."""
    model: bool = True
    """score the shipped model's map (--no-model: skip it)"""
    refine: bool = False
    """also refine the shipped model's map (validate.refine's defaults) and report its error before and after, and
    whether the refinement was accepted"""
    optimised: bool = False
    """on each trusted capture also refine the ground truth, GT+10, GT+25, the shipped model's map and calibrated
    least squares (where the folder has lights) with validate.refine's defaults at the fitting resolution, and score
    the refined maps ('<map>*') too"""
    light_model: Literal["directional", "point", "environment"] = "directional"
    """light model of every fit (the check's default: directional)"""
    tile: int = option(0, minimum=0)
    """trial: run the images-only rank-4 test per square tile of this many pixels at the fitting resolution (a near
    light is locally distant) instead of over the whole object (0, the check's test)"""
    near: bool = False
    """trial: the whole-object test, then where it abstains the test per tile of a quarter of the object, trusted
    from 55 % explained and judged with the point light model (overrides --tile and --light-model)"""
    degenerate: bool = False
    """instead: the sweep of nearly unjudgeable captures made from each calibrated capture (8 scaled copies of one
    image; the 5 lights most to the right; 5 and 40 of the right half; 5 and 8 spread over all): light dimensions,
    verdict, and the judged scores of the truth, the truth mirrored left to right (lights turned with it) and the
    constant map"""

    def validate(self) -> "Options":
        check_fields(self)
        if not self.captures:
            raise UsageError("the following arguments are required: CAPTURE")
        return self


COMMAND = Command(Options, prog="python bench/bench_verdict.py", description=__doc__.split("\n\n")[0],
                  needs=(Needs("refine", lambda c, _: c.model, "with the model's map scored (without --no-model)"),
                         *(Needs(f, lambda c, _: not c.degenerate, "without --degenerate (a sweep of its own)")
                           for f in ("refine", "optimised", "tile", "near"))))
RESULT_KEYS = ("rows",)
"""The key of every result (--out, --degenerate's too): a file without it is not this bench's and is never replaced."""


def before_work(args: Options) -> None:
    """What the command line names on disk, checked before any work (each refusal one line)."""
    for capture in args.captures:
        need_path(capture, "CAPTURE", "an object folder with ground-truth normals")
    claim_result(args.out, RESULT_KEYS, COMMAND, inputs={f"CAPTURE {c}": c for c in args.captures})


def main(argv: list[str] | None = None) -> int:
    args = parse(COMMAND, argv)
    before_work(args)
    if args.degenerate:
        return degenerate_sweep(args.captures, args.out)

    from scenes.metrics import mean_angular_error
    from scenes.renderer.variant import choose_variant

    choose_variant("llvm_ad_rgb")
    from unips.data import load_object
    from unips.inference import load_network, predict_object
    from validate.fitted.fit import fit_normals, prepare
    from validate.fitted.fit_scene import FitConfig
    from validate.fitted.verdict import explain, judged_rel_l1, told_apart, verdict
    from validate.observations import load_capture
    from validate.perturb import perturb_normals

    base = FitConfig(light_model=args.light_model).validate()
    net = None if not args.model else load_network(None)
    rows = []
    for folder in args.captures:
        t0 = time.perf_counter()
        cap = load_capture(folder, arg="CAPTURE")
        gt = cap.normal_gt
        if gt is None:
            print(f"{folder}: no ground truth, skipped", file=sys.stderr)
            continue
        small, _, _ = prepare(cap, gt, base)
        cfg, test = base, "whole object" if args.tile <= 0 else f"tiles of {args.tile} px"
        if args.near:
            ex, trusted, why, model, test = near_judgement(small.images, small.mask, small.saturated)
            cfg = FitConfig(light_model=model).validate()
        else:
            ex = (explain(small.images, small.mask, small.saturated) if args.tile <= 0 else
                  explain_by_tile(small.images, small.mask, small.saturated, args.tile))
            trusted, why = verdict(ex)
        maps = {"gt": gt,
                "gt+10": perturb_normals(gt, cap.mask, "smooth", 10, 0),
                "gt+25": perturb_normals(gt, cap.mask, "smooth", 25, 0),
                "random10": perturb_normals(gt, cap.mask, "random", 10, 0)}
        if net is not None:
            maps["model"] = predict_object(load_object(folder), "model", net)
        maps["constant"] = np.where(cap.mask[..., None], np.float32([0, 0, 1]), 0).astype(np.float32)
        if args.optimised and trusted:
            optimised_maps(maps, cap, small, cfg)
        row = {"capture": folder.name, "explained": ex.explained_fraction, "trusted": trusted, "why": why,
               "test": test, "light_model": cfg.light_model, "maps": {}}
        for name, m in maps.items():
            _, nm, _ = prepare(cap, m, cfg)
            r = fit_normals(small.images, small.mask, nm, cfg, saturated=small.saturated)
            row["maps"][name] = {"mae_deg": mean_angular_error(m, gt, cap.mask), "rel_l1": r.rel_l1,
                                 "judged_rel_l1": judged_rel_l1(r.render, small.images[:, small.mask], ex)}
        if args.refine and "model" in maps:
            from validate.fitted.refinement import refine_object

            rr = refine_object(str(folder), maps["model"])
            row["refine"] = {"before_deg": rr["before"]["mae_deg"], "after_deg": rr["after"]["mae_deg"],
                             "accepted": rr["accepted"], "why": rr["why"], "seconds": rr["timings"]["total_s"]}
            print(
                f"  refine: {rr['before']['mae_deg']:.2f} -> {rr['after']['mae_deg']:.2f} deg, "
                f"accepted {rr['accepted']} "
                f"({rr['timings']['total_s']:.0f} s)",
                flush=True,
            )
        s = {k: v["judged_rel_l1"] for k, v in row["maps"].items()}
        far = [k for k, v in row["maps"].items() if k != "gt" and v["mae_deg"] >= 10]
        row["gt_first"] = all(s["gt"] < s[k] for k in far)
        row["ordered"] = s["gt+10"] < s["gt+25"] < s["constant"]
        # With the resolution: first or not told apart; in order or not told apart.
        row["resolution"] = ex.resolution
        row["gt_first_or_tied"] = all(s["gt"] < s[k] or not told_apart(s["gt"], s[k], ex) for k in far)
        row["ordered_or_tied"] = all(a < b or not told_apart(a, b, ex) for a, b in
                                     ((s["gt+10"], s["gt+25"]), (s["gt+25"], s["constant"])))
        row["below_gt_told_apart"] = [k for k in s if k != "gt" and s[k] < s["gt"] and told_apart(s["gt"], s[k], ex)]
        row["gt_first_old_score"] = all(row["maps"]["gt"]["rel_l1"] < row["maps"][k]["rel_l1"] for k in far)
        row["seconds"] = time.perf_counter() - t0
        rows.append(row)
        print(
            f"{row['capture']:<14} {test} {cfg.light_model} explained {row['explained']:.2f} trusted {str(trusted):<5} "
            f"resolution {row['resolution']:.4f} first-or-tied {row['gt_first_or_tied']!s:<5} ordered-or-tied "
            f"{row['ordered_or_tied']!s:<5} gt_first {row['gt_first']!s:<5} "
            f"ordered {row['ordered']!s:<5} (old score gt_first {row['gt_first_old_score']})  "
            + "  ".join(f"{k} {v['mae_deg']:.1f}deg {v['judged_rel_l1']:.4f}" for k, v in row["maps"].items()),
            flush=True,
        )
    judged = [r for r in rows if r["trusted"]]
    summary = {
        "captures": len(rows),
        "trusted": len(judged),
        "light_model": "verdict (--near)" if args.near else args.light_model,
        "tile": args.tile,
        "near": args.near,
        "trusted_by_tiles": sum(r["test"] != "whole object" for r in judged),
        "abstention_rate": 1 - len(judged) / len(rows) if rows else None,
        "trusted_gt_first": sum(r["gt_first"] for r in judged),
        "trusted_ordered": sum(r["ordered"] for r in judged),
        "trusted_gt_first_or_tied": sum(r["gt_first_or_tied"] for r in judged),
        "trusted_ordered_or_tied": sum(r["ordered_or_tied"] for r in judged),
        "trusted_with_a_map_told_apart_below_gt": sum(bool(r["below_gt_told_apart"]) for r in judged),
        "all_gt_first_judged_score": sum(r["gt_first"] for r in rows),
        "all_gt_first_old_score": sum(r["gt_first_old_score"] for r in rows),
    }
    refined = [r["refine"] for r in rows if "refine" in r]
    if refined:
        change = [r["after_deg"] - r["before_deg"] for r in refined]
        summary["refine"] = {"objects": len(refined), "accepted": sum(r["accepted"] for r in refined),
                             "mean_change_deg": float(np.mean(change)), "largest_rise_deg": float(max(change))}
    print(json.dumps(summary))

    write_result(args.out, {"summary": summary, "rows": rows}, indent=1)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(run_main(main))
