"""Fitted mode of the re-render check and refinement: the figures of docs/check.md, "How well it works".

    python bench/bench_fit.py [--diligent ../shared/data/diligent] [--synthetic 3] [--threads T] [--tta N] \
        [--out bench_fit.json]

DiLiGenT (ball, cat; skipped when the folder is absent):
- fitted light directions with the ground-truth normals vs the calibrated ones (mean angular error);
- the score (rel_l1) of ground truth, calibrated least squares (unips.baselines), the shipped model and the
  constant (0, 0, 1) map, with their angular errors;
- perturbation series of the ground truth (random, smooth, bias; 5-40 deg): Spearman(score, angular error);
- refinement from the shipped model's prediction (fitted lights, with and without the rotation search, and the
  calibrated lights held), from calibrated least squares, and from the ground truth itself (how far the refinement
  moves a perfect map: the error floor its data term sets on this object): angular error before / after, minutes.
Synthetic (held-out wildgen objects rendered here, scene.json removed for the fitted mode): the same
perturbation series scored in fitted and in known-scene mode (validate.rerender), Spearman between the
two, and refinement from the model vs calibrated least squares on directional objects.
Wall-clock times on this machine (2 CPU cores shared with other jobs when they run).
"""
from __future__ import annotations

import json
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Literal

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from bench.cli_common import DILIGENT, MIN_RES, check_diligent, claim_result, parse, run_main, write_result  # noqa: E402
from scenes.cli.errors import UsageError, report_error  # noqa: E402
from scenes.cli.options import CommaList, Command, arg, check_fields, comma_list, option  # noqa: E402
from validate.perturb import KINDS  # noqa: E402

RESULT_KEYS = ("tta", "diligent", "synthetic")
"""The keys of every result (--out): a file without them is not this bench's and is never replaced."""


def spearman(a, b) -> float:
    from scipy.stats import spearmanr

    return float(spearmanr(a, b).statistic)


def series(gt: np.ndarray, mask: np.ndarray, angles, kinds, seed: int):
    from validate.perturb import perturb_normals

    for kind in kinds:
        for a in angles:
            yield kind, a, perturb_normals(gt, mask, kind, a, seed=seed)


def model_and_ls(folder: Path, net, tta: int):
    """(least squares with the folder's calibrated lights or None, model prediction with `tta` views) as
    full-size maps."""
    from unips.baselines import least_squares
    from unips.data import load_object
    from unips.inference import predict_object

    obj = load_object(folder)
    ls = least_squares(obj) if obj.light_directions is not None else None
    return ls, predict_object(obj, "model", net, tta=tta)


def diligent(args, net, out: dict) -> None:
    from scenes.metrics import mean_angular_error as mae_deg
    from validate.fitted.fit import FitConfig, fit_normals, prepare
    from validate.fitted.light_models import angular_errors_deg, directions_of
    from validate.fitted.refinement import RefineConfig, refine_object
    from validate.observations import downsample_normals, load_capture

    for name in ("ball", "cat"):
        folder = args.diligent / f"{name}PNG"
        cap = load_capture(folder)
        cfg = FitConfig(seed=args.seed)
        small, n_gt, f = prepare(cap, cap.normal_gt, cfg)
        row: dict = {"downsample": f, "fit_pixels": int(small.mask.sum())}

        def score(n_full: np.ndarray):
            n = downsample_normals(n_full, small.mask, f)
            n = np.where(
                small.mask[..., None] & (np.linalg.norm(n, axis=-1, keepdims=True) < 0.5), np.float32([0, 0, 1]), n
            )
            return fit_normals(small.images, small.mask, n, cfg, saturated=small.saturated)

        t0 = time.perf_counter()
        r_gt = score(cap.normal_gt)
        row["fit_minutes"] = (time.perf_counter() - t0) / 60
        err = angular_errors_deg(directions_of(r_gt.model, r_gt.light_params), cap.light_directions)
        row["light_error_deg"] = {"mean": float(err.mean()), "median": float(np.median(err)), "max": float(err.max())}
        ls, model = model_and_ls(folder, net, args.tta)
        const = np.where(cap.mask[..., None], np.float32([0, 0, 1]), 0).astype(np.float32)
        ranking = {"ground truth": (0.0, r_gt.rel_l1)}
        for label, n in (("least squares (calibrated)", ls), ("model", model), ("constant", const)):
            ranking[label] = (mae_deg(n, cap.normal_gt, cap.mask), score(n).rel_l1)
        row["ranking"] = {k: {"mae_deg": v[0], "rel_l1": v[1]} for k, v in ranking.items()}
        print(
            f"{name}: light error {err.mean():.2f} deg (median {np.median(err):.2f}), "
            f"fit {row['fit_minutes']:.2f} min (1/{f} res)"
        )
        for k, (m, s) in ranking.items():
            print(f"  {k:<28} mae {m:6.2f}  rel_l1 {s:.4f}")
        pert = []
        for kind, a, n in series(cap.normal_gt, cap.mask, args.angles, args.kinds, args.seed):
            pert.append(
                {"kind": kind, "angle": a, "mae_deg": mae_deg(n, cap.normal_gt, cap.mask), "rel_l1": score(n).rel_l1}
            )
        row["perturbations"] = pert
        row["spearman"] = spearman([p["rel_l1"] for p in pert], [p["mae_deg"] for p in pert])
        row["spearman_per_kind"] = {
            k: spearman([p["rel_l1"] for p in pert if p["kind"] == k], [p["mae_deg"] for p in pert if p["kind"] == k])
            for k in args.kinds
        }
        print(f"  perturbations: Spearman(score, error) {row['spearman']:.3f}  per kind {row['spearman_per_kind']}")
        if not args.skip_refine:
            ref = {}
            for label, start, lights, rot in (("model, fitted lights", model, "fitted", False),
                                              ("model, fitted lights, --rotation-search", model, "fitted", True),
                                              ("model, calibrated lights", model, "calibrated", False),
                                              ("least squares, fitted lights", ls, "fitted", False),
                                              ("ground truth, fitted lights", cap.normal_gt, "fitted", False)):
                t0 = time.perf_counter()
                r = refine_object(
                    str(folder), start, RefineConfig(fit=FitConfig(seed=args.seed), lights=lights, rotation_search=rot)
                )
                ref[label] = {"before_mae": r["before"]["mae_deg"], "after_mae": r["after"]["mae_deg"],
                              "before_rel_l1": r["before"]["rel_l1"], "after_rel_l1": r["after"]["rel_l1"],
                              "minutes": (time.perf_counter() - t0) / 60}
                print(
                    f"  refine {label:<30} mae {ref[label]['before_mae']:.2f} -> {ref[label]['after_mae']:.2f}  "
                    f"rel_l1 {ref[label]['before_rel_l1']:.4f} -> {ref[label]['after_rel_l1']:.4f}  "
                    f"{ref[label]['minutes']:.1f} min"
                )
            row["refine"] = ref
        out["diligent"][name] = row


def synthetic(args, net, out: dict) -> None:
    from scenes.metrics import mean_angular_error as mae_deg
    from validate.fitted.fit import FitConfig, fit_normals
    from validate.fitted.refinement import RefineConfig, refine_object
    from validate.observations import load_capture
    from validate.rerender import RerenderConfig, rerender_object

    work = Path(tempfile.mkdtemp(prefix="bench_fit_"))
    try:
        cmd = [
            sys.executable,
            "-m",
            "wildgen.make",
            "--out",
            str(work / "data"),
            "--objects",
            str(args.synthetic),
            "--images",
            str(args.images),
            "--res",
            str(args.res),
            "--spp",
            "32",
            "--lights",
            "directional,point,near_area",
            "--seed",
            str(args.synthetic_seed),
            "--workers",
            "0",
            "--quiet",
        ]
        subprocess.run(cmd, check=True, cwd=ROOT)
        folders = sorted((work / "data").glob("*.data"))
        rows = {}
        for folder in folders:
            bare = work / "bare" / folder.name
            shutil.copytree(folder, bare, ignore=shutil.ignore_patterns("scene.json"))
            cap = load_capture(bare)
            ls, model = model_and_ls(folder, net, args.tta)
            light_model = args.light_model
            if light_model == "auto":
                # Chosen once per object around the model's prediction (the map a user has), then held for
                # every map: a light model chosen per map would make the scores of the series incomparable.
                light_model = fit_normals(
                    cap.images, cap.mask, model, FitConfig(seed=args.seed, light_model="auto"), saturated=cap.saturated
                ).model
            cfg = FitConfig(seed=args.seed, light_model=light_model)
            maps = [("gt", 0, cap.normal_gt)] + list(
                series(cap.normal_gt, cap.mask, args.synthetic_angles, args.kinds, args.seed)
            )
            res = []
            for kind, a, n in maps:
                fitted = fit_normals(cap.images, cap.mask, n, cfg, saturated=cap.saturated).rel_l1
                known = rerender_object(folder, n, RerenderConfig(floors=False))["rel_l1"]
                res.append(
                    {
                        "kind": kind,
                        "angle": a,
                        "mae_deg": mae_deg(n, cap.normal_gt, cap.mask),
                        "fitted": fitted,
                        "known": known,
                    }
                )
            family = json.loads((folder / "scene.json").read_text()).get("light_family")
            row = {"light_family": family, "light_model": light_model, "maps": res,
                   "spearman_fitted_known": spearman([r["fitted"] for r in res], [r["known"] for r in res]),
                   "spearman_fitted_error": spearman([r["fitted"] for r in res], [r["mae_deg"] for r in res]),
                   "spearman_known_error": spearman([r["known"] for r in res], [r["mae_deg"] for r in res])}
            # Within one kind of error (as for DiLiGenT): does the fitted score order the angles as the
            # known-scene score and the angular error do?
            by_kind = {k: [r for r in res if r["kind"] == k] for k in args.kinds}
            row["spearman_per_kind"] = {
                k: {"fitted_known": spearman([r["fitted"] for r in rs], [r["known"] for r in rs]),
                    "fitted_error": spearman([r["fitted"] for r in rs], [r["mae_deg"] for r in rs])}
                for k, rs in by_kind.items()}
            if not args.skip_refine:
                r = refine_object(str(bare), model, RefineConfig(fit=cfg))
                row["refine_model"] = {
                    "before_mae": r["before"]["mae_deg"],
                    "after_mae": r["after"]["mae_deg"],
                    "least_squares_mae": mae_deg(ls, cap.normal_gt, cap.mask) if ls is not None else None,
                }
            rows[folder.name] = row
            print(
                f"{folder.name} ({family}, light model {light_model}): "
                f"Spearman fitted~known {row['spearman_fitted_known']:.3f}, fitted~error "
                f"{row['spearman_fitted_error']:.3f}, known~error {row['spearman_known_error']:.3f}"
                + (
                    f"; refine model {row['refine_model']['before_mae']:.2f} -> "
                    f"{row['refine_model']['after_mae']:.2f} deg"
                    f" (calibrated LS {row['refine_model']['least_squares_mae']})"
                    if "refine_model" in row
                    else ""
                )
            )
        out["synthetic"] = rows
    finally:
        shutil.rmtree(work, ignore_errors=True)


@dataclass
class Options:
    """The command line of bench/bench_fit.py."""

    diligent: Annotated[Path, arg(metavar="DIR", help_behavior_hint="(default: ../shared/data/diligent)")] = DILIGENT
    """folder with ballPNG/, catPNG/"""
    synthetic: int = option(3, minimum=0)
    """held-out wildgen objects (0: none)"""
    synthetic_seed: int = 913
    """wildgen seed of the held-out objects"""
    images: int = option(16, minimum=1)
    """images per synthetic object"""
    res: int = option(64, minimum=MIN_RES)
    """synthetic resolution"""
    angles: Annotated[list[float], comma_list(float, "DEG,DEG")] = option(
        default_factory=lambda: [5.0, 10.0, 20.0, 40.0], minimum=0, maximum=90)
    """perturbation angles (deg), DiLiGenT"""
    synthetic_angles: Annotated[list[float], comma_list(float, "DEG,DEG")] = option(
        default_factory=lambda: [5.0, 10.0, 20.0, 40.0], minimum=0, maximum=90)
    """perturbation angles (deg), synthetic"""
    kinds: Annotated[list[str], CommaList] = option(default_factory=lambda: list(KINDS), choices=KINDS)
    """perturbation kinds"""
    light_model: Literal["directional", "point", "environment", "auto"] = "directional"
    """light model of the synthetic objects' fits and refinement; auto: chosen once per object by residual around
    the model's prediction, then held (DiLiGenT: always directional)"""
    skip_diligent: bool = False
    """synthetic objects only"""
    skip_refine: bool = False
    """no refinement runs"""
    seed: int = 0
    """seed of perturbations and fits"""
    threads: Annotated[int | None, arg(metavar="T", help_behavior_hint="(default: one per core)")] = option(
        None, minimum=1
    )
    """Dr.Jit threads (1: byte-identical figures run to run)"""
    tta: Annotated[int | None, arg(metavar="N", help_behavior_hint="(default: unips.predict's)")] = None
    """views of the model's prediction"""
    out: Annotated[Path | None, arg(metavar="FILE")] = None
    """also write the figures as JSON"""

    def validate(self) -> "Options":
        check_fields(self)
        if self.tta is not None:
            from unips.inference import check_tta

            check_tta(self.tta, "--tta")
        return self


COMMAND = Command(Options, prog="python bench/bench_fit.py", description=__doc__.split("\n\n")[0])


def main(argv: list[str] | None = None) -> int:
    args = parse(COMMAND, argv)
    if not args.skip_diligent and args.diligent.is_dir():  # an absent DiLiGenT folder is skipped, a partial one refused
        check_diligent(args.diligent, ("ballPNG", "catPNG"), "--diligent")
    claim_result(args.out, RESULT_KEYS, COMMAND, inputs={"--diligent": args.diligent})
    if args.synthetic == 0 and (args.skip_diligent or not args.diligent.is_dir()):  # nothing would be measured
        raise SystemExit(report_error(UsageError("--synthetic: got 0 with --skip-diligent (or no DiLiGenT folder), "
                                                 "expected at least one synthetic object or the DiLiGenT objects")))
    from unips.inference import DEFAULT_TTA

    args.tta = DEFAULT_TTA if args.tta is None else args.tta
    from scenes.renderer.variant import choose_variant, set_jit_threads
    from unips.inference import load_network

    choose_variant("llvm_ad_rgb")
    set_jit_threads(args.threads)
    net = load_network(None)
    out: dict = {"tta": args.tta, "diligent": {}, "synthetic": {}}
    if args.skip_diligent:
        pass
    elif args.diligent.is_dir():
        diligent(args, net, out)
    else:
        print(f"DiLiGenT folder {args.diligent} not found: skipped")
    if args.synthetic > 0:
        synthetic(args, net, out)
    if args.out is not None:
        write_result(args.out, out, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(run_main(main))
